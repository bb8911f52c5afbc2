// config/config.cc — typed reading of TOML scenario tables with file:line errors.
#include "config/config.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

namespace ncosim::config {

std::string escape_text(std::string_view text, bool keep_newlines) {
  std::string out;
  out.reserve(text.size());
  std::size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    if ((c >= 0x20 && c < 0x7F) || (keep_newlines && (c == '\n' || c == '\t'))) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    // A well-formed UTF-8 sequence (no overlongs, no surrogates) stays as it is.
    std::size_t len = 0;
    if (c >= 0xC2 && c <= 0xDF)
      len = 2;
    else if (c >= 0xE0 && c <= 0xEF)
      len = 3;
    else if (c >= 0xF0 && c <= 0xF4)
      len = 4;
    bool ok = len > 0 && i + len <= text.size();
    for (std::size_t k = 1; ok && k < len; ++k)
      ok = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
    if (ok && len >= 3) {
      const auto c1 = static_cast<unsigned char>(text[i + 1]);
      if (c == 0xE0 && c1 < 0xA0) ok = false;
      if (c == 0xED && c1 >= 0xA0) ok = false;
      if (c == 0xF0 && c1 < 0x90) ok = false;
      if (c == 0xF4 && c1 >= 0x90) ok = false;
    }
    if (ok) {
      out.append(text.substr(i, len));
      i += len;
      continue;
    }
    out += fmt::format("\\x{:02x}", c);
    ++i;
  }
  return out;
}

namespace {

std::string joined(const std::vector<std::string>& messages) {
  std::string out;
  const std::size_t shown = std::min(messages.size(), ScenarioError::kMaxShown);
  for (std::size_t i = 0; i < shown; ++i) out += (i ? "\n" : "") + messages[i];
  if (shown < messages.size()) {
    out += fmt::format("\nand {} more errors ({} in all; the first {} are shown)",
                       messages.size() - shown, messages.size(), shown);
  }
  return out;
}

}  // namespace

ScenarioError::ScenarioError(std::vector<std::string> messages)
    : std::runtime_error(joined(messages)),
      messages_(std::make_shared<const std::vector<std::string>>(std::move(messages))) {}

std::string format_error(const std::string& file, int line, const std::string& path,
                         const std::string& message) {
  std::string out;
  // "<dict>" (a scenario given as a Python dict): its TOML text is generated, so a line in it
  // means nothing to the reader; the key path says where.
  if (!file.empty())
    out += line > 0 && file != kDictOrigin ? fmt::format("{}:{}: ", escape_text(file), line)
                                           : escape_text(file) + ": ";
  if (!path.empty()) out += fmt::format("key '{}': ", escape_text(path));
  out += message;
  return escape_text(out, true);  // any byte of a key, value or file name survives
}

namespace {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

}  // namespace

std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, word.size() / 3) + 1;
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  if (!best.empty()) return best;
  // The same word in other capitals ("SATURATED", "Periodic").
  auto lower = [](std::string_view s) {
    std::string out(s);
    for (char& ch : out) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return out;
  };
  for (const auto& c : candidates) {
    if (lower(c) == lower(word)) return c;
  }
  return best;
}

std::string compact_toml(const toml::node& node) {
  if (auto s = node.value_exact<std::string>()) return fmt::format("\"{}\"", *s);
  if (auto b = node.value_exact<bool>()) return *b ? "true" : "false";
  if (auto i = node.value_exact<std::int64_t>()) return fmt::format("{}", *i);
  if (auto d = node.value_exact<double>()) {
    std::string text = fmt::format("{}", *d);
    if (text.find_first_of(".eEn") == std::string::npos) text += ".0";  // keep it a float
    return text;
  }
  if (const auto* arr = node.as_array()) {
    std::string out = "[";
    for (std::size_t i = 0; i < arr->size(); ++i)
      out += (i ? ", " : "") + compact_toml(*arr->get(i));
    return out + "]";
  }
  if (const auto* tab = node.as_table()) {
    std::string out = "{";
    for (const auto& [k, v] : *tab)
      out += fmt::format("{}{} = {}", out.size() > 1 ? ", " : " ", k.str(), compact_toml(v));
    return out + (tab->empty() ? "}" : " }");
  }
  std::ostringstream os;
  os << toml::toml_formatter{node};
  return os.str();
}

std::string describe(const toml::node& node) {
  if (auto s = node.value_exact<std::string>())
    return fmt::format("a string \"{}\"", escape_text(*s));
  if (node.is_boolean() || node.is_integer() || node.is_floating_point()) return compact_toml(node);
  if (node.is_table()) return "a table";
  if (node.is_array()) {
    std::string text = compact_toml(node);
    if (text.size() > 60) text = text.substr(0, 57) + "...";
    return "an array " + text;
  }
  return "a date/time";
}

Table::Table(const toml::table& table, std::string path, std::string file)
    : table_(&table),
      path_(std::move(path)),
      file_(std::move(file)),
      known_(std::make_shared<std::set<std::string, std::less<>>>()) {}

int Table::line() const {
  const int own = static_cast<int>(table_->source().begin.line);
  if (own > 0) return own;
  // A table that only an override made (a [[sweep]] key below a table the file lacks) has no
  // place of its own: point at the first value the file gave it (the sweep's values).
  int first = 0;
  for (auto&& [key, node] : *table_) {
    const toml::source_region& src = node.source();
    if (src.path && src.path->starts_with(kCommandLineOrigin)) continue;
    const int l = static_cast<int>(src.begin.line);
    if (l > 0 && (first == 0 || l < first)) first = l;
  }
  return first;
}

std::string Table::key_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : fmt::format("{}.{}", path_, key);
}

const toml::node* Table::get(std::string_view key) const {
  known_->emplace(key);
  return table_->get(key);
}

bool Table::has(std::string_view key) const { return get(key) != nullptr; }

void Table::allow(std::string_view key) const { known_->emplace(key); }

std::pair<std::string, int> Table::location(const toml::node& node) const {
  const toml::source_region& src = node.source();
  if (src.path && src.path->starts_with(kCommandLineOrigin)) return {*src.path, 0};
  const int l = static_cast<int>(src.begin.line);
  return {file_, l > 0 ? l : line()};
}

int Table::line_of(std::string_view key) const {
  const toml::node* n = table_->get(key);
  if (n == nullptr) return line();
  const int l = location(*n).second;
  return l > 0 ? l : line();
}

void Table::fail(std::string_view key, const std::string& message) const {
  const toml::node* n = table_->get(key);
  const auto [file, l] = n != nullptr ? location(*n) : std::pair<std::string, int>{file_, line()};
  throw ScenarioError(format_error(file, l, key_path(key), message));
}

void Table::fail_here(const std::string& message) const {
  throw ScenarioError(format_error(file_, line(), path_, message));
}

void Table::type_error(std::string_view key, const std::string& expected) const {
  const toml::node* n = table_->get(key);
  if (n == nullptr)
    fail(key, fmt::format("expected {}, got nothing (the key is required)", expected));
  fail(key, fmt::format("expected {}, got {}", expected, describe(*n)));
}

namespace {
std::optional<double> as_number(const toml::node& n) {
  if (auto d = n.value_exact<double>()) return *d;
  if (auto i = n.value_exact<std::int64_t>()) return static_cast<double>(*i);
  return std::nullopt;
}
}  // namespace

double Table::number(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "a number");
  auto v = as_number(*n);
  if (!v) type_error(key, "a number");
  if (!std::isfinite(*v)) type_error(key, "a finite number");
  return *v;
}

double Table::number_or(std::string_view key, double fallback) const {
  return has(key) ? number(key) : fallback;
}

std::optional<double> Table::opt_number(std::string_view key) const {
  if (!has(key)) return std::nullopt;
  return number(key);
}

std::int64_t Table::integer(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "an integer");
  if (auto i = n->value_exact<std::int64_t>()) return *i;
  if (auto d = n->value_exact<double>()) {
    if (std::isfinite(*d) && std::floor(*d) == *d && std::fabs(*d) < 9e15) {
      return static_cast<std::int64_t>(*d);
    }
  }
  type_error(key, "an integer");
}

std::int64_t Table::integer_or(std::string_view key, std::int64_t fallback) const {
  return has(key) ? integer(key) : fallback;
}

bool Table::boolean_or(std::string_view key, bool fallback) const {
  const toml::node* n = get(key);
  if (n == nullptr) return fallback;
  if (auto b = n->value_exact<bool>()) return *b;
  type_error(key, "true or false");
}

std::string Table::string(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "a string");
  if (auto s = n->value_exact<std::string>()) return *s;
  type_error(key, "a string");
}

bool Table::is_string(std::string_view key) const {
  const toml::node* n = get(key);
  return n != nullptr && n->is_string();
}

std::string Table::string_or(std::string_view key, std::string_view fallback) const {
  return has(key) ? string(key) : std::string(fallback);
}

std::string Table::choice_or(std::string_view key, std::string_view fallback,
                             const std::vector<std::string>& choices) const {
  std::string v = string_or(key, fallback);
  if (std::find(choices.begin(), choices.end(), v) != choices.end()) return v;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", c);
  std::string hint = did_you_mean(v, choices);
  fail(key, fmt::format("expected one of {}, got \"{}\"{}", list, escape_text(v),
                        hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
}

std::vector<double> Table::numbers(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "an array of numbers");
  if (auto v = as_number(*n)) {
    if (!std::isfinite(*v)) type_error(key, "an array of finite numbers");
    return {*v};
  }
  const toml::array* arr = n->as_array();
  if (arr == nullptr) type_error(key, "an array of numbers");
  std::vector<double> out;
  for (const toml::node& e : *arr) {
    auto v = as_number(e);
    if (!v || !std::isfinite(*v)) {
      fail(key, fmt::format("expected an array of finite numbers, got {} at index {}", describe(e),
                            out.size()));
    }
    out.push_back(*v);
  }
  return out;
}

Eigen::VectorXd Table::vector(std::string_view key) const {
  const std::vector<double> v = numbers(key);
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

std::vector<std::vector<double>> Table::ragged(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "an array of arrays of numbers");
  const toml::array* arr = n->as_array();
  if (arr == nullptr) type_error(key, "an array of arrays of numbers");
  std::vector<std::vector<double>> rows;
  for (const toml::node& r : *arr) {
    const toml::array* row = r.as_array();
    if (row == nullptr) {
      fail(key, fmt::format("expected an array of arrays of numbers, got {} as row {}", describe(r),
                            rows.size()));
    }
    std::vector<double> vals;
    for (const toml::node& e : *row) {
      auto v = as_number(e);
      if (!v || !std::isfinite(*v)) {
        fail(key, fmt::format("expected an array of arrays of finite numbers, got {} at [{}][{}]",
                              describe(e), rows.size(), vals.size()));
      }
      vals.push_back(*v);
    }
    rows.push_back(std::move(vals));
  }
  return rows;
}

Eigen::MatrixXd Table::matrix(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr) type_error(key, "a matrix [[...], ...]");
  if (auto v = as_number(*n)) {
    if (!std::isfinite(*v)) type_error(key, "a matrix of finite numbers");
    return Eigen::MatrixXd::Constant(1, 1, *v);
  }
  const toml::array* arr = n->as_array();
  if (arr == nullptr || arr->empty()) type_error(key, "a matrix [[...], ...]");
  if (!(*arr)[0].is_array()) {
    fail(key,
         fmt::format("expected a matrix [[...], ...] (an array of rows), got {}", describe(*n)));
  }
  const auto rows = ragged(key);
  const std::size_t cols = rows[0].size();
  if (cols == 0) type_error(key, "a matrix with at least one column");
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != cols) {
      fail(key, fmt::format("expected every row to have {} entries, got {} in row {}", cols,
                            rows[i].size(), i));
    }
  }
  Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(cols));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (std::size_t j = 0; j < cols; ++j) {
      m(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = rows[i][j];
    }
  }
  return m;
}

Table Table::table(std::string_view key) const {
  const toml::node* n = get(key);
  if (n == nullptr || !n->is_table()) type_error(key, "a table");
  return Table(*n->as_table(), key_path(key), file_);
}

std::optional<Table> Table::opt_table(std::string_view key) const {
  if (!has(key)) return std::nullopt;
  return table(key);
}

std::vector<Table> Table::tables(std::string_view key) const {
  const toml::node* n = get(key);
  std::vector<Table> out;
  if (n == nullptr) return out;
  const toml::array* arr = n->as_array();
  if (arr == nullptr) type_error(key, fmt::format("an array of tables [[{}]]", key));
  std::size_t i = 0;
  for (const toml::node& e : *arr) {
    if (!e.is_table()) type_error(key, fmt::format("an array of tables [[{}]]", key));
    out.emplace_back(*e.as_table(), fmt::format("{}[{}]", key_path(key), i++), file_);
  }
  return out;
}

std::vector<LineError> Table::unknown_keys(const std::vector<std::string>& known_keys) const {
  std::vector<std::string> known = known_keys;
  std::sort(known.begin(), known.end());
  std::vector<LineError> out;
  for (const auto& [k, v] : *table_) {
    if (std::find(known.begin(), known.end(), k.str()) != known.end()) continue;
    std::string hint = did_you_mean(k.str(), known);
    const auto [file, l] = location(v);
    std::string list;
    for (const auto& c : known) list += (list.empty() ? "" : ", ") + escape_text(c);
    out.push_back({l, format_error(file, l, key_path(k.str()),
                                   hint.empty() ? fmt::format("unknown key (valid keys here: {})",
                                                              list.empty() ? "none" : list)
                                                : fmt::format("unknown key (did you mean '{}'?)",
                                                              escape_text(hint)))});
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const LineError& a, const LineError& b) { return a.line < b.line; });
  return out;
}

void Table::finish() const {
  const auto errors = unknown_keys({known_->begin(), known_->end()});
  if (errors.size() == 1) throw ScenarioError(errors[0].message);
  if (!errors.empty()) throw ScenarioError(in_file_order(errors));
}

std::vector<std::string> in_file_order(std::vector<LineError> errors) {
  std::stable_sort(errors.begin(), errors.end(),
                   [](const LineError& a, const LineError& b) { return a.line < b.line; });
  std::vector<std::string> out;
  for (auto& e : errors) out.push_back(std::move(e.message));
  return out;
}

void require_shape(const Table& t, std::string_view key, const Eigen::MatrixXd& m,
                   Eigen::Index rows, Eigen::Index cols) {
  if (m.rows() != rows || m.cols() != cols) {
    t.fail(key, fmt::format("expected a {}x{} matrix, got {}x{}", rows, cols, m.rows(), m.cols()));
  }
}

void require_psd(const Table& t, std::string_view key, const Eigen::MatrixXd& m) {
  if (m.rows() != m.cols()) {
    t.fail(key, fmt::format("expected a square covariance matrix, got {}x{}", m.rows(), m.cols()));
  }
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-12 * scale) {
    t.fail(key, "expected a symmetric positive semidefinite matrix, got a non-symmetric one");
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(m);
  const double min_eig = es.eigenvalues().minCoeff();
  if (min_eig < -1e-12 * scale) {
    t.fail(key, fmt::format("expected a symmetric positive semidefinite matrix, got one with "
                            "eigenvalue {:.6g}",
                            min_eig));
  }
}

void require_probability(const Table& t, std::string_view key, double p) {
  if (!(p >= 0.0 && p <= 1.0))
    t.fail(key, fmt::format("expected a probability in [0, 1], got {}", p));
}

void require_subprobability(const Table& t, std::string_view key, const std::vector<double>& pmf) {
  double sum = 0.0;
  for (std::size_t i = 0; i < pmf.size(); ++i) {
    if (pmf[i] < 0.0) {
      t.fail(key, fmt::format("probabilities must be non-negative, got {} at index {}", pmf[i], i));
    }
    sum += pmf[i];
  }
  if (sum > 1.0 + 1e-9) t.fail(key, fmt::format("probabilities must sum to <= 1, got {:.6g}", sum));
}

}  // namespace ncosim::config

// config/keys.cc — declared keys: the generic read, type and range checks, and their docs.
#include "config/keys.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace ncosim::config {

std::string_view key_type_name(KeyType type) {
  switch (type) {
    case KeyType::kNumber:
      return "number";
    case KeyType::kInteger:
      return "integer";
    case KeyType::kBoolean:
      return "boolean";
    case KeyType::kString:
      return "string";
    case KeyType::kChoice:
      return "choice";
    case KeyType::kNumbers:
      return "numbers";
    case KeyType::kVector:
      return "vector";
    case KeyType::kMatrix:
      return "matrix";
    case KeyType::kRagged:
      return "ragged";
    case KeyType::kTable:
      return "table";
    case KeyType::kTables:
      return "tables";
    case KeyType::kArray:
      return "array";
    case KeyType::kAny:
      return "any";
  }
  return "?";
}

namespace {

bool is_integral(KeyType t) { return t == KeyType::kInteger; }

std::string bound(double v, bool integral) {
  if (integral || (std::floor(v) == v && std::fabs(v) < 1e15))
    return fmt::format("{}", static_cast<std::int64_t>(v));
  return fmt::format("{}", v);
}

std::string number_text(double v) {
  std::string text = fmt::format("{}", v);
  return text;
}

}  // namespace

Key Key::choice(std::string name, std::vector<std::string> values) {
  Key k(std::move(name), KeyType::kChoice);
  k.values_ = std::move(values);
  return k;
}

Key Key::any(std::string name, std::string type_text) {
  Key k(std::move(name), KeyType::kAny);
  k.any_text_ = std::move(type_text);
  return k;
}

Key& Key::help(std::string text) {
  help_ = std::move(text);
  return *this;
}
Key& Key::unit(std::string text) {
  unit_ = std::move(text);
  return *this;
}
Key& Key::or_default(double v) {
  default_ = v;
  return *this;
}
Key& Key::or_default(std::int64_t v) {
  default_ = v;
  return *this;
}
Key& Key::or_default(bool v) {
  default_ = v;
  return *this;
}
Key& Key::or_default(std::string v) {
  default_ = std::move(v);
  return *this;
}
Key& Key::or_default(std::vector<double> v) {
  default_ = std::move(v);
  return *this;
}
Key& Key::optional(std::string text) {
  optional_ = true;
  optional_text_ = std::move(text);
  return *this;
}
Key& Key::min(double v) {
  lo_ = v;
  lo_open_ = false;
  return *this;
}
Key& Key::max(double v) {
  hi_ = v;
  hi_open_ = false;
  return *this;
}
Key& Key::above(double v) {
  lo_ = v;
  lo_open_ = true;
  return *this;
}
Key& Key::below(double v) {
  hi_ = v;
  hi_open_ = true;
  return *this;
}
Key& Key::noun(std::string singular, std::string plural) {
  noun_ = std::move(singular);
  plural_ = std::move(plural);
  return *this;
}
Key& Key::says(std::string phrase) {
  says_ = std::move(phrase);
  return *this;
}
Key& Key::fields(const Keys& keys) {
  fields_ = std::make_shared<const Keys>(keys);
  return *this;
}
Key& Key::or_words(std::vector<std::string> words) {
  words_ = std::move(words);
  return *this;
}
Key& Key::entries(std::size_t lo, std::size_t hi) {
  min_entries_ = lo;
  max_entries_ = hi;
  return *this;
}
Key& Key::columns(std::size_t n) {
  columns_ = n;
  return *this;
}

std::string Key::type_text() const {
  if (type_ == KeyType::kAny) return any_text_;
  std::string text(key_type_name(type_));
  for (const auto& w : words_) text += fmt::format(" or \"{}\"", w);
  return text;
}

namespace {

// What an array key's entries are called: "numbers", "rows", "tables", "values".
std::string entry_noun(KeyType t, std::size_t count) {
  const bool one = count == 1;
  switch (t) {
    case KeyType::kMatrix:
    case KeyType::kRagged:
      return one ? "row" : "rows";
    case KeyType::kTables:
      return one ? "table" : "tables";
    case KeyType::kArray:
      return one ? "value" : "values";
    default:
      return one ? "number" : "numbers";
  }
}

}  // namespace

std::string Key::shape_text() const {
  std::string out;
  const std::size_t lo = min_entries_, hi = max_entries_;
  if (lo > 0 && lo == hi)
    out = fmt::format("{} {}", lo, entry_noun(type_, lo));
  else if (lo > 0 && hi > 0)
    out = fmt::format("{}..{} {}", lo, hi, entry_noun(type_, hi));
  else if (lo > 0)
    out = fmt::format("at least {} {}", lo, entry_noun(type_, lo));
  else if (hi > 0)
    out = fmt::format("at most {} {}", hi, entry_noun(type_, hi));
  if (columns_ > 0)
    out += fmt::format("{}rows of {} {}", out.empty() ? "" : ", ", columns_,
                       columns_ == 1 ? "number" : "numbers");
  return out;
}

std::string Key::entries_error(std::size_t got) const {
  std::string phrase = says_;
  if (phrase.empty()) {
    phrase = shape_text();
    if (columns_ > 0) phrase = phrase.substr(0, phrase.find(", rows of"));
  }
  return fmt::format("expected {}, got {} {}", phrase, got, entry_noun(type_, got));
}

std::string Key::columns_error(std::size_t got, std::size_t row) const {
  return fmt::format("expected rows of {} {}, got {} in row {}", columns_,
                     columns_ == 1 ? "number" : "numbers", got, row);
}

std::string Key::default_text() const {
  struct Visit {
    std::string operator()(std::monostate) const { return ""; }
    std::string operator()(double v) const {
      std::string text = number_text(v);
      if (text.find_first_of(".eEn") == std::string::npos) text += ".0";
      return text;
    }
    std::string operator()(std::int64_t v) const { return fmt::format("{}", v); }
    std::string operator()(bool v) const { return v ? "true" : "false"; }
    std::string operator()(const std::string& v) const { return fmt::format("\"{}\"", v); }
    std::string operator()(const std::vector<double>& v) const {
      std::string out = "[";
      for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + (*this)(v[i]);
      return out + "]";
    }
  };
  if (std::holds_alternative<std::monostate>(default_)) return optional_ ? optional_text_ : "";
  return std::visit(Visit{}, default_);
}

std::string Key::range_text() const {
  const bool integral = is_integral(type_);
  if (lo_ && hi_) {
    if (integral) {
      const double lo = lo_open_ ? *lo_ + 1 : *lo_;
      const double hi = hi_open_ ? *hi_ - 1 : *hi_;
      return fmt::format("{}..{}", bound(lo, true), bound(hi, true));
    }
    return fmt::format("{}{}, {}{}", lo_open_ ? "(" : "[", bound(*lo_, false), bound(*hi_, false),
                       hi_open_ ? ")" : "]");
  }
  if (lo_) return fmt::format("{} {}", lo_open_ ? ">" : ">=", bound(*lo_, integral));
  if (hi_) return fmt::format("{} {}", hi_open_ ? "<" : "<=", bound(*hi_, integral));
  return "";
}

bool Key::in_range(double v) const {
  if (lo_ && !(lo_open_ ? v > *lo_ : v >= *lo_)) return false;
  if (hi_ && !(hi_open_ ? v < *hi_ : v <= *hi_)) return false;
  return true;
}

std::string Key::range_error(double v, const std::string& index) const {
  const bool integral = is_integral(type_);
  const bool entry = !index.empty();
  std::string phrase = says_;
  if (phrase.empty()) {
    std::string noun = entry ? plural_ : noun_;
    if (noun.empty()) noun = entry ? "numbers" : (integral ? "an integer" : "a number");
    const std::string range = range_text();
    phrase = lo_ && hi_ ? fmt::format("{} in {}", noun, range) : fmt::format("{} {}", noun, range);
  }
  const std::string got =
      integral ? fmt::format("{}", static_cast<std::int64_t>(v)) : number_text(v);
  return fmt::format("expected {}, got {}{}", phrase, got, index);
}

Keys::Keys(std::initializer_list<Key> keys) : keys_(keys) {}

const Key* Keys::find(std::string_view name) const {
  for (const auto& k : keys_) {
    if (k.name() == name) return &k;
  }
  return nullptr;
}

const Key& Keys::at(std::string_view name) const {
  if (const Key* k = find(name)) return *k;
  throw std::logic_error(fmt::format("key '{}' is read but not declared", name));
}

Keys Keys::operator+(const Keys& more) const {
  std::vector<Key> all = keys_;
  all.insert(all.end(), more.keys_.begin(), more.keys_.end());
  Keys out(std::move(all));
  out.one_of_ = one_of_;
  out.one_of_.insert(out.one_of_.end(), more.one_of_.begin(), more.one_of_.end());
  return out;
}

Keys& Keys::require_one_of(std::vector<std::string> names) {
  one_of_.push_back(std::move(names));
  return *this;
}

std::string Keys::one_of_error(const std::vector<std::string>& names) {
  std::string list;
  for (std::size_t i = 0; i < names.size(); ++i) {
    list += (i == 0 ? "" : (i + 1 == names.size() ? " or " : ", ")) + fmt::format("`{}`", names[i]);
  }
  return fmt::format("expected {}, got {}", list, names.size() == 2 ? "neither" : "none of them");
}

// ---------------------------------------------------------------------------------------------

const Key& KeyReader::declared(std::string_view key, std::initializer_list<KeyType> types) const {
  const Key& k = keys_.at(key);
  for (KeyType t : types) {
    if (k.type() == t || k.type() == KeyType::kAny) return k;
  }
  throw std::logic_error(
      fmt::format("key '{}' is declared as a {} but read otherwise", key, key_type_name(k.type())));
}

void KeyReader::check(const Key& k, double v, const std::string& index) const {
  if (!k.in_range(v)) t_.fail(k.name(), k.range_error(v, index));
}

void KeyReader::check_entries(const Key& k, std::size_t count) const {
  if ((k.min_entries() > 0 && count < k.min_entries()) ||
      (k.max_entries() > 0 && count > k.max_entries()))
    t_.fail(k.name(), k.entries_error(count));
}

void KeyReader::check_columns(const Key& k, const std::vector<std::vector<double>>& rows) const {
  if (k.columns() == 0) return;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != k.columns()) t_.fail(k.name(), k.columns_error(rows[i].size(), i));
  }
}

const Key::Value& KeyReader::fallback(const Key& k, const std::string& expected) const {
  // No default: required here (an optional() key is required where its reader asks for it).
  if (std::holds_alternative<std::monostate>(k.default_value()))
    t_.fail(k.name(), fmt::format("expected {}, got nothing (the key is required)", expected));
  return k.default_value();
}

bool KeyReader::has(std::string_view key) const {
  (void)keys_.at(key);
  return t_.has(key);
}

double KeyReader::number(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kNumber});
  if (!t_.has(key)) {
    const Key::Value& d = fallback(k, "a number");
    if (const auto* i = std::get_if<std::int64_t>(&d)) return static_cast<double>(*i);
    return std::get<double>(d);
  }
  const double v = t_.number(key);
  check(k, v);
  return v;
}

std::optional<double> KeyReader::opt_number(std::string_view key) const {
  (void)declared(key, {KeyType::kNumber});
  if (!t_.has(key)) return std::nullopt;
  return number(key);
}

std::int64_t KeyReader::integer(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kInteger});
  if (!t_.has(key)) return std::get<std::int64_t>(fallback(k, "an integer"));
  const std::int64_t v = t_.integer(key);
  check(k, static_cast<double>(v));
  return v;
}

std::optional<std::int64_t> KeyReader::opt_integer(std::string_view key) const {
  (void)declared(key, {KeyType::kInteger});
  if (!t_.has(key)) return std::nullopt;
  return integer(key);
}

bool KeyReader::boolean(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kBoolean});
  if (!t_.has(key)) return std::get<bool>(fallback(k, "true or false"));
  return t_.boolean_or(key, false);
}

std::string KeyReader::string(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kString, KeyType::kChoice});
  if (k.type() == KeyType::kChoice) {
    if (!t_.has(key)) {
      const Key::Value& d = fallback(k, "a string");
      return t_.choice_or(key, std::get<std::string>(d), k.values());
    }
    return t_.choice_or(key, "", k.values());
  }
  if (!t_.has(key)) return std::get<std::string>(fallback(k, "a string"));
  return t_.string(key);
}

std::optional<std::string> KeyReader::opt_string(std::string_view key) const {
  (void)declared(key, {KeyType::kString, KeyType::kChoice});
  if (!t_.has(key)) return std::nullopt;
  return string(key);
}

std::vector<double> KeyReader::numbers(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kNumbers, KeyType::kVector});
  if (!t_.has(key)) return std::get<std::vector<double>>(fallback(k, "an array of numbers"));
  std::vector<double> v = t_.numbers(key);
  check_entries(k, v.size());
  for (std::size_t i = 0; i < v.size(); ++i) check(k, v[i], fmt::format(" at index {}", i));
  return v;
}

Eigen::VectorXd KeyReader::vector(std::string_view key) const {
  const std::vector<double> v = numbers(key);
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

Eigen::MatrixXd KeyReader::matrix(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kMatrix});
  if (!t_.has(key)) (void)fallback(k, "a matrix [[...], ...]");
  Eigen::MatrixXd m = t_.matrix(key);
  check_entries(k, static_cast<std::size_t>(m.rows()));
  if (k.columns() > 0 && static_cast<std::size_t>(m.cols()) != k.columns())
    t_.fail(k.name(), k.columns_error(static_cast<std::size_t>(m.cols()), 0));
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    for (Eigen::Index j = 0; j < m.cols(); ++j)
      check(k, m(i, j), fmt::format(" at [{}][{}]", i, j));
  }
  return m;
}

std::vector<std::vector<double>> KeyReader::ragged(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kRagged});
  if (!t_.has(key)) (void)fallback(k, "an array of arrays of numbers");
  auto rows = t_.ragged(key);
  check_entries(k, rows.size());
  check_columns(k, rows);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    for (std::size_t j = 0; j < rows[i].size(); ++j)
      check(k, rows[i][j], fmt::format(" at [{}][{}]", i, j));
  }
  return rows;
}

Table KeyReader::table(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kTable});
  if (!t_.has(key)) (void)fallback(k, "a table");
  return t_.table(key);
}

std::optional<Table> KeyReader::opt_table(std::string_view key) const {
  (void)declared(key, {KeyType::kTable});
  return t_.opt_table(key);
}

std::vector<Table> KeyReader::tables(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kTables});
  std::vector<Table> out = t_.tables(key);
  if (t_.has(key)) check_entries(k, out.size());
  return out;
}

std::optional<std::string> KeyReader::word(std::string_view key) const {
  const Key& k = keys_.at(key);
  if (!t_.is_string(key)) return std::nullopt;
  const std::string v = t_.string(key);
  if (std::find(k.words().begin(), k.words().end(), v) != k.words().end()) return v;
  const std::string hint = did_you_mean(v, k.words());
  t_.fail(key, fmt::format("expected {}, got a string \"{}\"{}",
                           k.says_text().empty() ? k.type_text() : k.says_text(), escape_text(v),
                           hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
}

const toml::array* KeyReader::array(std::string_view key) const {
  const Key& k = declared(key, {KeyType::kArray});
  const std::string expected = k.says_text().empty() ? "an array" : k.says_text();
  if (!t_.has(key)) {
    (void)fallback(k, expected);
    return nullptr;
  }
  const toml::array* a = t_.raw().get(key)->as_array();
  if (a == nullptr)
    t_.fail(key, fmt::format("expected {}, got {}", expected, describe(*t_.raw().get(key))));
  check_entries(k, a->size());
  return a;
}

// ---------------------------------------------------------------------------------------------

namespace {

// A Markdown table cell: `|` escaped, so that a help text cannot cut the row.
std::string cell(const std::string& text) {
  std::string out;
  for (char c : text) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}

std::string values_text(const Key& k) {
  if (k.type() == KeyType::kChoice) {
    std::string out;
    for (const auto& v : k.values()) out += (out.empty() ? "" : ", ") + fmt::format("\"{}\"", v);
    return out;
  }
  const std::string range = k.range_text(), shape = k.shape_text();
  return range.empty() || shape.empty() ? range + shape : range + "; " + shape;
}

// Every key with its name prefixed (`reference.` for a table's fields), fields after their table.
void flatten(const Keys& keys, const std::string& prefix,
             std::vector<std::pair<std::string, const Key*>>& out) {
  for (const Key& k : keys.list()) {
    out.emplace_back(prefix + k.name(), &k);
    if (k.fields() != nullptr) flatten(*k.fields(), prefix + k.name() + ".", out);
  }
}

}  // namespace

std::string format_keys(const Keys& keys, bool markdown) {
  std::vector<std::pair<std::string, const Key*>> all;
  flatten(keys, "", all);
  std::string out;
  if (markdown) {
    out += "| key | type | unit | default | allowed | meaning |\n";
    out += "|---|---|---|---|---|---|\n";
    for (const auto& [name, key] : all) {
      const Key& k = *key;
      const std::string def = k.required() ? "required" : k.default_text();
      out += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", name, k.type_text(),
                         cell(k.unit_text()), cell(def), cell(values_text(k)), cell(k.help_text()));
    }
    return out;
  }
  for (const auto& [name, key] : all) {
    const Key& k = *key;
    std::string line = fmt::format("  {:<16} {:<8}", name, k.type_text());
    if (!k.unit_text().empty()) line += fmt::format(" [{}]", k.unit_text());
    line += k.required()
                ? "  required"
                : fmt::format("  default {}", k.default_text().empty() ? "none" : k.default_text());
    const std::string allowed = values_text(k);
    if (!allowed.empty()) line += fmt::format("  allowed {}", allowed);
    out += line + "\n";
    if (!k.help_text().empty()) out += fmt::format("      {}\n", k.help_text());
  }
  return out;
}

}  // namespace ncosim::config

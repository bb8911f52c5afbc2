// sim/cmd/find.cc — scan + bisection of a design quantity over one scenario key.
#include "sim/cmd/find.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "config/toml_path.h"
#include "sim/analysis/output.h"

namespace ncosim::sim {

FindTarget parse_target(const std::string& text, const std::string& origin) {
  FindTarget t;
  std::size_t at = std::string::npos, len = 0;
  for (const char* op : {"<=", ">=", "<", ">"}) {
    const std::size_t p = text.find(op);
    if (p != std::string::npos) {
      at = p;
      len = std::string(op).size();
      t.op = op;
      break;
    }
  }
  auto bad = [&](const std::string& why) {
    throw config::ScenarioError(
        fmt::format("{}: expected QUANTITY<=VALUE (or >=, <, >), e.g. "
                    "'predicted_mse<=0.03', got '{}' ({})",
                    origin, text, why));
  };
  if (at == std::string::npos) bad("no comparison");
  auto trim = [](std::string s) {
    s.erase(0, s.find_first_not_of(" \t"));
    s.erase(s.find_last_not_of(" \t") + 1);
    return s;
  };
  t.quantity = trim(text.substr(0, at));
  const std::string num = trim(text.substr(at + len));
  if (t.quantity.empty()) bad("no quantity");
  try {
    std::size_t used = 0;
    t.value = std::stod(num, &used);
    if (used != num.size()) bad("the value is not a number");
  } catch (const std::logic_error&) {
    bad("the value is not a number");
  }
  if (!std::isfinite(t.value)) bad("the value is not finite");
  return t;
}

std::string toml_float(double v) {
  std::string s = fmt::format("{}", v);  // shortest exact form
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

namespace {

// The quantity of every estimator of one case at one key value; nullopt where the design
// failed or the field is not a number.
using Sample = std::map<std::string, std::optional<double>>;

// How --key is set: the key itself; when it is swept (axis `swept`), that axis reduced to the one
// value (a sweep is applied after --set); when it names an entry of an array (link[0].pmf[1]),
// the whole array with that entry changed (`entries`: the others as the scenario has them).
struct KeySetter {
  std::optional<std::size_t> swept;
  std::string path;                  // what the assignment sets
  std::optional<std::size_t> entry;  // the index, for an array entry
  std::vector<std::string> entries;  // the array's entries (TOML text)
};

std::string assignment(const KeySetter& k, double v) {
  if (k.swept) return fmt::format("sweep[{}].values=[{}]", *k.swept, toml_float(v));
  if (!k.entry) return fmt::format("{}={}", k.path, toml_float(v));
  std::string arr;
  for (std::size_t i = 0; i < k.entries.size(); ++i)
    arr += (i ? ", " : "") + (i == *k.entry ? toml_float(v) : k.entries[i]);
  return fmt::format("{}=[{}]", k.path, arr);
}

// An error of the assignment made for --key ("--set: key 'PATH': ...") told as the user's option,
// with the value tried; any other error as it is.
[[noreturn]] void rethrow_for_key(const config::ScenarioError& e, const FindOptions& opt,
                                  const KeySetter& k, double v) {
  const std::string msg = e.what();
  for (const std::string& path :
       {k.path, k.swept ? fmt::format("sweep[{}].values", *k.swept) : k.path}) {
    const std::string head = fmt::format("--set: key '{}': ", path);
    if (msg.starts_with(head)) {
      throw config::ScenarioError(
          fmt::format("--key: '{}' = {}: {}", opt.key, toml_float(v), msg.substr(head.size())));
    }
  }
  throw e;
}

Sample evaluate(const std::string& file, const std::vector<std::string>& sets,
                const FindOptions& opt, const KeySetter& key, std::size_t case_index, double v) {
  std::vector<std::string> s = sets;
  s.push_back(assignment(key, v));
  LoadedScenario loaded;
  try {
    loaded = load_cases(file, s, {}, case_index);
  } catch (const config::ScenarioError& e) {
    rethrow_for_key(e, opt, key, v);
  }
  const nlohmann::json dj = design_json(loaded);
  const nlohmann::json& ests =
      dj.contains("cases") ? dj["cases"][0]["estimators"] : dj["estimators"];
  Sample out;
  for (const auto& e : ests) {
    std::optional<double> q;
    const auto it = e.find(opt.target.quantity);
    if (e["status"] == "ok" && it != e.end() && it->is_number()) q = it->get<double>();
    out[e["name"].get<std::string>()] = q;
  }
  return out;
}

bool met(const FindTarget& t, const std::optional<double>& q) {
  if (!q || !std::isfinite(*q)) return false;
  if (t.op == "<=") return *q <= t.value;
  if (t.op == ">=") return *q >= t.value;
  if (t.op == "<") return *q < t.value;
  return *q > t.value;
}

}  // namespace

bool is_monotone(const std::map<double, std::optional<double>>& pts) {
  int dir = 0;
  std::optional<double> prev;
  for (const auto& [k, q] : pts) {
    if (!q) continue;
    if (prev) {
      const double d = *q - *prev;
      const double slack = 1e-9 * std::max(std::abs(*q), std::abs(*prev));
      const int s = d > slack ? 1 : d < -slack ? -1 : 0;
      if (s != 0) {
        if (dir != 0 && s != dir) return false;
        dir = s;
      }
    }
    prev = q;
  }
  return true;
}

namespace {

// Refuses a range, tolerance or scan that cannot be searched.
void check_find_options(const FindOptions& opt) {
  if (!(opt.lo < opt.hi))
    throw config::ScenarioError(
        fmt::format("--lo: expected lo < hi, got {} and {}", opt.lo, opt.hi));
  if (!(opt.tol > 0.0))
    throw config::ScenarioError(
        fmt::format("--tol: expected a positive tolerance, got {}", opt.tol));
  if (opt.scan < 1)
    throw config::ScenarioError(
        fmt::format("--scan: expected at least 1 interval, got {}", opt.scan));
}

// The array entry that `key` names (PATH[I] after a key: link[0].pmf[1]) in the scenario with the
// user's --set: `k` gets the array's path, the index and the entries. Throws naming --key when
// PATH is not an array of numbers of the scenario or I is not one of its entries.
void resolve_entry(const LoadedScenario& probe, const std::vector<std::string>& sets,
                   const std::string& key, KeySetter& k) {
  const std::size_t open = key.rfind('[');
  const std::string idx = key.substr(open + 1, key.size() - open - 2);
  if (open == 0 || open == std::string::npos || key[open - 1] == ']' || idx.empty() ||
      idx.find_first_not_of("0123456789") != std::string::npos || idx.size() > 9) {
    throw config::ScenarioError(fmt::format(
        "--key: expected a key path (link[0].delivery) or an entry of an array of numbers "
        "(link[0].pmf[1]), got '{}'",
        key));
  }
  k.path = key.substr(0, open);
  k.entry = std::stoul(idx);
  toml::table doc;
  try {
    doc = toml::parse(probe.text, std::string_view(probe.file));
  } catch (const toml::parse_error&) {
    return;  // load_cases reported it already
  }
  for (const auto& s : sets) config::apply_set(doc, s, "--set");
  const toml::node* node = config::find_path(doc, k.path);
  const toml::array* arr = node != nullptr ? node->as_array() : nullptr;
  if (arr == nullptr || arr->empty() ||
      !std::all_of(arr->begin(), arr->end(), [](const toml::node& n) { return n.is_number(); })) {
    throw config::ScenarioError(
        fmt::format("--key: '{}' names an entry of '{}', which is not an array of numbers in {}; "
                    "search a key of a number (e.g. link[0].delivery) or an entry of such an "
                    "array (e.g. link[0].pmf[1])",
                    key, k.path, probe.file));
  }
  if (*k.entry >= arr->size()) {
    throw config::ScenarioError(
        fmt::format("--key: '{}': '{}' has {} entries (0-based: {}[0] .. {}[{}])", key, k.path,
                    arr->size(), k.path, k.path, arr->size() - 1));
  }
  for (const auto& n : *arr) k.entries.push_back(config::compact_toml(n));
}

// Case 0 at lo: the sweep axes (into res), the estimator names, and a check that the key loads.
// A swept key is searched instead of swept: `key.swept` gets its axis, which is reduced to the
// searched value and left out of the output's sweep columns.
std::vector<std::string> probe_scenario(const std::string& file,
                                        const std::vector<std::string>& sets,
                                        const FindOptions& opt, KeySetter& key, FindResult& res) {
  const LoadedScenario probe = load_cases(file, sets, {}, 0);
  key.path = opt.key;
  for (std::size_t a = 0; a < probe.sweeps.size(); ++a) {
    if (probe.sweeps[a].key == opt.key) key.swept = a;
  }
  if (!key.swept && !opt.key.empty() && opt.key.back() == ']')
    resolve_entry(probe, sets, opt.key, key);
  std::vector<std::string> s = sets;
  s.push_back(assignment(key, opt.lo));
  LoadedScenario first;
  try {
    first = load_cases(file, s, {}, 0);
  } catch (const config::ScenarioError& e) {
    rethrow_for_key(e, opt, key, opt.lo);
  }
  std::vector<std::string> names;
  for (const auto& e : first.cases.front().scenario->estimators) names.push_back(e.name);
  res.sweeps = first.sweeps;
  return names;
}

// The estimators searched: --estimator's (each refused unless one of `names`), else all.
std::vector<std::string> chosen_estimators(const std::string& file, const FindOptions& opt,
                                           const std::vector<std::string>& names) {
  std::vector<std::string> chosen = opt.estimators.empty() ? names : opt.estimators;
  for (const auto& n : chosen) {
    if (std::find(names.begin(), names.end(), n) == names.end()) {
      const std::string hint = config::did_you_mean(n, names);
      throw config::ScenarioError(
          fmt::format("--estimator: expected an estimator name of {}, got \"{}\"{}", file, n,
                      hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
  }
  return chosen;
}

// The sweep labels of case c (the last axis varies fastest).
std::vector<std::string> case_labels(const std::vector<SweepAxis>& sweeps, std::size_t c) {
  std::vector<std::string> labels(sweeps.size());
  std::size_t rem = c;
  for (std::size_t a = sweeps.size(); a-- > 0;) {
    labels[a] = sweeps[a].labels[rem % sweeps[a].labels.size()];
    rem /= sweeps[a].labels.size();
  }
  return labels;
}

// One case's quantities, each key value evaluated once for every estimator.
class CaseSamples {
 public:
  CaseSamples(const std::string& file, const std::vector<std::string>& sets, const FindOptions& opt,
              const KeySetter& key, std::size_t c)
      : file_(file), sets_(sets), opt_(opt), key_(key), c_(c) {}
  const Sample& at(double v) {
    auto it = cache_.find(v);
    if (it == cache_.end()) it = cache_.emplace(v, evaluate(file_, sets_, opt_, key_, c_, v)).first;
    return it->second;
  }

 private:
  const std::string& file_;
  const std::vector<std::string>& sets_;
  const FindOptions& opt_;
  const KeySetter& key_;
  std::size_t c_;
  std::map<double, Sample> cache_;  // key value -> every estimator's quantity
};

// One estimator's search: its quantity at a key value, each point kept (for the monotonicity
// check) and counted in the row's evaluations.
struct EstimatorSearch {
  CaseSamples& samples;
  const FindOptions& opt;
  FindRow& row;
  std::map<double, std::optional<double>> pts;
  std::optional<double> q(double v) {
    const std::optional<double> r = samples.at(v).at(row.estimator);
    pts[v] = r;
    ++row.evaluations;
    return r;
  }
  bool ok(double v) { return met(opt.target, q(v)); }
};

// Scans [lo, hi] in opt.scan intervals, counts the crossings of the target into the row, and
// bisects the crossing nearest lo down to opt.tol; the warnings go to log.
void search_row(EstimatorSearch& s, const std::string& where, std::ostream& log) {
  const FindOptions& opt = s.opt;
  FindRow& row = s.row;
  std::vector<double> xs;
  std::vector<bool> ok;
  for (int i = 0; i <= opt.scan; ++i) {
    const double v = i == opt.scan ? opt.hi : opt.lo + (opt.hi - opt.lo) * i / opt.scan;
    xs.push_back(v);
    ok.push_back(s.ok(v));
  }
  std::size_t first = xs.size();
  for (std::size_t i = 0; i + 1 < xs.size(); ++i) {
    if (ok[i] != ok[i + 1]) {
      ++row.crossings;
      if (first == xs.size()) first = i;
    }
  }
  if (row.crossings == 0) {
    row.status = "not_bracketed";
    log << fmt::format(
        "ncosim find: warning: \"{}\"{}: {} {} over [{}, {}]: no threshold in the range\n",
        row.estimator, where, opt.target.quantity,
        ok.front() ? "meets the target everywhere" : "never meets the target", opt.lo, opt.hi);
    return;
  }
  double a = xs[first], b = xs[first + 1];
  const bool ok_a = ok[first];
  while (b - a > opt.tol) {
    const double mid = 0.5 * (a + b);
    if (mid <= a || mid >= b) break;
    (s.ok(mid) == ok_a ? a : b) = mid;
  }
  row.threshold = ok_a ? a : b;
  row.other = ok_a ? b : a;
  row.value = s.pts[*row.threshold];
  row.status = row.crossings > 1 ? "several_crossings" : "ok";
  if (row.crossings > 1) {
    log << fmt::format(
        "ncosim find: warning: \"{}\"{}: the target is crossed {} times over the scan; "
        "the crossing nearest lo is reported\n",
        row.estimator, where, row.crossings);
  }
}

// The rows of case c: each chosen estimator's threshold, checked for monotonicity.
void search_case(const std::string& file, const std::vector<std::string>& sets,
                 const FindOptions& opt, const KeySetter& key, std::size_t c,
                 const std::vector<std::string>& chosen, std::ostream& log, FindResult& res) {
  const std::optional<std::size_t> swept = key.swept;
  const std::vector<std::string> labels = case_labels(res.sweeps, c);
  CaseSamples samples(file, sets, opt, key, c);
  std::vector<std::string> shown;
  for (std::size_t a = 0; a < labels.size(); ++a) {
    if (!swept || a != *swept) shown.push_back(labels[a]);
  }
  std::string where;
  for (std::size_t a = 0; a < labels.size(); ++a) {
    if (swept && a == *swept) continue;
    where += fmt::format("{}{} = {}", where.empty() ? " (" : ", ", res.sweeps[a].key, labels[a]);
  }
  if (!where.empty()) where += ")";
  for (const auto& name : chosen) {
    FindRow row;
    row.sweep_labels = shown;
    row.estimator = name;
    EstimatorSearch s{samples, opt, row, {}};
    search_row(s, where, log);
    row.monotone = is_monotone(s.pts);
    if (!row.monotone) {
      if (row.status == "ok") row.status = "not_monotone";
      log << fmt::format(
          "ncosim find: warning: \"{}\"{}: {} is not monotone in {} over the evaluated "
          "points; a bisection threshold may not be unique\n",
          name, where, opt.target.quantity, opt.key);
    }
    res.rows.push_back(std::move(row));
  }
}

}  // namespace

FindResult find_threshold(const std::string& file, const std::vector<std::string>& sets,
                          const FindOptions& opt, std::ostream& log) {
  check_find_options(opt);
  FindResult res;
  KeySetter key;
  const std::vector<std::string> names = probe_scenario(file, sets, opt, key, res);
  std::size_t total = 1;
  for (const auto& a : res.sweeps) total *= a.labels.size();
  const std::vector<std::string> chosen = chosen_estimators(file, opt, names);
  for (std::size_t c = 0; c < total; ++c) search_case(file, sets, opt, key, c, chosen, log, res);
  if (key.swept) res.sweeps.erase(res.sweeps.begin() + static_cast<std::ptrdiff_t>(*key.swept));
  return res;
}

std::string find_csv(const FindResult& result, const FindOptions& opt) {
  std::string out;
  std::vector<std::string> cols;
  for (const auto& s : result.sweeps) cols.push_back(s.key);
  for (const char* c : {"estimator", "key", "quantity", "op", "target", "threshold", "other_end",
                        "value_at_threshold", "evaluations", "monotone", "status"}) {
    cols.push_back(c);
  }
  for (std::size_t i = 0; i < cols.size(); ++i) out += (i ? "," : "") + csv_field(cols[i]);
  out += "\n";
  auto num = [](const std::optional<double>& v) {
    return v ? fmt::format("{:.10g}", *v) : std::string();
  };
  for (const auto& r : result.rows) {
    std::vector<std::string> cells = r.sweep_labels;
    cells.push_back(r.estimator);
    cells.push_back(opt.key);
    cells.push_back(opt.target.quantity);
    cells.push_back(opt.target.op);
    cells.push_back(fmt::format("{}", opt.target.value));
    cells.push_back(num(r.threshold));
    cells.push_back(num(r.other));
    cells.push_back(num(r.value));
    cells.push_back(std::to_string(r.evaluations));
    cells.push_back(r.monotone ? "true" : "false");
    cells.push_back(r.status);
    for (std::size_t i = 0; i < cells.size(); ++i) out += (i ? "," : "") + csv_field(cells[i]);
    out += "\n";
  }
  return out;
}

}  // namespace ncosim::sim

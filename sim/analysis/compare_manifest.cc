// sim/analysis/compare_manifest.cc — the identity of a compared folder and what differs between two
// (sim/analysis/compare_manifest.h).
#include "sim/analysis/compare_manifest.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "sim/files/csv.h"
#include "sim/scenario/scenario.h"
#include "sim/store/store.h"

namespace ncosim::sim {

namespace {

// How and when a campaign ran, not what it ran: never reported (command_line always differs in
// --out; runs_done .. shard are said by the partial-campaign warning; inputs have their own lines).
const std::set<std::string>& not_compared() {
  static const std::set<std::string> keys{
      "command_line",  "date",     "wall_seconds", "threads", "ranks",     "store", "runs_done",
      "runs_expected", "complete", "stopped",      "shard",   "links_csv", "inputs"};
  return keys;
}

// At most `width` characters (a scenario title, a long override list): the rest as "...".
std::string shortened(const std::string& s, std::size_t width = 80) {
  return s.size() <= width ? s : s.substr(0, width - 3) + "...";
}

// A manifest value as a user wrote it: a string bare, anything else as compact JSON.
std::string rendered(const nlohmann::json& v) {
  return v.is_string() ? v.get<std::string>() : v.dump();
}

}  // namespace

void read_folder_identity(const nlohmann::json& manifest, RunFolder& f) {
  for (auto it = manifest.begin(); it != manifest.end(); ++it)
    f.fields[it.key()] = rendered(it.value());
  if (const auto it = manifest.find("scenario_text_hash");
      it != manifest.end() && it->is_string()) {
    f.text_hash = it->get<std::string>();
  }
  const std::string store = (std::filesystem::path(f.dir) / "runs.sqlite").string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(store, ec)) return;
  try {
    const auto meta = RunStore::open(store, false).meta();
    const auto text = meta.find("scenario_text");
    if (text == meta.end()) return;
    f.text = text->second;
    if (f.text_hash) return;
    // A manifest of an older ncosim: the text hash from the text and --set the store holds.
    std::vector<std::string> sets;
    if (const auto o = meta.find("overrides"); o != meta.end() && !o->second.empty()) {
      sets = nlohmann::json::parse(o->second).get<std::vector<std::string>>();
    }
    f.text_hash = scenario_text_hash(f.text.value(), sets);
  } catch (const std::exception&) {
    // A damaged or foreign store: compare then goes by the manifest alone (export says why).
    f.text.reset();
  }
}

bool same_scenario_text(const RunFolder& base, const RunFolder& fresh) {
  if (base.text_hash && fresh.text_hash) return *base.text_hash == *fresh.text_hash;
  return base.scenario_hash == fresh.scenario_hash;
}

std::string first_differing_line(const std::string& a, const std::string& b) {
  // The line starting at `from` (nullopt past the end of the text) and where the next one starts.
  auto line_at = [](const std::string& s, std::size_t& from) -> std::optional<std::string> {
    if (from > s.size()) return std::nullopt;
    const std::size_t end = s.find('\n', from);
    std::string line = s.substr(from, end == std::string::npos ? std::string::npos : end - from);
    from = end == std::string::npos ? s.size() + 1 : end + 1;
    return line;
  };
  auto text = [](const std::optional<std::string>& l) {
    return l ? "`" + shortened(*l, 60) + "`" : "(end of file)";
  };
  std::size_t pa = 0, pb = 0;
  for (int line = 1; pa <= a.size() || pb <= b.size(); ++line) {
    const auto la = line_at(a, pa), lb = line_at(b, pb);
    if (la != lb) return fmt::format("line {}: {} -> {}", line, text(la), text(lb));
  }
  return "";
}

std::vector<std::string> manifest_differences(const RunFolder& base, const RunFolder& fresh) {
  std::vector<std::string> out;
  if (base.text && fresh.text && *base.text != *fresh.text) {
    out.push_back("scenario text: " + first_differing_line(*base.text, *fresh.text));
  }
  std::set<std::string> keys;
  for (const auto& [k, v] : base.fields) keys.insert(k);
  for (const auto& [k, v] : fresh.fields) keys.insert(k);
  auto get = [](const RunFolder& f, const std::string& k) {
    const auto it = f.fields.find(k);
    return it == f.fields.end() ? std::string("(absent)") : shortened(it->second);
  };
  for (const auto& k : keys) {
    if (not_compared().count(k) != 0) continue;
    const std::string b = get(base, k), n = get(fresh, k);
    if (b != n) out.push_back(fmt::format("{}: {} -> {}", k, b, n));
  }
  if (base.inputs && fresh.inputs) {
    std::set<std::string> files;
    for (const auto& [file, h] : *base.inputs) files.insert(file);
    for (const auto& [file, h] : *fresh.inputs) files.insert(file);
    auto hash = [](const std::map<std::string, std::string>& m, const std::string& file) {
      const auto it = m.find(file);
      return it == m.end() ? std::string("(not read)") : it->second;
    };
    for (const auto& file : files) {
      const std::string b = hash(*base.inputs, file), n = hash(*fresh.inputs, file);
      if (b != n) out.push_back(fmt::format("inputs '{}': {} -> {}", file, b, n));
    }
  }
  return out;
}

namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw CompareInputError(fmt::format("{}: cannot open the file", p.string()));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::optional<double> parse_number(const std::string& s) {
  if (s.empty()) return std::nullopt;
  double v = 0.0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (p != s.data() + s.size()) throw std::invalid_argument(s);
  // Beyond a double's range: +-inf on overflow (the callers refuse it), 0 or subnormal on
  // underflow.
  if (ec == std::errc::result_out_of_range) return std::strtod(s.c_str(), nullptr);
  if (ec != std::errc()) throw std::invalid_argument(s);
  return v;
}

std::string case_text(const std::vector<std::string>& keys,
                      const std::vector<std::string>& labels) {
  std::string out;
  for (std::size_t a = 0; a < keys.size(); ++a)
    out += fmt::format("{}{} = {}", a ? ", " : "", keys[a], labels[a]);
  return out;
}

}  // namespace

std::string row_text(const std::vector<std::string>& keys, const RunFolder::Row& r) {
  return keys.empty()
             ? fmt::format("estimator \"{}\"", r.estimator)
             : fmt::format("case {}, estimator \"{}\"", case_text(keys, r.labels), r.estimator);
}

namespace {

// manifest.json of the folder into f: scenario, title, hash, seed, inputs, identity and whether
// the campaign is partial.
void read_manifest(const fs::path& d, RunFolder& f) {
  const fs::path man = d / "manifest.json";
  nlohmann::json m;
  try {
    m = nlohmann::json::parse(slurp(man));
  } catch (const nlohmann::json::exception& e) {
    throw CompareInputError(fmt::format("{}: not valid JSON: {}", man.string(), e.what()));
  }
  try {
    f.scenario = m.at("scenario").get<std::string>();
    f.title = m.value("title", std::string());
    f.scenario_hash = m.at("scenario_hash").get<std::string>();
    f.seed = m.at("seed").get<std::uint64_t>();
    if (m.contains("inputs")) {
      std::map<std::string, std::string> in;
      for (auto it = m["inputs"].begin(); it != m["inputs"].end(); ++it)
        in[it.key()] = it.value().get<std::string>();
      f.inputs = std::move(in);
    }
  } catch (const nlohmann::json::exception& e) {
    throw CompareInputError(
        fmt::format("{}: expected the fields scenario, scenario_hash and seed of `ncosim run` ({})",
                    man.string(), e.what()));
  }
  read_folder_identity(m, f);
  if (m.contains("complete") && m["complete"].is_boolean() && !m["complete"].get<bool>()) {
    f.partial = fmt::format("{} of {} runs (a partial campaign: stopped, or one shard)",
                            m.value("runs_done", 0), m.value("runs_expected", 0));
  }
}

// The next record of runs.csv (false at the end); a malformed file is a CompareInputError.
bool next_record(CsvReader& reader, CsvRecord& r) {
  try {
    return reader.next(r);
  } catch (const CompareInputError&) {
    throw;
  } catch (const config::ScenarioError& e) {
    throw CompareInputError(e.what());
  }
}

// The columns of runs.csv that compare reads.
struct RunsColumns {
  std::size_t run, estimator, diverged, metric;
};

// The columns in runs.csv's header `head`; refuses a header not of `ncosim run` and a metric that
// is no per-run column (listing those there are).
RunsColumns runs_columns(const std::vector<std::string>& head, const std::string& metric,
                         const std::string& file) {
  auto col = [&](const std::string& name) -> std::size_t {
    const auto it = std::find(head.begin(), head.end(), name);
    return it == head.end() ? head.size() : static_cast<std::size_t>(it - head.begin());
  };
  const RunsColumns c{col("run"), col("estimator"), col("diverged"), col(metric)};
  if (c.run == head.size() || c.estimator != c.run + 1 || c.diverged == head.size()) {
    throw CompareInputError(
        fmt::format("{}:1: expected the header of `ncosim run`'s runs.csv ([sweep keys,] run, "
                    "estimator, ..., diverged, ...)",
                    file));
  }
  if (c.metric == head.size() || metric == "run" || metric == "estimator" || metric == "status" ||
      metric == "diverged") {
    std::string list;
    for (std::size_t i = c.estimator + 1; i < head.size(); ++i) {
      if (head[i] != "status" && head[i] != "diverged")
        list += (list.empty() ? "" : ", ") + head[i];
    }
    throw CompareInputError(fmt::format(
        "--metric: expected a per-run column of {} ({}), got \"{}\"", file, list, metric));
  }
  return c;
}

// A run index of record r: an integer 0 .. 2^53 (exact in a double).
std::int64_t run_index(const CsvRecord& r, std::size_t c_run, const std::string& file) {
  std::optional<double> run;
  try {
    run = parse_number(r.fields[c_run]);
  } catch (const std::invalid_argument&) {
  }
  if (!run || !(*run >= 0.0 && *run <= 9007199254740992.0) || *run != std::floor(*run)) {
    throw CompareInputError(
        fmt::format("{}:{}: run: expected a run index (an integer >= 0), got \"{}\"", file, r.line,
                    r.fields[c_run]));
  }
  return static_cast<std::int64_t>(*run);
}

// The metric of record r: empty (no value in this run), else a finite number >= 0 (every per-run
// column of runs.csv is); nan, inf, a negative value or one beyond a double's range is damaged
// input.
std::optional<double> metric_value(const CsvRecord& r, std::size_t c_metric,
                                   const std::string& metric, const std::string& file) {
  std::optional<double> value;
  try {
    value = parse_number(r.fields[c_metric]);
  } catch (const std::invalid_argument&) {
    throw CompareInputError(fmt::format("{}:{}: {}: expected a number, got \"{}\"", file, r.line,
                                        metric, r.fields[c_metric]));
  }
  if (value && !(std::isfinite(*value) && *value >= 0.0)) {
    throw CompareInputError(fmt::format("{}:{}: {}: expected a finite number >= 0, got \"{}\"",
                                        file, r.line, metric, r.fields[c_metric]));
  }
  return value;
}

// The records of runs.csv after its header into f.rows, one row per (sweep labels, estimator) in
// order of first appearance; `lines` gets, per row, the line of each run.
void read_runs(CsvReader& reader, std::size_t width, const RunsColumns& c,
               const std::string& metric, const std::string& file, RunFolder& f,
               std::vector<std::vector<int>>& lines) {
  std::map<std::pair<std::vector<std::string>, std::string>, std::size_t> index;
  CsvRecord r;
  while (next_record(reader, r)) {
    if (r.fields.size() != width) {
      throw CompareInputError(fmt::format("{}:{}: expected {} fields (the header's), got {}", file,
                                          r.line, width, r.fields.size()));
    }
    std::vector<std::string> labels(r.fields.begin(),
                                    r.fields.begin() + static_cast<std::ptrdiff_t>(c.run));
    auto key = std::make_pair(std::move(labels), r.fields[c.estimator]);
    auto it = index.find(key);
    if (it == index.end()) {
      it = index.emplace(key, f.rows.size()).first;
      f.rows.push_back({std::move(key.first), std::move(key.second), {}, {}, {}});
      lines.emplace_back();
    }
    RunFolder::Row& row = f.rows[it->second];
    const std::int64_t run = run_index(r, c.run, file);
    const std::optional<double> value = metric_value(r, c.metric, metric, file);
    row.run.push_back(run);
    row.value.push_back(value);
    row.diverged.push_back(r.fields[c.diverged] == "1");
    lines[it->second].push_back(r.line);
  }
}

// Refuses a run twice in one row, naming the earliest line that repeats a run.
void check_unique_runs(const RunFolder& f, const std::vector<std::vector<int>>& lines,
                       const std::string& file) {
  int dup_line = 0;
  std::size_t dup_row = 0;
  std::int64_t dup_run = 0;
  for (std::size_t k = 0; k < f.rows.size(); ++k) {
    const auto& runs_k = f.rows[k].run;
    std::vector<std::size_t> order(runs_k.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return runs_k[a] != runs_k[b] ? runs_k[a] < runs_k[b] : a < b;
    });
    for (std::size_t i = 1; i < order.size(); ++i) {
      if (runs_k[order[i]] != runs_k[order[i - 1]]) continue;
      const int line = lines[k][order[i]];
      if (dup_line == 0 || line < dup_line) {
        dup_line = line;
        dup_row = k;
        dup_run = runs_k[order[i]];
      }
    }
  }
  if (dup_line != 0) {
    throw CompareInputError(fmt::format("{}:{}: run {} of {} appears twice", file, dup_line,
                                        dup_run, row_text(f.sweep_keys, f.rows[dup_row])));
  }
}

}  // namespace

RunFolder read_run_folder(const std::string& dir, const std::string& metric) {
  RunFolder f;
  f.dir = dir;
  const fs::path d(dir);
  if (!fs::is_directory(d))
    throw CompareInputError(
        fmt::format("{}: not a directory (expected an ncosim run output folder)", dir));
  read_manifest(d, f);
  const fs::path runs = d / "runs.csv";
  const std::string file = runs.string();
  if (!fs::exists(runs) && fs::exists(d / "runs.sqlite")) {
    throw CompareInputError(fmt::format(
        "{}: missing; the folder holds a run store: `ncosim export {}` writes it", file, dir));
  }
  // Streamed one record at a time, keeping only the columns compare needs: memory follows the
  // runs of the metric, not the size of the file.
  std::ifstream in(runs, std::ios::binary);
  if (!in) throw CompareInputError(fmt::format("{}: cannot open the file", file));
  CsvReader reader(in, file);
  CsvRecord r;
  if (!next_record(reader, r))
    throw CompareInputError(
        fmt::format("{}: empty file (expected the runs.csv of `ncosim run`)", file));
  const std::vector<std::string> head = std::move(r.fields);
  const RunsColumns c = runs_columns(head, metric, file);
  std::vector<bool> keep(head.size(), false);
  for (std::size_t i = 0; i <= c.estimator; ++i) keep[i] = true;  // sweep labels, run, estimator
  keep[c.diverged] = keep[c.metric] = true;
  reader.keep_only(std::move(keep));
  f.sweep_keys.assign(head.begin(), head.begin() + static_cast<std::ptrdiff_t>(c.run));
  std::vector<std::vector<int>> lines;  // per row, the line of each run
  read_runs(reader, head.size(), c, metric, file, f, lines);
  check_unique_runs(f, lines, file);
  if (f.rows.empty())
    throw CompareInputError(
        fmt::format("{}: no runs (expected the runs.csv of `ncosim run`)", file));
  return f;
}

void read_row_statuses(RunFolder& f) {
  const fs::path file = fs::path(f.dir) / "summary.csv";
  std::error_code ec;
  if (!fs::exists(file, ec)) return;
  CsvTable t;
  try {
    t = parse_csv(slurp(file), file.string());
  } catch (const CompareInputError&) {
    throw;
  } catch (const config::ScenarioError& e) {
    throw CompareInputError(e.what());
  }
  const int c_est = t.column("estimator"), c_status = t.column("status"),
            c_exp = t.column("expected_status");
  if (c_est < 0 || c_status < 0) return;
  std::map<std::pair<std::vector<std::string>, std::string>, std::size_t> index;
  for (std::size_t i = 0; i < f.rows.size(); ++i)
    index[{f.rows[i].labels, f.rows[i].estimator}] = i;
  f.statuses.assign(f.rows.size(), {});
  for (const auto& cells : t.rows) {
    std::vector<std::string> labels;
    for (const auto& k : f.sweep_keys) {
      const int c = t.column(k);
      labels.push_back(c < 0 ? "" : cells[static_cast<std::size_t>(c)]);
    }
    const auto it = index.find({labels, cells[static_cast<std::size_t>(c_est)]});
    if (it == index.end()) continue;
    auto& st = f.statuses[it->second];
    st.status = cells[static_cast<std::size_t>(c_status)];
    if (c_exp >= 0) st.expected_status = cells[static_cast<std::size_t>(c_exp)];
  }
}

}  // namespace ncosim::sim

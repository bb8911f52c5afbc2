// sim/scenario/scenario.cc — scenario loading: TOML parse, --set overrides, sweeps, validation,
// design.
#include "sim/scenario/scenario.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "sim/scenario/registries.h"
#include "sim/scenario/resource_limits.h"
#include "sim/scenario/scenario_check.h"
#include "sim/scenario/scenario_document.h"
#include "sim/scenario/scenario_keys.h"
#include "sim/scenario/scenario_sections.h"

namespace ncosim::sim {

std::string fnv1a_hex(const std::string& text) {
  return config::content_hash(text);
}  // config/input_files.h

namespace {

std::string text_and_sets(const std::string& text, const std::vector<std::string>& sets) {
  std::string hashed = text;
  for (const auto& s : sets) hashed += "\n--set " + s;
  return hashed;
}

}  // namespace

std::string scenario_text_hash(const std::string& text, const std::vector<std::string>& sets) {
  return fnv1a_hex(text_and_sets(text, sets));
}

namespace {

// The largest scenario file read (bytes; documented in scenarios/README.md).
constexpr std::uintmax_t kMaxScenarioBytes = 64'000'000;

}  // namespace

std::unique_ptr<Scenario> build_scenario(const toml::table& doc, const std::string& file,
                                         const std::string& dir) {
  auto sc = std::make_unique<Scenario>();
  sc->file = file;
  config::Table root(doc, "", file);
  sc->title = config::KeyReader(root, top_level_keys())
                  .opt_string("title")
                  .value_or(std::filesystem::path(file).stem().string());
  // Unknown top-level keys first (a misspelt [[sensor]] is reported as such, not as a missing
  // table): the declared ones (sim/scenario/scenario_keys.h) are known.
  for (const config::Key& key : top_level_keys().list()) root.allow(key.name());
  root.finish();
  // The sections, each by its reader (sim/scenario/scenario_sections.h), in an order where every
  // reader finds what it refers to.
  sc->run = read_run(root);
  // [sumo]: vehicle mobility (sumo/); the readers below name the vehicles they need, and the
  // realisations are recorded (or reused) once every reader has run, before the designs.
  if (const auto sumo = root.opt_table("sumo")) sc->mobility = make_mobility(*sumo, sc->run, dir);
  const std::string state_size_driver = read_plant(root, doc, *sc);
  read_networks(root, *sc);
  read_links(root, dir, *sc);
  read_sensors(root, *sc);
  drop_doubled_riders(*sc);
  read_actuators(root, *sc);
  check_networks(root, *sc);
  if (sc->mobility) sc->mobility->prepare();
  const std::optional<config::Table> input = read_input(root, *sc);
  read_estimators(root, doc, state_size_driver, *sc);
  bind_feedback_source(input, *sc);
  choose_recentre(root, *sc);
  {
    const auto rt = root.opt_table("run");
    check_campaign_resources(file, rt ? rt->line_of("runs") : 1, sc->run.runs, 1,
                             sc->estimators.size(), sc->model.plant.n(),
                             sc->model.sensors.size());  // sim/scenario/resource_limits.h
    if (sc->run.error_curve) {
      CurveTotals curve;
      curve.add(sc->run.periods, sc->estimators.size(), sc->model.plant.n());
      check_error_curve_resources(file, rt ? rt->line_of("error_curve") : 1, "run.error_curve",
                                  curve);
    }
  }
  sc->paired = read_paired(root, doc, *sc);
  root.finish();
  return sc;
}

namespace {

// The error curve of the case just built: error_curve.csv is one file for every case (so the key
// is the same in every case), and the exports hold every case's curve at once (`curves`, checked
// against --max-memory as the cases are built).
void check_case_curve(const LoadedScenario& out, const std::string& file, int line,
                      CurveTotals& curves) {
  const Scenario& built = *out.cases.back().scenario;
  if (built.run.error_curve != out.cases.front().scenario->run.error_curve) {
    throw config::ScenarioError(config::format_error(
        file, line, "run.error_curve",
        "expected the same value in every sweep case (error_curve.csv covers them "
        "all), got both true and false"));
  }
  if (!built.run.error_curve) return;
  curves.add(built.run.periods, built.estimators.size(), built.model.plant.n());
  if (curves.cases() > 1) check_error_curve_resources(file, line, "sweep", curves);
}

}  // namespace

// The scenario text parsed, with --set and the [run] options applied. Parsed afresh for every
// sweep case: toml++ copies drop the source lines that error messages need.
toml::table parse_document(const std::string& text, const std::string& file,
                           const std::vector<std::string>& sets, const RunOverrides& overrides) {
  toml::table doc;
  try {
    doc = toml::parse(text, std::string_view(file));
  } catch (const toml::parse_error& e) {
    throw config::ScenarioError(
        config::format_error(file, static_cast<int>(e.source().begin.line), "",
                             fmt::format("TOML syntax error: {}", e.description())));
  }
  for (const auto& s : sets) config::apply_set(doc, s, "--set");
  auto override_run = [&](const char* key, std::int64_t value, const char* option) {
    toml::table parsed = config::parse_value(key, std::to_string(value), option);
    config::set_path(doc, fmt::format("run.{}", key), std::move(*parsed.get("value")), option, 0);
  };
  if (overrides.runs > 0) override_run("runs", overrides.runs, "--runs");
  if (overrides.periods > 0) override_run("periods", overrides.periods, "--periods");
  if (overrides.seed) override_run("seed", static_cast<std::int64_t>(*overrides.seed), "--seed");
  return doc;
}

namespace {

// A swept value as written in summary.csv: strings bare, numbers in their shortest exact
// form ("0.3", not toml++'s "0.29999999999999999"), arrays as "[0.9, 0.05]".
std::string sweep_label(const toml::node& v) {
  if (auto s = v.value_exact<std::string>()) return *s;
  return config::compact_toml(v);
}

// The `values` array of [[sweep]] number `axis`.
toml::array& sweep_values(toml::table& doc, std::size_t axis) {
  return *doc.get("sweep")->as_array()->get(axis)->as_table()->get("values")->as_array();
}

}  // namespace

namespace {

std::map<std::string, std::string>& in_memory_texts() {
  static std::map<std::string, std::string> texts;
  return texts;
}

}  // namespace

ScenarioText::ScenarioText(std::string name, std::string text) : name_(std::move(name)) {
  if (!in_memory_texts().emplace(name_, std::move(text)).second)
    throw std::logic_error("ncosim::sim::ScenarioText: \"" + name_ + "\" is already held");
}

ScenarioText::~ScenarioText() { in_memory_texts().erase(name_); }

LoadedScenario load_cases(const std::string& file, const std::vector<std::string>& sets,
                          const RunOverrides& overrides, std::optional<std::size_t> only_case) {
  if (const auto it = in_memory_texts().find(file); it != in_memory_texts().end())
    return load_cases_text(file, it->second, sets, overrides, only_case);
  {
    // A regular file of bounded size: a FIFO or device would block or never end.
    std::error_code ec;
    const auto st = std::filesystem::status(file, ec);
    if (!ec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
      throw config::ScenarioError(config::format_error(
          file, 0, "", "expected a regular scenario file (not a FIFO, device or folder)"));
    }
    const auto size = std::filesystem::file_size(file, ec);
    if (!ec && size > kMaxScenarioBytes) {
      throw config::ScenarioError(
          config::format_error(file, 0, "",
                               fmt::format("the scenario file holds {} bytes; at most {} are read",
                                           size, kMaxScenarioBytes)));
    }
  }
  std::ifstream in(file, std::ios::binary);
  if (!in)
    throw config::ScenarioError(config::format_error(file, 0, "", "cannot open the scenario file"));
  std::stringstream ss;
  ss << in.rdbuf();
  return load_cases_text(file, ss.str(), sets, overrides, only_case);
}

namespace {

// The [[sweep]] axes of `doc` (each key's path validated on a scratch copy), appended to
// out.sweeps. Returns the line of the last axis' values (1 without sweeps), where a sweep that
// is too large is reported.
// Axes sharing a `zip` name are one dimension of the cartesian product (they move together;
// equal lengths), placed at its first axis: `axis_sizes` receives the size of each dimension,
// `axis_dim` the dimension of each axis.
int read_sweeps(toml::table& doc, const std::string& file, LoadedScenario& out,
                std::vector<std::size_t>& axis_sizes, std::vector<std::size_t>& axis_dim) {
  int last_sweep_line = 1;
  std::vector<std::string> dim_zip;  // per dimension: its zip name ("" = a plain axis)
  config::Table root(doc, "", file);
  const auto sweep_tables = root.tables("sweep");
  for (std::size_t a = 0; a < sweep_tables.size(); ++a) {
    const config::Table& t = sweep_tables[a];
    SweepAxis axis;
    const config::KeyReader k(t, sweep_keys());
    axis.key = k.string("key");
    const int key_line = t.line_of("key");
    if (axis.key == "sweep" || axis.key.starts_with("sweep.") || axis.key.starts_with("sweep[")) {
      t.fail("key",
             fmt::format("expected the key path of a scenario value, got \"{}\" (a sweep cannot "
                         "change the sweeps)",
                         axis.key));
    }
    t.allow("values");
    const std::string zip = k.opt_string("zip").value_or("");
    const toml::node* vals = doc.get("sweep")->as_array()->get(a)->as_table()->get("values");
    if (vals == nullptr || !vals->is_array() || vals->as_array()->empty()) {
      t.fail("values", fmt::format("expected a non-empty array of values, got {}",
                                   vals == nullptr ? std::string("nothing (the key is required)")
                                                   : config::describe(*vals)));
    }
    for (const toml::node& v : *vals->as_array()) axis.labels.push_back(sweep_label(v));
    t.finish();
    for (const auto& prev : out.sweeps) {
      if (prev.key == axis.key)
        t.fail("key", fmt::format("expected each swept key once, got \"{}\" twice", axis.key));
    }
    // Validate the path now, on a scratch copy.
    toml::table scratch = doc;
    config::set_path(scratch, axis.key, *vals->as_array()->get(0), file, key_line);
    last_sweep_line = std::max(1, t.line_of("values"));
    const std::size_t size = vals->as_array()->size();
    std::size_t dim = axis_sizes.size();
    if (!zip.empty()) {
      for (std::size_t d = 0; d < dim_zip.size(); ++d) {
        if (dim_zip[d] == zip) dim = d;
      }
    }
    if (dim == axis_sizes.size()) {
      axis_sizes.push_back(size);
      dim_zip.push_back(zip);
    } else if (axis_sizes[dim] != size) {
      t.fail("values",
             fmt::format("expected {} values like the other sweeps zipped as \"{}\", got {}",
                         axis_sizes[dim], zip, size));
    }
    axis_dim.push_back(dim);
    out.sweeps.push_back(std::move(axis));
  }
  return last_sweep_line;
}

// The key path an error names (format_error's "key 'PATH': "), or "" when it names none.
std::string error_key(const std::string& what) {
  const auto a = what.find("key '");
  if (a == std::string::npos) return "";
  const auto b = what.find('\'', a + 5);
  return b == std::string::npos ? "" : what.substr(a + 5, b - a - 5);
}

// Whether path `a` is `b` or lies inside it ("link[0].loss" in "link[0]").
bool inside(const std::string& a, const std::string& b) {
  return a == b || (a.size() > b.size() && a.compare(0, b.size(), b) == 0 &&
                    (a[b.size()] == '.' || a[b.size()] == '['));
}

// Whether an error of one variant of a swept scenario (a case, or the values written outside
// [[sweep]]) concerns the sweep: it names a swept key (or a key inside or around one), or the
// same scenario with other swept values (`other`: its error, nullopt when it builds) does not
// fail alike. A typo elsewhere fails every variant alike: a suffix about the sweep would only send
// the user looking in the wrong place.
bool concerns_sweep(const std::string& what, const LoadedScenario& out,
                    const std::function<std::optional<std::string>()>& other) {
  const std::string key = error_key(what);
  for (const auto& axis : out.sweeps) {
    if (!key.empty() && (inside(key, axis.key) || inside(axis.key, key))) return true;
  }
  const auto other_error = other();
  return !other_error || *other_error != what;
}

// The error of building `doc` (nullopt when it builds).
std::optional<std::string> build_error(toml::table& doc, const std::string& file,
                                       const std::string& dir) {
  try {
    (void)build_scenario(doc, file, dir);
  } catch (const config::ScenarioError& e) {
    return std::string(e.what());
  } catch (const std::exception& e) {
    return std::string("other: ") + e.what();
  }
  return std::nullopt;
}

// The swept values of case `c` (the first axis varying slowest) moved into `case_doc`; returns
// the case's labels, one per axis.
std::vector<std::string> apply_case(toml::table& case_doc, std::size_t c,
                                    const std::vector<std::size_t>& axis_sizes,
                                    const std::vector<std::size_t>& axis_dim,
                                    const LoadedScenario& out) {
  std::size_t rem = c;
  std::vector<std::size_t> idx(axis_sizes.size());
  for (std::size_t a = axis_sizes.size(); a-- > 0;) {
    idx[a] = rem % axis_sizes[a];
    rem /= axis_sizes[a];
  }
  std::vector<std::string> labels;
  for (std::size_t a = 0; a < axis_dim.size(); ++a) {
    // Moved, not copied: an error at the swept value then points at its line in `values`.
    const std::size_t i = idx[axis_dim[a]];
    toml::node& value = *sweep_values(case_doc, a).get(i);
    config::set_path(case_doc, out.sweeps[a].key, std::move(value), out.file, 0);
    labels.push_back(out.sweeps[a].labels[i]);
  }
  return labels;
}

// What the sweep's sizes and the options that parse a document are, for building other cases.
struct SweepShape {
  std::vector<std::size_t> axis_sizes, axis_dim;
  std::size_t total = 1;
  const std::vector<std::string>* sets = nullptr;
  const RunOverrides* overrides = nullptr;
  std::string dir;
};

// The error of case `c` built afresh (nullopt when it builds).
std::optional<std::string> case_error(std::size_t c, const SweepShape& shape,
                                      const LoadedScenario& out) {
  toml::table doc = parse_document(out.text, out.file, *shape.sets, *shape.overrides);
  try {
    (void)apply_case(doc, c, shape.axis_sizes, shape.axis_dim, out);
  } catch (const config::ScenarioError& e) {
    return std::string(e.what());
  }
  return build_error(doc, out.file, shape.dir);
}

// The base values of swept keys are validated too (as one whole scenario) when one of them is
// not among its swept values: a value in the file must be valid even when a sweep replaces it.
// Axes without a base value take their first value.
void check_base_scenario(const toml::table& doc, const LoadedScenario& out,
                         const SweepShape& shape) {
  std::vector<std::size_t> missing;
  bool unchecked = false;
  for (std::size_t a = 0; a < out.sweeps.size(); ++a) {
    const toml::node* base = config::find_path(doc, out.sweeps[a].key);
    if (base == nullptr) {
      missing.push_back(a);
      continue;
    }
    const auto& labels = out.sweeps[a].labels;
    unchecked =
        unchecked || std::find(labels.begin(), labels.end(), sweep_label(*base)) == labels.end();
  }
  if (!unchecked) return;
  toml::table base_doc = parse_document(out.text, out.file, *shape.sets, *shape.overrides);
  for (const std::size_t a : missing) {
    toml::node& value = *sweep_values(base_doc, a).get(0);
    config::set_path(base_doc, out.sweeps[a].key, std::move(value), out.file, 0);
  }
  try {
    (void)build_scenario(base_doc, out.file, shape.dir);
  } catch (const config::ScenarioError& e) {
    if (!concerns_sweep(e.what(), out, [&] { return case_error(0, shape, out); })) throw;
    throw config::ScenarioError(
        fmt::format("{} (in the base scenario: the values written outside [[sweep]] must be "
                    "valid too, even where a sweep replaces them)",
                    e.what()));
  }
}

// Case `c` of the sweeps built from `case_doc`; errors that concern the sweep name the case's
// swept values.
Case build_case(toml::table& case_doc, std::size_t c, const SweepShape& shape,
                const LoadedScenario& out) {
  Case cs;
  cs.labels = apply_case(case_doc, c, shape.axis_sizes, shape.axis_dim, out);
  try {
    cs.scenario = build_scenario(case_doc, out.file, shape.dir);
  } catch (const config::ScenarioError& e) {
    if (cs.labels.empty()) throw;
    const auto other = [&]() -> std::optional<std::string> {
      if (shape.total < 2) return std::string(e.what());  // no other case: the key decides
      return case_error(c == 0 ? 1 : 0, shape, out);
    };
    if (!concerns_sweep(e.what(), out, other)) throw;
    std::string where;
    for (std::size_t a = 0; a < cs.labels.size(); ++a) {
      where += fmt::format("{}{} = {}", a ? ", " : "", out.sweeps[a].key, cs.labels[a]);
    }
    throw config::ScenarioError(fmt::format("{} (in the sweep case {})", e.what(), where));
  }
  return cs;
}

}  // namespace

LoadedScenario load_cases_text(const std::string& file, const std::string& text,
                               const std::vector<std::string>& sets, const RunOverrides& overrides,
                               std::optional<std::size_t> only_case) {
  LoadedScenario out;
  // What the readers open, hashed, keyed relative to the scenario's folder.
  const config::InputFileRecorder record_inputs(out.inputs,
                                                std::filesystem::path(file).parent_path().string());
  out.file = file;
  out.text = text;
  out.overrides = sets;
  // The campaign's hash also covers the [run] overrides (resume and merge identity, committed
  // references' manifests); the text hash does not (results/README.md, manifest.json).
  std::string hashed = text_and_sets(out.text, sets);
  out.text_hash = fnv1a_hex(hashed);
  if (overrides.runs > 0) hashed += "\n--runs " + std::to_string(overrides.runs);
  if (overrides.periods > 0) hashed += "\n--periods " + std::to_string(overrides.periods);
  if (overrides.seed) hashed += "\n--seed " + std::to_string(*overrides.seed);
  out.hash = fnv1a_hex(hashed);

  toml::table doc = parse_document(out.text, file, sets, overrides);
  check_scenario_keys(doc, file);  // every key-level error at once, before anything is built
  // Sweeps: cartesian product, the first axis varying slowest (zipped axes: one dimension).
  std::vector<std::size_t> axis_sizes, axis_dim;
  const int last_sweep_line = read_sweeps(doc, file, out, axis_sizes, axis_dim);
  std::size_t total = 1;
  for (const std::size_t n : axis_sizes) {
    total *= n;
    if (total > 100000) {
      throw config::ScenarioError(config::format_error(
          file, last_sweep_line, "sweep",
          "expected at most 100000 cases (the product of the [[sweep]] value counts), "
          "got more"));
    }
  }
  check_sweep_resources(file, last_sweep_line, total, out.text.size());  // resource_limits.h
  const std::string dir = std::filesystem::path(file).parent_path().string();
  const SweepShape shape{axis_sizes, axis_dim, total, &sets, &overrides, dir};
  if (!out.sweeps.empty() && !only_case) check_base_scenario(doc, out, shape);
  if (only_case && *only_case >= total) {
    throw config::ScenarioError(config::format_error(
        file, 0, "sweep",
        fmt::format("expected a case index below {}, got {}", total, *only_case)));
  }
  // Mobility (SUMO): every case's document is shown to the mobility source first, so that one
  // recording per realisation can serve every case.
  if (doc.contains("sumo") && total > 1 && !only_case) {
    for (std::size_t c = 0; c < total; ++c) {
      toml::table case_doc = parse_document(out.text, file, sets, overrides);
      std::size_t rem = c;
      std::vector<std::size_t> idx(axis_sizes.size());
      for (std::size_t a = axis_sizes.size(); a-- > 0;) {
        idx[a] = rem % axis_sizes[a];
        rem /= axis_sizes[a];
      }
      try {
        for (std::size_t a = 0; a < axis_dim.size(); ++a) {
          config::set_path(case_doc, out.sweeps[a].key,
                           *sweep_values(case_doc, a).get(idx[axis_dim[a]]), file, 0);
        }
      } catch (const config::ScenarioError&) {
        continue;  // reported when the case is built
      }
      announce_mobility(case_doc, file, dir);
    }
  }
  CurveTotals curves;  // sim/scenario/resource_limits.h
  for (std::size_t c = 0; c < total; ++c) {
    if (only_case && c != *only_case) continue;
    toml::table case_doc =
        c == 0 ? std::move(doc) : parse_document(out.text, file, sets, overrides);
    out.cases.push_back(build_case(case_doc, c, shape, out));
    check_case_curve(out, file, last_sweep_line, curves);
  }
  return out;
}

}  // namespace ncosim::sim

// sim/scenario.cc — scenario loading: TOML parse, --set overrides, sweeps, validation, design.
#include "sim/scenario.h"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "kernel/time.h"
#include "lmi/limits.h"
#include "lmi/lmi.h"
#include "sim/limits.h"
#include "sim/registries.h"

namespace ncosim::sim {

std::string fnv1a_hex(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : text) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return fmt::format("{:016x}", h);
}

namespace {

// The largest scenario file read (bytes; documented in scenarios/README.md).
constexpr std::uintmax_t kMaxScenarioBytes = 64'000'000;

struct PathSegment {
  std::string key;
  std::optional<std::size_t> index;
};

std::vector<PathSegment> parse_path(const std::string& path, const std::string& origin, int line) {
  std::vector<PathSegment> out;
  std::size_t i = 0;
  auto bad = [&](const std::string& why) {
    throw ScenarioError(format_error(origin, line, path, why));
  };
  while (i < path.size()) {
    std::size_t j = i;
    while (j < path.size() && path[j] != '.' && path[j] != '[') ++j;
    if (j == i) bad("expected a key path like 'estimator[0].history' or 'run.runs'");
    PathSegment seg{path.substr(i, j - i), std::nullopt};
    if (j < path.size() && path[j] == '[') {
      const std::size_t close = path.find(']', j);
      if (close == std::string::npos) bad("expected ']' in the key path");
      const std::string idx = path.substr(j + 1, close - j - 1);
      if (idx.empty() || idx.find_first_not_of("0123456789") != std::string::npos) {
        bad(fmt::format("expected a 0-based index inside [], got '{}'", idx));
      }
      seg.index = std::stoul(idx);
      j = close + 1;
    }
    out.push_back(seg);
    if (j < path.size()) {
      if (path[j] != '.') bad("expected '.' between keys");
      ++j;
      if (j == path.size()) bad("the key path ends with '.'");
    }
    i = j;
  }
  if (out.empty()) bad("expected a key path");
  if (out.back().index) bad("expected the path to end with a key, not an index");
  return out;
}

}  // namespace

namespace {

// The table that holds the last key of `path` (intermediate tables are created).
toml::table& parent_of(toml::table& doc, const std::string& path,
                       const std::vector<PathSegment>& segs, const std::string& origin, int line) {
  toml::table* cur = &doc;
  std::string walked;
  for (std::size_t s = 0; s + 1 < segs.size(); ++s) {
    const auto& seg = segs[s];
    walked += (walked.empty() ? "" : ".") + seg.key;
    toml::node* n = cur->get(seg.key);
    if (seg.index) {
      toml::array* arr = n ? n->as_array() : nullptr;
      const std::size_t size = arr ? arr->size() : 0;
      if (*seg.index >= size) {
        throw ScenarioError(format_error(
            origin, line, path,
            fmt::format("there is no [[{}]] number {} (the scenario has {}; indices are 0-based)",
                        seg.key, *seg.index, size)));
      }
      toml::table* t = (*arr)[*seg.index].as_table();
      if (t == nullptr) {
        throw ScenarioError(format_error(origin, line, path, fmt::format("'{}' is not an array of tables", walked)));
      }
      cur = t;
      walked += fmt::format("[{}]", *seg.index);
    } else {
      if (n == nullptr) {
        cur->insert(seg.key, toml::table{});
        n = cur->get(seg.key);
      }
      if (!n->is_table()) {
        throw ScenarioError(format_error(origin, line, path, fmt::format("'{}' is not a table", walked)));
      }
      cur = n->as_table();
    }
  }
  return *cur;
}

// Parses `value = TEXT` with `origin` as the source path, so that errors at the value name
// the option that set it (see kCommandLineOrigin).
toml::table parse_value(const std::string& key, const std::string& text,
                        const std::string& origin) {
  try {
    return toml::parse("value = " + text, std::string_view(origin));
  } catch (const toml::parse_error& e) {
    throw ScenarioError(format_error(
        origin, 0, key,
        fmt::format("expected a TOML value (e.g. 4, 0.5, \"S4\", [0.9, 0.05]), got '{}': {}", text,
                    e.description())));
  }
}

}  // namespace

void set_path(toml::table& doc, const std::string& path, const toml::node& value,
              const std::string& origin, int line) {
  const auto segs = parse_path(path, origin, line);
  parent_of(doc, path, segs, origin, line).insert_or_assign(segs.back().key, value);
}

void set_path(toml::table& doc, const std::string& path, toml::node&& value,
              const std::string& origin, int line) {
  const auto segs = parse_path(path, origin, line);
  // Moving keeps the value's source (file and line, or command-line origin) for error messages;
  // toml++ drops it on copies.
  parent_of(doc, path, segs, origin, line).insert_or_assign(segs.back().key, std::move(value));
}

void apply_set(toml::table& doc, const std::string& assignment, const std::string& origin) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ScenarioError(format_error(origin, 0, "", fmt::format("expected KEY=VALUE, got '{}'", assignment)));
  }
  std::string key = assignment.substr(0, eq);
  while (!key.empty() && key.back() == ' ') key.pop_back();
  while (!key.empty() && key.front() == ' ') key.erase(0, 1);
  toml::table parsed = parse_value(key, assignment.substr(eq + 1), origin);
  set_path(doc, key, std::move(*parsed.get("value")), origin, 0);
}

namespace {

RunSettings read_run(const Table& root) {
  RunSettings r;
  const auto t = root.opt_table("run");
  if (!t) return r;
  r.periods = t->integer_or("periods", r.periods);
  if (r.periods < 1 || r.periods > 1'000'000'000) {
    t->fail("periods", fmt::format("expected an integer in 1..1000000000 (1e9), got {}", r.periods));
  }
  r.warmup = t->integer_or("warmup", std::min<std::int64_t>(r.warmup, r.periods / 10));
  if (r.warmup < 0 || r.warmup >= r.periods) {
    t->fail("warmup", fmt::format("expected an integer in 0..periods-1 ({}), got {}", r.periods - 1, r.warmup));
  }
  r.runs = t->integer_or("runs", r.runs);
  if (r.runs < 1 || r.runs > 10'000'000) {
    t->fail("runs", fmt::format("expected an integer in 1..10000000 (1e7), got {}", r.runs));
  }
  const auto seed = t->integer_or("seed", 1);
  if (seed < 0) t->fail("seed", fmt::format("expected a non-negative integer, got {}", seed));
  r.seed = static_cast<std::uint64_t>(seed);
  r.period = t->number_or("period", 1.0);
  if (!(r.period > 0.0 && r.period <= 1e6) || seconds_to_time(r.period) <= 0) {
    t->fail("period", fmt::format("expected a period in seconds in (1e-9, 1e6], got {}", r.period));
  }
  // The integer-ns clock must hold every event time (arrivals may lie beyond the horizon).
  if (static_cast<double>(r.periods) * static_cast<double>(seconds_to_time(r.period)) > 4.0e18) {
    t->fail("period", fmt::format("expected periods x period <= 4e9 s (the nanosecond clock), got {} x {} s",
                                  r.periods, r.period));
  }
  r.recentre = t->choice_or("recentre", "auto", {"auto", "always", "never"});
  t->finish();
  return r;
}

}  // namespace

std::unique_ptr<Scenario> build_scenario(const toml::table& doc, const std::string& file, const std::string& dir) {
  auto sc = std::make_unique<Scenario>();
  sc->file = file;
  Table root(doc, "", file);
  sc->title = root.string_or("title", std::filesystem::path(file).stem().string());
  // Unknown top-level keys first (a misspelt [[sensor]] is reported as such, not as a missing
  // table). Every top-level key read below must be listed here.
  for (const char* key : {"run", "sweep", "plant", "link", "sensor", "input", "estimator", "actuator", "sumo", "paired"})
    root.allow(key);
  root.finish();
  sc->run = read_run(root);
  // [sumo]: vehicle mobility (sumo/); the readers below name the vehicles they need, and the
  // realisations are recorded (or reused) once every reader has run, before the designs.
  if (const auto sumo = root.opt_table("sumo")) sc->mobility = make_mobility(*sumo, sc->run, dir);

  // Plant.
  if (!root.has("plant")) {
    throw ScenarioError(format_error(file, 1, "plant", "expected a [plant] table (required: the plant model), got none"));
  }
  const Table plant = root.table("plant");
  const auto& pk = plant_registry().lookup(plant, "kind", "lti");
  sc->plant_kind = pk.name;
  sc->model.plant = pk.factory(plant, sc->run.period);
  sc->model.period = sc->run.period;
  sc->disturbance = models::read_disturbance(plant, sc->model.plant.nw());
  if (pk.name.starts_with("sumo_")) {
    if (!sc->mobility) plant.fail("kind", fmt::format("expected a [sumo] table for plant kind \"{}\"", pk.name));
    sc->plant_vehicle = sc->mobility->vehicle(plant, "vehicle");
  }
  const std::string state_size_driver = state_driver(plant, *doc.get("plant")->as_table(), sc->model);
  plant.finish();

  // Links.
  std::vector<std::string> link_names;
  const models::LinkContext ctx{dir, sc->run.period, sc->mobility};
  for (const Table& t : root.tables("link")) {
    LinkEntry e;
    e.name = t.string("name");
    if (std::find(link_names.begin(), link_names.end(), e.name) != link_names.end()) {
      t.fail("name", fmt::format("expected a unique link name, got \"{}\" twice", e.name));
    }
    const auto& k = link_registry().lookup(t, "kind", "");
    e.kind = k.name;
    e.link = k.factory(t, ctx);
    t.finish();
    link_names.push_back(e.name);
    sc->links.push_back(std::move(e));
  }

  // Sensors.
  const auto sensor_tables = root.tables("sensor");
  if (sensor_tables.empty())
    root.fail("sensor", "expected at least one [[sensor]] table, got none");
  std::set<std::string> sensor_names;
  for (std::size_t i = 0; i < sensor_tables.size(); ++i) {
    const Table& t = sensor_tables[i];
    est::SensorModel sm;
    sm.spec = models::read_sensor(t, sc->model.plant, link_names, static_cast<int>(i));
    if (!sensor_names.insert(sm.spec.name).second) {
      t.fail("name", fmt::format("expected a unique sensor name, got \"{}\" twice", sm.spec.name));
    }
    if (sm.spec.link >= 0) sm.link = sc->links[static_cast<std::size_t>(sm.spec.link)].link.get();
    if (sm.link != nullptr && sm.link->independent_copies() && sm.spec.buffer > 0) {
      t.fail("buffer", fmt::format("expected buffer = 0 on a link with independent copies (link \"{}\"), got {}",
                                   link_names[static_cast<std::size_t>(sm.spec.link)], sm.spec.buffer));
    }
    t.finish();
    sc->model.sensors.push_back(std::move(sm));
  }
  // Trace links must hold every packet a run sends.
  for (std::size_t l = 0; l < sc->links.size(); ++l) {
    const auto* trace = dynamic_cast<const models::TraceLink*>(sc->links[l].link.get());
    if (trace == nullptr) continue;
    std::int64_t packets = 0;
    for (const auto& s : sc->model.sensors) {
      if (s.spec.link == static_cast<int>(l)) packets += (sc->run.periods + s.spec.every - 1) / s.spec.every;
    }
    if (static_cast<std::int64_t>(trace->size()) < packets) {
      const Table t = root.tables("link")[l];
      t.fail("file", fmt::format("expected a trace of at least {} packets (one run sends {}), got {}",
                                 packets, packets, trace->size()));
    }
  }

  // Actuators (controller-to-actuator links): one per input channel, in input order.
  const auto act_tables = root.tables("actuator");
  if (!act_tables.empty()) {
    const Eigen::Index nu = sc->model.plant.nu();
    if (static_cast<Eigen::Index>(act_tables.size()) != nu) {
      act_tables.back().fail_here(fmt::format("expected one [[actuator]] per input channel ({}), got {}", nu,
                                              act_tables.size()));
    }
    if (nu > 16) act_tables.back().fail_here(fmt::format("expected at most 16 actuators, got {}", nu));
    if (!sc->model.plant.modes.empty()) {
      act_tables.front().fail_here("expected no [[actuator]] with a jump_linear plant (one mode source per scenario)");
    }
    std::set<std::string> names;
    for (std::size_t i = 0; i < act_tables.size(); ++i) {
      const Table& t = act_tables[i];
      est::ActuatorModel am;
      am.spec = models::read_actuator(t, link_names, static_cast<int>(i));
      if (!names.insert(am.spec.name).second) {
        t.fail("name", fmt::format("expected a unique actuator name, got \"{}\" twice", am.spec.name));
      }
      if (am.spec.link >= 0) {
        am.link = sc->links[static_cast<std::size_t>(am.spec.link)].link.get();
        const auto* trace = dynamic_cast<const models::TraceLink*>(am.link);
        if (trace != nullptr && static_cast<std::int64_t>(trace->size()) < sc->run.periods) {
          t.fail("link", fmt::format("expected a trace of at least {} packets (one per period), got {}",
                                     sc->run.periods, trace->size()));
        }
      }
      t.finish();
      sc->model.actuators.push_back(std::move(am));
    }
  }
  if (sc->mobility) sc->mobility->prepare();

  // Input.
  const std::optional<Table> input = root.opt_table("input");
  if (input) {
    const auto& ik = input_registry().lookup(*input, "kind", "none");
    sc->input = ik.factory(*input, sc->model.plant);
    const auto delay = input->integer_or("actuation_delay", 0);
    if (delay < 0 || delay > 1000) {
      input->fail("actuation_delay", fmt::format("expected an integer in 0..1000 (periods), got {}", delay));
    }
    sc->input.actuation_delay = static_cast<int>(delay);
    if (sc->input.controller) {
      std::vector<models::SensorSpec> specs;
      for (const auto& s : sc->model.sensors) specs.push_back(s.spec);
      sc->input.controller->bind(*input, specs);
    }
    input->finish();
  }

  // Estimators.
  const auto est_tables = root.tables("estimator");
  if (est_tables.empty())
    root.fail("estimator", "expected at least one [[estimator]] table, got none");
  std::set<std::string> est_names;
  for (std::size_t i = 0; i < est_tables.size(); ++i) {
    const Table& t = est_tables[i];
    EstimatorEntry e;
    const auto& k = estimator_registry().lookup(t, "kind", "");
    e.kind = k.name;
    e.name = t.string_or("name", fmt::format("{} {}", e.kind, i));
    if (!est_names.insert(e.name).second) {
      t.fail("name", fmt::format("expected a unique estimator name, got \"{}\" twice", e.name));
    }
    check_estimator_resources(t, *doc.get("estimator")->as_array()->get(i)->as_table(), k.name, sc->model,
                              state_size_driver);  // sim/limits.h
    try {
      e.design = k.factory(t, sc->model);
    } catch (const lmi::ResourceLimitError& err) {
      t.fail("kind", fmt::format("the {} design: {} (--max-memory / --max-work raise the limits); its size is "
                                 "driven by {}",
                                 k.name, err.what(), state_size_driver));
    } catch (const lmi::Error& err) {
      // The model's numbers make the LMIs meaningless (e.g. an overflow to inf): bad input.
      t.fail("kind", fmt::format("the {} design cannot be posed for this model: {} (check the magnitudes of the "
                                 "plant, sensor and noise values)",
                                 k.name, err.what()));
    }
    t.finish();
    sc->estimators.push_back(std::move(e));
  }

  // The state-feedback source.
  const bool reads_estimate =
      (sc->input.kind == models::InputSpec::Kind::kStateFeedback && sc->input.source != "plant") ||
      (sc->input.kind == models::InputSpec::Kind::kController && !sc->input.source.empty());
  if (reads_estimate) {
    for (std::size_t i = 0; i < sc->estimators.size(); ++i) {
      if (sc->estimators[i].name == sc->input.source) sc->input.source_index = static_cast<int>(i);
    }
    if (sc->input.source_index < 0) {
      std::vector<std::string> names{"plant"};
      for (const auto& e : sc->estimators) names.push_back(e.name);
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + fmt::format("\"{}\"", n);
      const std::string hint = did_you_mean(sc->input.source, names);
      input->fail(sc->input.kind == models::InputSpec::Kind::kController ? "feedback" : "source",
                  fmt::format("expected \"plant\" or an estimator name ({}), got \"{}\"{}", list,
                              sc->input.source,
                              hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
  }

  // Re-centring: an open-loop unstable plant is simulated in coordinates that the known
  // input keeps bounded; the estimation error is unchanged (scenarios/README.md).
  const bool unstable = sc->model.plant.spectral_radius() >= 1.0;
  const bool feedback = sc->input.kind == models::InputSpec::Kind::kStateFeedback ||
                        sc->input.kind == models::InputSpec::Kind::kController;
  // Send-on-delta sensors decide on the output itself: re-centring would change what they send.
  bool send_on_delta = false;
  for (const auto& sm : sc->model.sensors) {
    send_on_delta = send_on_delta || sm.spec.policy == models::SensorSpec::Policy::kSendOnDelta;
  }
  if (sc->plant_vehicle >= 0) {
    // The true state comes from SUMO: nothing to re-centre.
    if (sc->run.recentre == "always") {
      root.table("run").fail("recentre", "expected \"auto\" or \"never\" with a SUMO vehicle as the plant");
    }
  } else if (sc->run.recentre == "always") {
    sc->recentre = true;
    if (send_on_delta) {
      root.table("run").fail("recentre", "expected \"auto\" or \"never\" with send-on-delta sensors (they would "
                                         "decide on re-centred outputs), got \"always\"");
    }
  } else if (sc->run.recentre == "auto") {
    sc->recentre = unstable && !feedback && !send_on_delta;
  }
  if (sc->recentre && feedback && sc->input.source_index >= 0) {
    root.table("run").fail(
        "recentre", fmt::format("expected \"auto\" or \"never\" with feedback on an estimate "
                                "(input.source = \"{}\"), got \"always\" (the controller "
                                "would see re-centred estimates)",
                                sc->input.source));
  }
  if (sc->recentre && sc->input.kind == models::InputSpec::Kind::kController) {
    root.table("run").fail("recentre", "expected \"auto\" or \"never\" with a controller input (it would see "
                                       "re-centred outputs), got \"always\"");
  }
  {
    const auto rt = root.opt_table("run");
    check_campaign_resources(file, rt ? rt->line_of("runs") : 1, sc->run.runs, 1, sc->estimators.size(),
                             sc->model.plant.n(), sc->model.sensors.size());  // sim/limits.h
  }
  sc->paired = read_paired(root, doc, *sc);
  root.finish();
  return sc;
}

namespace {

// The scenario text parsed, with --set and the [run] options applied. Parsed afresh for every
// sweep case: toml++ copies drop the source lines that error messages need.
toml::table parse_document(const std::string& text, const std::string& file,
                           const std::vector<std::string>& sets, const RunOverrides& overrides) {
  toml::table doc;
  try {
    doc = toml::parse(text, std::string_view(file));
  } catch (const toml::parse_error& e) {
    throw ScenarioError(format_error(file, static_cast<int>(e.source().begin.line), "",
                                     fmt::format("TOML syntax error: {}", e.description())));
  }
  for (const auto& s : sets) apply_set(doc, s, "--set");
  auto override_run = [&](const char* key, std::int64_t value, const char* option) {
    toml::table parsed = parse_value(key, std::to_string(value), option);
    set_path(doc, fmt::format("run.{}", key), std::move(*parsed.get("value")), option, 0);
  };
  if (overrides.runs > 0) override_run("runs", overrides.runs, "--runs");
  if (overrides.periods > 0) override_run("periods", overrides.periods, "--periods");
  if (overrides.seed) override_run("seed", static_cast<std::int64_t>(*overrides.seed), "--seed");
  return doc;
}

// A swept value as written in summary.csv: strings bare, numbers in their shortest exact
// form ("0.3", not toml++'s "0.29999999999999999"), arrays as "[0.9, 0.05]".
std::string sweep_label(const toml::node& v) {
  if (auto s = v.value_exact<std::string>()) return *s;
  return compact_toml(v);
}

// The value at a key path ("estimator[0].history"), or nullptr.
const toml::node* find_path(const toml::table& doc, const std::string& path) {
  std::vector<PathSegment> segs;
  try {
    segs = parse_path(path, "", 0);
  } catch (const ScenarioError&) {
    return nullptr;
  }
  const toml::table* cur = &doc;
  for (std::size_t s = 0; s < segs.size(); ++s) {
    const toml::node* n = cur->get(segs[s].key);
    if (n == nullptr) return nullptr;
    if (segs[s].index) {
      const toml::array* arr = n->as_array();
      if (arr == nullptr || *segs[s].index >= arr->size()) return nullptr;
      n = arr->get(*segs[s].index);
    }
    if (s + 1 == segs.size()) return n;
    cur = n->as_table();
    if (cur == nullptr) return nullptr;
  }
  return nullptr;
}

// The `values` array of [[sweep]] number `axis`.
toml::array& sweep_values(toml::table& doc, std::size_t axis) {
  return *doc.get("sweep")->as_array()->get(axis)->as_table()->get("values")->as_array();
}

}  // namespace

LoadedScenario load_cases(const std::string& file, const std::vector<std::string>& sets,
                          const RunOverrides& overrides, std::optional<std::size_t> only_case) {
  {
    // A regular file of bounded size: a FIFO or device would block or never end.
    std::error_code ec;
    const auto st = std::filesystem::status(file, ec);
    if (!ec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
      throw ScenarioError(format_error(file, 0, "", "expected a regular scenario file (not a FIFO, device or folder)"));
    }
    const auto size = std::filesystem::file_size(file, ec);
    if (!ec && size > kMaxScenarioBytes) {
      throw ScenarioError(format_error(file, 0, "", fmt::format("the scenario file holds {} bytes; at most {} are read",
                                                                size, kMaxScenarioBytes)));
    }
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ScenarioError(format_error(file, 0, "", "cannot open the scenario file"));
  std::stringstream ss;
  ss << in.rdbuf();
  return load_cases_text(file, ss.str(), sets, overrides, only_case);
}

LoadedScenario load_cases_text(const std::string& file, const std::string& text, const std::vector<std::string>& sets,
                               const RunOverrides& overrides, std::optional<std::size_t> only_case) {
  LoadedScenario out;
  out.file = file;
  out.text = text;
  out.overrides = sets;
  std::string hashed = out.text;
  for (const auto& s : sets) hashed += "\n--set " + s;
  if (overrides.runs > 0) hashed += "\n--runs " + std::to_string(overrides.runs);
  if (overrides.periods > 0) hashed += "\n--periods " + std::to_string(overrides.periods);
  if (overrides.seed) hashed += "\n--seed " + std::to_string(*overrides.seed);
  out.hash = fnv1a_hex(hashed);

  toml::table doc = parse_document(out.text, file, sets, overrides);

  // Sweeps: cartesian product, the first axis varying slowest.
  std::vector<std::size_t> axis_sizes;
  int last_sweep_line = 1;
  {
    Table root(doc, "", file);
    const auto sweep_tables = root.tables("sweep");
    for (std::size_t a = 0; a < sweep_tables.size(); ++a) {
      const Table& t = sweep_tables[a];
      SweepAxis axis;
      axis.key = t.string("key");
      const int key_line = t.line_of("key");
      if (axis.key == "sweep" || axis.key.starts_with("sweep.") || axis.key.starts_with("sweep[")) {
        t.fail("key",
               fmt::format("expected the key path of a scenario value, got \"{}\" (a sweep cannot "
                           "change the sweeps)",
                           axis.key));
      }
      t.allow("values");
      const toml::node* vals = doc.get("sweep")->as_array()->get(a)->as_table()->get("values");
      if (vals == nullptr || !vals->is_array() || vals->as_array()->empty()) {
        t.fail("values", fmt::format("expected a non-empty array of values, got {}",
                                     vals == nullptr ? std::string("nothing (the key is required)")
                                                     : describe(*vals)));
      }
      for (const toml::node& v : *vals->as_array()) axis.labels.push_back(sweep_label(v));
      t.finish();
      for (const auto& prev : out.sweeps) {
        if (prev.key == axis.key)
          t.fail("key", fmt::format("expected each swept key once, got \"{}\" twice", axis.key));
      }
      // Validate the path now, on a scratch copy.
      toml::table scratch = doc;
      set_path(scratch, axis.key, *vals->as_array()->get(0), file, key_line);
      axis_sizes.push_back(vals->as_array()->size());
      last_sweep_line = std::max(1, t.line_of("values"));
      out.sweeps.push_back(std::move(axis));
    }
  }
  std::size_t total = 1;
  for (const std::size_t n : axis_sizes) {
    total *= n;
    if (total > 100000) {
      throw ScenarioError(format_error(file, last_sweep_line, "sweep",
                                       "expected at most 100000 cases (the product of the [[sweep]] value counts), "
                                       "got more"));
    }
  }
  check_sweep_resources(file, last_sweep_line, total, out.text.size());  // sim/limits.h
  const std::string dir = std::filesystem::path(file).parent_path().string();
  // The base values of swept keys are validated too (as one whole scenario) when one of them is
  // not among its swept values: a value in the file must be valid even when a sweep replaces it.
  if (!out.sweeps.empty() && !only_case) {
    std::vector<std::size_t> missing;  // axes without a base value: they take their first value
    bool unchecked = false;
    for (std::size_t a = 0; a < out.sweeps.size(); ++a) {
      const toml::node* base = find_path(doc, out.sweeps[a].key);
      if (base == nullptr) {
        missing.push_back(a);
        continue;
      }
      const auto& labels = out.sweeps[a].labels;
      unchecked = unchecked || std::find(labels.begin(), labels.end(), sweep_label(*base)) == labels.end();
    }
    if (unchecked) {
      toml::table base_doc = parse_document(out.text, file, sets, overrides);
      for (const std::size_t a : missing) {
        toml::node& value = *sweep_values(base_doc, a).get(0);
        set_path(base_doc, out.sweeps[a].key, std::move(value), file, 0);
      }
      try {
        (void)build_scenario(base_doc, file, dir);
      } catch (const ScenarioError& e) {
        throw ScenarioError(fmt::format("{} (in the base scenario: the values written outside [[sweep]] must be "
                                        "valid too, even where a sweep replaces them)",
                                        e.what()));
      }
    }
  }
  if (only_case && *only_case >= total) {
    throw ScenarioError(format_error(file, 0, "sweep",
                                     fmt::format("expected a case index below {}, got {}", total, *only_case)));
  }
  for (std::size_t c = 0; c < total; ++c) {
    if (only_case && c != *only_case) continue;
    toml::table case_doc =
        c == 0 ? std::move(doc) : parse_document(out.text, file, sets, overrides);
    Case cs;
    std::size_t rem = c;
    std::vector<std::size_t> idx(axis_sizes.size());
    for (std::size_t a = axis_sizes.size(); a-- > 0;) {
      idx[a] = rem % axis_sizes[a];
      rem /= axis_sizes[a];
    }
    for (std::size_t a = 0; a < axis_sizes.size(); ++a) {
      // Moved, not copied: an error at the swept value then points at its line in `values`.
      toml::node& value = *sweep_values(case_doc, a).get(idx[a]);
      set_path(case_doc, out.sweeps[a].key, std::move(value), file, 0);
      cs.labels.push_back(out.sweeps[a].labels[idx[a]]);
    }
    try {
      cs.scenario = build_scenario(case_doc, file, dir);
    } catch (const ScenarioError& e) {
      if (cs.labels.empty()) throw;
      std::string where;
      for (std::size_t a = 0; a < cs.labels.size(); ++a) {
        where += fmt::format("{}{} = {}", a ? ", " : "", out.sweeps[a].key, cs.labels[a]);
      }
      throw ScenarioError(fmt::format("{} (in the sweep case {})", e.what(), where));
    }
    out.cases.push_back(std::move(cs));
  }
  return out;
}

}  // namespace ncosim::sim

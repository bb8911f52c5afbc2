// sumo/traffic.cc — the [sumo] table as the scenario's mobility source: its inputs, the
// recording cache (one recording per realisation, shared by every case of a scenario), replay.
#include "sumo/traffic.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>

#include "config/input_files.h"
#include "kernel/time.h"
#include "sumo/channel.h"
#include "sumo/process.h"
#include "sumo/sumo.h"

namespace ncosim::sumo {

namespace fs = std::filesystem;

namespace {

// Input files named by a .sumocfg: net-file, route-files, additional-files (comma lists).
std::vector<std::string> config_inputs(const fs::path& cfg) {
  const std::string text = read_file(cfg);
  std::vector<std::string> out;
  static const std::regex re(
      R"re(<\s*(net-file|route-files|additional-files)\s+value\s*=\s*"([^"]*)")re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator();
       ++it) {
    std::stringstream list((*it)[2].str());
    for (std::string f; std::getline(list, f, ',');) {
      f.erase(0, f.find_first_not_of(' '));
      f.erase(f.find_last_not_of(' ') + 1);
      if (f.empty()) continue;
      fs::path p(f);
      if (p.is_relative()) p = cfg.parent_path() / p;
      out.push_back(p.string());
    }
  }
  return out;
}

class ReplayRun final : public models::MobilityRun {
 public:
  explicit ReplayRun(const Recording& r) : r_(r), step_ns_(r.step_ms * 1'000'000) {}
  void advance(kernel::SimTime t) override { frame_ = std::min(t / step_ns_, r_.frames - 1); }
  const models::VehicleState& vehicle(int index) const override { return r_.at(frame_, index); }

 private:
  const Recording& r_;
  std::int64_t step_ns_;
  std::int64_t frame_ = 0;
};

}  // namespace

std::string default_cache_dir() {
  if (const char* e = std::getenv("NCOSIM_SUMO_CACHE"); e != nullptr && *e != '\0') return e;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && *x != '\0') {
    return (fs::path(x) / "ncosim" / "sumo").string();
  }
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != '\0') {
    return (fs::path(h) / ".cache" / "ncosim" / "sumo").string();
  }
  return (fs::temp_directory_path() / "ncosim-sumo-cache").string();
}

Mobility::Mobility(const config::Table& t, const config::RunSettings& run, const std::string& dir)
    : file_(t.file()) {
  auto resolve = [&](const std::string& f) {
    fs::path p(f);
    if (p.is_relative() && !dir.empty()) p = fs::path(dir) / p;
    return p.string();
  };
  auto existing = [&](std::string_view key, const std::string& f) {
    const std::string p = resolve(f);
    if (!fs::is_regular_file(p))
      t.fail(key, fmt::format("expected a readable SUMO file, got '{}' (not found)", p));
    return p;
  };
  if (t.has("config")) {
    config_key_ = "config";
    const std::string cfg = existing("config", t.string("config"));
    inputs_.args = {"-c", cfg};
    inputs_.files.push_back(cfg);
    for (const auto& f : config_inputs(cfg)) {
      if (!fs::is_regular_file(f)) {
        t.fail("config", fmt::format("the SUMO configuration names '{}', which does not exist", f));
      }
      inputs_.files.push_back(f);
    }
  } else {
    if (!t.has("net")) t.fail_here("expected `config` (a .sumocfg) or `net` and `routes`");
    config_key_ = "net";
    const std::string net = existing("net", t.string("net"));
    const std::string routes = existing("routes", t.string("routes"));
    inputs_.args = {"-n", net, "-r", routes};
    inputs_.files = {net, routes};
    if (t.has("additional")) {
      const std::string add = existing("additional", t.string("additional"));
      inputs_.args.insert(inputs_.args.end(), {"-a", add});
      inputs_.files.push_back(add);
    }
  }
  for (const auto& f : inputs_.files)
    config::note_input_file(f);  // part of the campaign's identity
  line_ = t.line_of(config_key_);
  const double step = t.number_or("step", 0.1);
  const double ms = step * 1000.0;
  if (!(step > 0.0 && step <= 3600.0) || std::abs(ms - std::round(ms)) > 1e-6 * std::max(1.0, ms)) {
    t.fail("step", fmt::format("expected a whole number of milliseconds in (0, 3600] s (SUMO time "
                               "is integer ms), got {} s",
                               step));
  }
  inputs_.step_ms = std::llround(ms);
  const auto seeds = t.integer_or("seeds", 1);
  if (seeds < 1 || seeds > 100000)
    t.fail("seeds", fmt::format("expected an integer in 1..100000, got {}", seeds));
  seeds_ = static_cast<int>(seeds);
  const auto first = t.integer_or("seed", 1);
  if (first < 0 || first + seeds > 2147483647) {
    t.fail("seed", fmt::format("expected a SUMO seed in 0..2^31-1-seeds, got {}", first));
  }
  first_seed_ = static_cast<std::uint64_t>(first);
  live_ = t.choice_or("mode", "replay", {"replay", "live"}) == "live";
  cache_dir_ = t.has("cache") ? resolve(t.string("cache")) : default_cache_dir();
  horizon_ns_ = (run.periods - 1) * kernel::seconds_to_time(run.period);
  frames_ = horizon_ns_ / (inputs_.step_ms * 1'000'000) + 1;
  t.finish();
}

int Mobility::vehicle(const config::Table& t, std::string_view key) {
  const std::string id = t.string(key);
  if (id.empty()) t.fail(key, "expected a SUMO vehicle id, got an empty string");
  if (id.find_first_of(" \t\n\r|\\'\";,<>&") != std::string::npos) {  // as SUMO's own id check
    t.fail(key,
           fmt::format("expected a SUMO vehicle id (no spaces or any of |\\'\";,<>&), got \"{}\"",
                       id));
  }
  const auto it = std::find(vehicles_.begin(), vehicles_.end(), id);
  if (it != vehicles_.end()) return static_cast<int>(it - vehicles_.begin());
  vehicles_.push_back(id);
  origins_.push_back(Origin{t.file(), t.key_path(key), t.line_of(key)});
  return static_cast<int>(vehicles_.size()) - 1;
}

// Every vehicle the traffic's input files define by id: the `id` of each <vehicle> and <trip>
// element, in file order. A <flow> makes its vehicles' ids during the simulation: they cannot be
// named before it (`flow` is set to the first file holding one).
namespace {
std::vector<std::string> defined_vehicles(const std::vector<std::string>& files,
                                          std::string& flow) {
  static const std::regex element(R"re(<\s*(vehicle|trip|flow)\b([^>]*)>)re");
  static const std::regex id(R"re(\bid\s*=\s*"([^"]*)")re");
  std::vector<std::string> out;
  for (const auto& f : files) {
    const std::string text = read_file(f);
    for (auto it = std::sregex_iterator(text.begin(), text.end(), element);
         it != std::sregex_iterator(); ++it) {
      if ((*it)[1] == "flow") {
        if (flow.empty()) flow = f;
        continue;
      }
      const std::string attributes = (*it)[2].str();
      std::smatch m;
      if (std::regex_search(attributes, m, id) &&
          std::find(out.begin(), out.end(), m[1].str()) == out.end())
        out.push_back(m[1].str());
    }
  }
  return out;
}
}  // namespace

std::vector<int> Mobility::every_vehicle(const config::Table& t, std::string_view key) {
  std::string flow;
  const std::vector<std::string> ids = defined_vehicles(inputs_.files, flow);
  if (!flow.empty()) {
    t.fail(key,
           fmt::format("expected a traffic whose vehicles are defined one by one (<vehicle> or "
                       "<trip>): '{}' has <flow> elements, whose vehicles are named during "
                       "the simulation (expand them with SUMO's duarouter)",
                       flow));
  }
  if (ids.empty()) t.fail(key, "expected a traffic with vehicles: its input files define none");
  std::vector<int> out;
  for (const auto& id : ids) {
    const auto it = std::find(vehicles_.begin(), vehicles_.end(), id);
    if (it != vehicles_.end()) {
      out.push_back(static_cast<int>(it - vehicles_.begin()));
      continue;
    }
    vehicles_.push_back(id);
    origins_.push_back(Origin{t.file(), t.key_path(key), t.line_of(key), true});
    out.push_back(static_cast<int>(vehicles_.size()) - 1);
  }
  return out;
}

std::string Mobility::traffic_key() const {
  // v3: keyed by the traffic only; a recording holds every vehicle announced for it.
  std::string text = "ncosim-sumo-recording-v3\n";
  for (const auto& f : inputs_.files) {
    const std::string content = read_file(f);
    text += fmt::format("file {} {:016x}\n", content.size(), name_hash(content));
  }
  text += fmt::format("step_ms {}\nframes {}\n", inputs_.step_ms, frames_);
  return fmt::format("{:016x}", name_hash(text));
}

std::string Mobility::key_for(std::uint64_t seed) const {
  return fmt::format("{:016x}", name_hash(fmt::format("{}\nseed {}\n", traffic_key(), seed)));
}

namespace {

// Vehicles announced per traffic key (announce_vehicles), for the process's lifetime.
std::map<std::string, std::vector<std::string>>& announced() {
  static std::map<std::string, std::vector<std::string>> m;
  return m;
}
std::mutex& announced_mutex() {
  static std::mutex m;
  return m;
}

void add_unique(std::vector<std::string>& to, const std::string& v) {
  if (v.empty() || v.find_first_of(" \t\n\r|\\'\";,<>&") != std::string::npos)
    return;  // Mobility::vehicle's check
  if (std::find(to.begin(), to.end(), v) == to.end()) to.push_back(v);
}

// The recording restricted to `vehicles` (all in r.vehicles), in that order.
Recording project(const Recording& r, const std::vector<std::string>& vehicles) {
  if (r.vehicles == vehicles) return r;
  Recording p;
  p.step_ms = r.step_ms;
  p.frames = r.frames;
  p.vehicles = vehicles;
  std::vector<int> index;
  for (const auto& v : vehicles) {
    index.push_back(
        static_cast<int>(std::find(r.vehicles.begin(), r.vehicles.end(), v) - r.vehicles.begin()));
  }
  p.states.reserve(static_cast<std::size_t>(r.frames) * vehicles.size());
  for (std::int64_t f = 0; f < r.frames; ++f) {
    for (const int i : index) p.states.push_back(r.at(f, i));
  }
  return p;
}

bool holds(const Recording& r, const std::vector<std::string>& vehicles) {
  for (const auto& v : vehicles) {
    if (std::find(r.vehicles.begin(), r.vehicles.end(), v) == r.vehicles.end()) return false;
  }
  return true;
}

}  // namespace

namespace {

struct DeclaredKeys {
  VehicleTable table;
  std::string kind;
  std::vector<std::string> keys;
};
std::vector<DeclaredKeys>& declared_keys() {
  static std::vector<DeclaredKeys> d;
  return d;
}
std::mutex& declared_mutex() {
  static std::mutex m;
  return m;
}

// The values of the vehicle keys that the kind of table `t` declares (none for an absent kind or
// one that declares none).
void add_declared_vehicles(VehicleTable table, const toml::table& t, std::vector<std::string>& to) {
  const auto kind = t["kind"].value<std::string>();
  if (!kind) return;
  const std::lock_guard<std::mutex> lock(declared_mutex());
  for (const auto& d : declared_keys()) {
    if (d.table != table || (d.kind != *kind && !d.kind.empty())) continue;
    for (const auto& key : d.keys) add_unique(to, t[key].value_or(std::string()));
  }
}

}  // namespace

void declare_vehicle_keys(VehicleTable table, std::string kind, std::vector<std::string> keys) {
  const std::lock_guard<std::mutex> lock(declared_mutex());
  declared_keys().push_back(DeclaredKeys{table, std::move(kind), std::move(keys)});
}

void announce_vehicles(const toml::table& doc, const std::string& file, const std::string& dir) {
  const toml::table* sumo = doc["sumo"].as_table();
  if (sumo == nullptr) return;
  config::RunSettings run;
  if (const auto* r = doc["run"].as_table()) {
    run.periods = (*r)["periods"].value_or(run.periods);
    run.period = (*r)["period"].value_or(run.period);
  }
  std::string key;
  try {
    const config::Table t(*sumo, "sumo", file);
    key = Mobility(t, run, dir).traffic_key();
  } catch (const config::ScenarioError&) {
    return;  // a bad [sumo] table: the case's own build reports it
  }
  std::vector<std::string> v;
  if (const auto* plant = doc["plant"].as_table())
    add_declared_vehicles(VehicleTable::kPlant, *plant, v);
  for (const auto& [section, table] :
       {std::pair{"link", VehicleTable::kLink}, std::pair{"network", VehicleTable::kNetwork}}) {
    if (const auto* array = doc[section].as_array()) {
      for (const auto& l : *array) {
        if (const auto* lt = l.as_table()) add_declared_vehicles(table, *lt, v);
      }
    }
  }
  const std::lock_guard<std::mutex> lock(announced_mutex());
  auto& list = announced()[key];
  for (const auto& x : v) add_unique(list, x);
}

void Mobility::prepare() {
  std::error_code ec;
  fs::create_directories(cache_dir_, ec);
  if (!fs::is_directory(cache_dir_))
    fail(fmt::format("cannot create the recording cache '{}'", cache_dir_));
  std::vector<RecordingJob> jobs, missing;
  // What to record: this case's vehicles, then those announced for the same traffic by the other
  // cases, then those of an existing recording that lacks some of ours (it is replaced).
  std::vector<std::string> record_vehicles = vehicles_;
  {
    const std::lock_guard<std::mutex> lock(announced_mutex());
    const auto it = announced().find(traffic_key());
    if (it != announced().end()) {
      for (const auto& v : it->second) add_unique(record_vehicles, v);
    }
  }
  for (int s = 0; s < seeds_; ++s) {
    const std::uint64_t seed = first_seed_ + static_cast<std::uint64_t>(s);
    RecordingJob j{seed, (fs::path(cache_dir_) / (key_for(seed) + ".traj")).string()};
    jobs.push_back(j);
    if (!fs::is_regular_file(j.path)) {
      missing.push_back(j);
      continue;
    }
    try {
      const Recording r = read_recording(j.path);
      if (!holds(r, vehicles_)) {
        for (const auto& v : r.vehicles) add_unique(record_vehicles, v);
        missing.push_back(j);
      }
    } catch (const std::exception&) {
      missing.push_back(j);  // unreadable: recorded again
    }
  }
  recorded_ = static_cast<int>(missing.size());
  reused_ = seeds_ - recorded_;
  if (!missing.empty()) {
    try {
      record_all(inputs_, frames_, record_vehicles, missing);
    } catch (const std::exception& e) {
      fail(e.what());
    }
  }
  recordings_.clear();
  for (const RecordingJob& j : jobs) load(j);
  std::cerr << fmt::format("sumo: {} realisation(s) recorded, {} reused (cache {})\n", recorded_,
                           reused_, cache_dir_);
}

void Mobility::fail(const std::string& why) const {
  throw config::ScenarioError(
      config::format_error(file_, line_, fmt::format("sumo.{}", config_key_), why));
}

void Mobility::load(const RecordingJob& j) {
  std::error_code ec;
  try {
    const Recording all = read_recording(j.path);
    if (!holds(all, vehicles_) || all.frames != frames_)
      fail(fmt::format("recording '{}' does not match; remove it", j.path));
    recordings_.push_back(project(all, vehicles_));
  } catch (const config::ScenarioError&) {
    throw;
  } catch (const std::exception& e) {
    fs::remove(j.path, ec);  // a bad cache entry is re-recorded next time
    fail(fmt::format("recording '{}' unreadable ({}); removed, run again", j.path, e.what()));
  }
  const Recording& r = recordings_.back();
  if (r.vehicles != vehicles_ || r.frames != frames_)
    fail(fmt::format("recording '{}' does not match; remove it", j.path));
  for (std::size_t v = 0; v < vehicles_.size(); ++v) {
    bool seen = false;
    for (std::int64_t f = 0; f < r.frames && !seen; ++f)
      seen = r.at(f, static_cast<int>(v)).present;
    if (!seen && !origins_[v].may_be_absent) {
      const Origin& o = origins_[v];
      throw config::ScenarioError(config::format_error(
          o.file, o.line, o.path,
          fmt::format("vehicle \"{}\" never drives in SUMO (seed {}) during the {:g} s horizon: "
                      "unknown id, or it "
                      "departs later",
                      vehicles_[v], j.seed, kernel::time_to_seconds(horizon_ns_))));
    }
  }
}

std::unique_ptr<models::MobilityRun> Mobility::start(std::uint64_t run) const {
  const auto s = static_cast<std::size_t>(run % static_cast<std::uint64_t>(seeds_));
  if (live_) return start_live(inputs_, first_seed_ + s, vehicles_);
  return std::make_unique<ReplayRun>(recordings_[s]);
}

}  // namespace ncosim::sumo

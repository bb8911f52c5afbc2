// sumo/mobility.cc — the [sumo] table, the recording cache, worker processes, replay.
#include "sumo/mobility.h"

#include <dlfcn.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <regex>
#include <sstream>
#include <thread>

#include "sim/time.h"
#include "sumo/channel.h"

extern char** environ;

namespace ncosim::sumo {

namespace fs = std::filesystem;

namespace {

std::string g_worker;

constexpr char kMagic[8] = {'N', 'C', 'O', 'S', 'U', 'M', 'O', '1'};

template <class T>
void put(std::ostream& o, const T& v) {
  o.write(reinterpret_cast<const char*>(&v), sizeof v);
}
template <class T>
void get(std::istream& i, T& v) {
  i.read(reinterpret_cast<char*>(&v), sizeof v);
  if (!i) throw std::runtime_error("truncated recording");
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Input files named by a .sumocfg: net-file, route-files, additional-files (comma lists).
std::vector<std::string> config_inputs(const fs::path& cfg) {
  const std::string text = read_file(cfg);
  std::vector<std::string> out;
  static const std::regex re(R"re(<\s*(net-file|route-files|additional-files)\s+value\s*=\s*"([^"]*)")re");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it) {
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

class ReplayRun final : public sim::MobilityRun {
 public:
  explicit ReplayRun(const Recording& r) : r_(r), step_ns_(r.step_ms * 1'000'000) {}
  void advance(sim::SimTime t) override { frame_ = std::min(t / step_ns_, r_.frames - 1); }
  const sim::VehicleState& vehicle(int index) const override { return r_.at(frame_, index); }

 private:
  const Recording& r_;
  std::int64_t step_ns_;
  std::int64_t frame_ = 0;
};

// The libsumo module (sumo/session.cc), opened on first use: $NCOSIM_SUMO_MODULE (only it,
// when set), else the build's module (NCOSIM_SUMO_MODULE_PATH), else libncosim_sumo_session.so beside the executable.
struct SessionApi {
  void (*record)(const SumoInputs*, std::uint64_t, std::int64_t, const std::vector<std::string>*, Recording*);
  sim::MobilityRun* (*start_live)(const SumoInputs*, std::uint64_t, const std::vector<std::string>*);
};

const SessionApi& session_api() {
  static const SessionApi api = [] {
    std::vector<std::string> candidates;
    if (const char* e = std::getenv("NCOSIM_SUMO_MODULE"); e != nullptr && *e != '\0') {
      candidates.emplace_back(e);  // only this one
    } else {
      candidates.emplace_back(NCOSIM_SUMO_MODULE_PATH);
      std::error_code ec;
      const auto self = fs::read_symlink("/proc/self/exe", ec);
      if (!ec) candidates.push_back((self.parent_path() / "libncosim_sumo_session.so").string());
    }
    std::string errors;
    for (const auto& c : candidates) {
      void* h = ::dlopen(c.c_str(), RTLD_NOW | RTLD_LOCAL);
      if (h == nullptr) {
        errors += fmt::format("\n  {}", ::dlerror());
        continue;
      }
      SessionApi a{};
      a.record = reinterpret_cast<decltype(a.record)>(::dlsym(h, "ncosim_sumo_record"));
      a.start_live = reinterpret_cast<decltype(a.start_live)>(::dlsym(h, "ncosim_sumo_start_live"));
      if (a.record != nullptr && a.start_live != nullptr) return a;
      errors += fmt::format("\n  {}: entry points missing", c);
    }
    throw std::runtime_error("cannot load the libsumo module (set NCOSIM_SUMO_MODULE):" + errors);
  }();
  return api;
}

}  // namespace

Recording record(const SumoInputs& in, std::uint64_t seed, std::int64_t frames,
                 const std::vector<std::string>& vehicles) {
  Recording r;
  session_api().record(&in, seed, frames, &vehicles, &r);
  return r;
}

std::unique_ptr<sim::MobilityRun> start_live(const SumoInputs& in, std::uint64_t seed,
                                             const std::vector<std::string>& vehicles) {
  return std::unique_ptr<sim::MobilityRun>(session_api().start_live(&in, seed, &vehicles));
}

void set_worker_executable(const std::string& path) { g_worker = path; }

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

void write_recording(const std::string& path, const Recording& r) {
  const std::string tmp = fmt::format("{}.tmp.{}", path, ::getpid());
  {
    std::ofstream o(tmp, std::ios::binary | std::ios::trunc);
    if (!o) throw std::runtime_error(fmt::format("cannot write '{}'", tmp));
    o.write(kMagic, sizeof kMagic);
    put(o, r.step_ms);
    put(o, r.frames);
    put(o, static_cast<std::uint32_t>(r.vehicles.size()));
    for (const auto& v : r.vehicles) {
      put(o, static_cast<std::uint32_t>(v.size()));
      o.write(v.data(), static_cast<std::streamsize>(v.size()));
    }
    for (const auto& s : r.states) {
      put(o, static_cast<std::uint8_t>(s.present));
      for (double x : {s.x, s.y, s.pos, s.speed, s.accel}) put(o, x);
    }
    if (!o) throw std::runtime_error(fmt::format("cannot write '{}'", tmp));
  }
  fs::rename(tmp, path);
}

Recording read_recording(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("cannot open '{}'", path));
  char magic[8];
  in.read(magic, sizeof magic);
  if (!in || std::memcmp(magic, kMagic, sizeof magic) != 0) throw std::runtime_error("not an ncosim SUMO recording");
  Recording r;
  std::uint32_t n = 0;
  get(in, r.step_ms);
  get(in, r.frames);
  get(in, n);
  if (r.step_ms <= 0 || r.frames <= 0 || n > 100000) throw std::runtime_error("corrupt recording header");
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint32_t len = 0;
    get(in, len);
    if (len > 4096) throw std::runtime_error("corrupt recording header");
    std::string name(len, '\0');
    in.read(name.data(), len);
    r.vehicles.push_back(name);
  }
  r.states.resize(static_cast<std::size_t>(r.frames) * n);
  for (auto& s : r.states) {
    std::uint8_t present = 0;
    get(in, present);
    s.present = present != 0;
    for (double* x : {&s.x, &s.y, &s.pos, &s.speed, &s.accel}) get(in, *x);
  }
  return r;
}

Mobility::Mobility(const sim::Table& t, const sim::RunSettings& run, const std::string& dir) : file_(t.file()) {
  auto resolve = [&](const std::string& f) {
    fs::path p(f);
    if (p.is_relative() && !dir.empty()) p = fs::path(dir) / p;
    return p.string();
  };
  auto existing = [&](std::string_view key, const std::string& f) {
    const std::string p = resolve(f);
    if (!fs::is_regular_file(p)) t.fail(key, fmt::format("expected a readable SUMO file, got '{}' (not found)", p));
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
  line_ = t.line_of(config_key_);
  const double step = t.number_or("step", 0.1);
  const double ms = step * 1000.0;
  if (!(step > 0.0 && step <= 3600.0) || std::abs(ms - std::round(ms)) > 1e-6 * std::max(1.0, ms)) {
    t.fail("step", fmt::format("expected a whole number of milliseconds in (0, 3600] s (SUMO time is integer ms), got {} s",
                               step));
  }
  inputs_.step_ms = std::llround(ms);
  const auto seeds = t.integer_or("seeds", 1);
  if (seeds < 1 || seeds > 100000) t.fail("seeds", fmt::format("expected an integer in 1..100000, got {}", seeds));
  seeds_ = static_cast<int>(seeds);
  const auto first = t.integer_or("seed", 1);
  if (first < 0 || first + seeds > 2147483647) {
    t.fail("seed", fmt::format("expected a SUMO seed in 0..2^31-1-seeds, got {}", first));
  }
  first_seed_ = static_cast<std::uint64_t>(first);
  live_ = t.choice_or("mode", "replay", {"replay", "live"}) == "live";
  cache_dir_ = t.has("cache") ? resolve(t.string("cache")) : default_cache_dir();
  horizon_ns_ = (run.periods - 1) * sim::seconds_to_time(run.period);
  frames_ = horizon_ns_ / (inputs_.step_ms * 1'000'000) + 1;
  t.finish();
}

int Mobility::vehicle(const sim::Table& t, std::string_view key) {
  const std::string id = t.string(key);
  if (id.empty()) t.fail(key, "expected a SUMO vehicle id, got an empty string");
  const auto it = std::find(vehicles_.begin(), vehicles_.end(), id);
  if (it != vehicles_.end()) return static_cast<int>(it - vehicles_.begin());
  vehicles_.push_back(id);
  origins_.push_back(Origin{t.file(), t.key_path(key), t.line_of(key)});
  return static_cast<int>(vehicles_.size()) - 1;
}

std::string Mobility::key_for(std::uint64_t seed) const {
  std::string text = "ncosim-sumo-recording-v1\n";
  for (const auto& f : inputs_.files) {
    const std::string content = read_file(f);
    text += fmt::format("file {} {:016x}\n", content.size(), name_hash(content));
  }
  text += fmt::format("step_ms {}\nframes {}\nseed {}\n", inputs_.step_ms, frames_, seed);
  for (const auto& v : vehicles_) text += fmt::format("vehicle {}\n", v);
  return fmt::format("{:016x}", name_hash(text));
}

void Mobility::prepare() {
  auto fail = [&](const std::string& why) {
    throw sim::ScenarioError(sim::format_error(file_, line_, fmt::format("sumo.{}", config_key_), why));
  };
  std::error_code ec;
  fs::create_directories(cache_dir_, ec);
  if (!fs::is_directory(cache_dir_)) fail(fmt::format("cannot create the recording cache '{}'", cache_dir_));
  struct Job {
    std::uint64_t seed;
    std::string path;
  };
  std::vector<Job> jobs, missing;
  for (int s = 0; s < seeds_; ++s) {
    const std::uint64_t seed = first_seed_ + static_cast<std::uint64_t>(s);
    Job j{seed, (fs::path(cache_dir_) / (key_for(seed) + ".traj")).string()};
    jobs.push_back(j);
    if (!fs::is_regular_file(j.path)) missing.push_back(j);
  }
  recorded_ = static_cast<int>(missing.size());
  reused_ = seeds_ - recorded_;
  if (!missing.empty() && g_worker.empty()) {
    for (const Job& j : missing) {  // library use: in this process, one after the other
      try {
        write_recording(j.path, record(inputs_, j.seed, frames_, vehicles_));
      } catch (const std::exception& e) {
        fail(fmt::format("SUMO failed (seed {}): {}", j.seed, e.what()));
      }
    }
  } else if (!missing.empty()) {
    // One worker process per realisation, at most one per core at a time.
    const std::size_t width = std::max(1u, std::thread::hardware_concurrency());
    std::string first_error;
    for (std::size_t b = 0; b < missing.size(); b += width) {
      std::vector<std::pair<pid_t, const Job*>> running;
      for (std::size_t i = b; i < std::min(missing.size(), b + width); ++i) {
        const Job& j = missing[i];
        std::vector<std::string> argv{g_worker, "sumo-record", "--seed", std::to_string(j.seed), "--frames",
                                      std::to_string(frames_), "--step-ms", std::to_string(inputs_.step_ms),
                                      "--out", j.path};
        for (const auto& v : vehicles_) argv.insert(argv.end(), {"--vehicle", v});
        argv.emplace_back("--");
        argv.insert(argv.end(), inputs_.args.begin(), inputs_.args.end());
        std::vector<char*> cargv;
        for (auto& a : argv) cargv.push_back(a.data());
        cargv.push_back(nullptr);
        posix_spawn_file_actions_t fa;
        posix_spawn_file_actions_init(&fa);
        posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);  // nothing on our stdout
        const std::string log = j.path + ".log";
        posix_spawn_file_actions_addopen(&fa, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        pid_t pid = 0;
        const int rc = posix_spawn(&pid, g_worker.c_str(), &fa, nullptr, cargv.data(), environ);
        posix_spawn_file_actions_destroy(&fa);
        if (rc != 0) fail(fmt::format("cannot start the SUMO worker '{}': {}", g_worker, std::strerror(rc)));
        running.emplace_back(pid, &j);
      }
      for (auto& [pid, job] : running) {
        int status = 0;
        ::waitpid(pid, &status, 0);
        const std::string log = job->path + ".log";
        if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0) && first_error.empty()) {
          std::string msg = read_file(log);
          while (!msg.empty() && (msg.back() == '\n' || msg.back() == '\r')) msg.pop_back();
          if (msg.empty()) msg = WIFSIGNALED(status) ? fmt::format("killed by signal {}", WTERMSIG(status)) : "no message";
          first_error = fmt::format("SUMO failed (seed {}): {}", job->seed, msg);
        }
        fs::remove(log, ec);
      }
    }
    if (!first_error.empty()) fail(first_error);
  }
  recordings_.clear();
  for (const Job& j : jobs) {
    try {
      recordings_.push_back(read_recording(j.path));
    } catch (const std::exception& e) {
      fs::remove(j.path, ec);  // a bad cache entry is re-recorded next time
      fail(fmt::format("recording '{}' unreadable ({}); removed, run again", j.path, e.what()));
    }
    const Recording& r = recordings_.back();
    if (r.vehicles != vehicles_ || r.frames != frames_) fail(fmt::format("recording '{}' does not match; remove it", j.path));
    for (std::size_t v = 0; v < vehicles_.size(); ++v) {
      bool seen = false;
      for (std::int64_t f = 0; f < r.frames && !seen; ++f) seen = r.at(f, static_cast<int>(v)).present;
      if (!seen) {
        const Origin& o = origins_[v];
        throw sim::ScenarioError(sim::format_error(o.file, o.line, o.path, fmt::format("vehicle \"{}\" never drives in SUMO (seed {}) during the {:g} s horizon: unknown id, or it "
                         "departs later",
                         vehicles_[v], j.seed, sim::time_to_seconds(horizon_ns_))));
      }
    }
  }
  std::cerr << fmt::format("sumo: {} realisation(s) recorded, {} reused (cache {})\n", recorded_, reused_, cache_dir_);
}

std::unique_ptr<sim::MobilityRun> Mobility::start(std::uint64_t run) const {
  const auto s = static_cast<std::size_t>(run % static_cast<std::uint64_t>(seeds_));
  if (live_) return start_live(inputs_, first_seed_ + s, vehicles_);
  return std::make_unique<ReplayRun>(recordings_[s]);
}

int worker_main(const std::vector<std::string>& args) {
  try {
    SumoInputs in;
    std::uint64_t seed = 0;
    std::int64_t frames = 0;
    std::string out;
    std::vector<std::string> vehicles;
    std::size_t i = 0;
    auto value = [&](const std::string& name) {
      if (i + 1 >= args.size()) throw std::runtime_error("missing value after " + name);
      return args[++i];
    };
    for (; i < args.size(); ++i) {
      const std::string& a = args[i];
      if (a == "--") {
        in.args.assign(args.begin() + static_cast<std::ptrdiff_t>(i) + 1, args.end());
        break;
      }
      if (a == "--seed") seed = std::stoull(value(a));
      else if (a == "--frames") frames = std::stoll(value(a));
      else if (a == "--step-ms") in.step_ms = std::stoll(value(a));
      else if (a == "--out") out = value(a);
      else if (a == "--vehicle") vehicles.push_back(value(a));
      else throw std::runtime_error("unknown option " + a);
    }
    if (out.empty() || frames < 1 || in.step_ms < 1) throw std::runtime_error("expected --out, --frames and --step-ms");
    write_recording(out, record(in, seed, frames, vehicles));
    return 0;
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
}

}  // namespace ncosim::sumo

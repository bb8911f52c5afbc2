// sumo/mobility.cc — the [sumo] table, the recording cache, `sumo` recording processes and
// their FCD output, replay, and live runs in worker processes.
#include "sumo/mobility.h"

#include <dlfcn.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <thread>
#include <unordered_map>

#include "config/input_files.h"
#include "kernel/time.h"
#include "sumo/channel.h"
#include "sumo/sumo.h"

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
  void advance(sim::SimTime t) override { frame_ = std::min(t / step_ns_, r_.frames - 1); }
  const models::VehicleState& vehicle(int index) const override { return r_.at(frame_, index); }

 private:
  const Recording& r_;
  std::int64_t step_ns_;
  std::int64_t frame_ = 0;
};

// The libsumo module (sumo/session.cc), opened on first use: $NCOSIM_SUMO_MODULE (only it,
// when set), else the build's module (NCOSIM_SUMO_MODULE_PATH), else libncosim_sumo_session.so
// beside the executable. Only the live worker process (`ncosim sumo-live`) opens it.
struct SessionApi {
  models::MobilityRun* (*start_live)(const SumoInputs*, std::uint64_t,
                                     const std::vector<std::string>*);
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
      a.start_live = reinterpret_cast<decltype(a.start_live)>(::dlsym(h, "ncosim_sumo_start_live"));
      if (a.start_live != nullptr) return a;
      errors += fmt::format("\n  {}: entry points missing", c);
    }
    throw std::runtime_error("cannot load the libsumo module (set NCOSIM_SUMO_MODULE):" + errors);
  }();
  return api;
}

std::string ms_to_seconds(std::int64_t ms) { return fmt::format("{}.{:03}", ms / 1000, ms % 1000); }

int wait_for(pid_t pid) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

std::string exit_text(int status) {
  if (WIFSIGNALED(status)) return fmt::format("killed by signal {}", WTERMSIG(status));
  if (WIFEXITED(status)) return fmt::format("exit status {}", WEXITSTATUS(status));
  return "stopped";
}

// A child process: stdin and stdout /dev/null (nothing from SUMO on our stdout), stderr to
// err_path, and `fd3` (when >= 0) as its file descriptor 3. envp: nullptr for ours.
pid_t spawn(const std::string& exe, std::vector<std::string> argv, char* const* envp,
            const std::string& err_path, int fd3 = -1) {
  std::vector<char*> cargv;
  for (auto& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd3 >= 0) posix_spawn_file_actions_adddup2(&fa, fd3, 3);
  pid_t pid = 0;
  const int rc =
      posix_spawn(&pid, exe.c_str(), &fa, nullptr, cargv.data(), envp != nullptr ? envp : environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0)
    throw std::runtime_error(fmt::format("cannot start '{}': {}", exe, std::strerror(rc)));
  return pid;
}

// SUMO's stderr as one line: "Error: " prefixes and "Quitting (on error)." dropped.
std::string sumo_message(const std::string& log) {
  std::stringstream in(read_file(log));
  std::string out;
  for (std::string line; std::getline(in, line);) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty() || line == "Quitting (on error).") continue;
    if (line.rfind("Error: ", 0) == 0) line.erase(0, 7);
    out += (out.empty() ? "" : "; ") + line;
  }
  return out;
}

// The environment of the `sumo` processes: ours, plus SUMO_HOME=/usr/share/sumo when unset
// (without it SUMO fetches XML schemas and rejects files written by its own tools).
struct SumoEnvironment {
  std::vector<std::string> text;
  std::vector<char*> ptrs;
  SumoEnvironment() {
    bool home = false;
    for (char** e = environ; *e != nullptr; ++e) {
      const std::string_view v(*e);
      if (v == "SUMO_HOME=") continue;
      home = home || v.rfind("SUMO_HOME=", 0) == 0;
      text.emplace_back(v);
    }
    if (!home) text.emplace_back("SUMO_HOME=/usr/share/sumo");
    for (auto& t : text) ptrs.push_back(t.data());
    ptrs.push_back(nullptr);
  }
};

// One recording process: `sumo` writing FCD output for the named vehicles.
struct SumoProcess {
  std::uint64_t seed = 0;
  std::string fcd, log;
  pid_t pid = -1;
};

SumoProcess start_sumo(const std::string& exe, char* const* envp, const SumoInputs& in,
                       std::uint64_t seed, std::int64_t frames,
                       const std::vector<std::string>& vehicles, const std::string& stem) {
  SumoProcess p{seed, stem + ".fcd.xml", stem + ".log", -1};
  std::vector<std::string> argv{exe};
  for (auto& a : sumo_arguments(in, seed)) argv.push_back(std::move(a));
  // frames - 1 steps: SUMO executes the steps at 0, step, ..., end - step.
  argv.insert(argv.end(), {"--end", ms_to_seconds((frames - 1) * in.step_ms)});
  if (!vehicles.empty()) {
    std::string ids;
    for (const auto& v : vehicles) ids += (ids.empty() ? "" : ",") + v;
    argv.insert(argv.end(),
                {"--fcd-output", p.fcd, "--device.fcd.explicit", ids, "--fcd-output.attributes",
                 "x,y,speed,acceleration,odometer", "--precision", "40"});
  }
  try {
    p.pid = spawn(exe, argv, envp, p.log);
  } catch (...) {
    std::error_code ec;
    fs::remove(p.log, ec);  // the child may have opened it before its exec failed
    throw;
  }
  return p;
}

// Waits for a recording process, reads its FCD output, removes its files.
Recording finish_sumo(SumoProcess& p, const SumoInputs& in, std::int64_t frames,
                      const std::vector<std::string>& vehicles) {
  const int status = wait_for(p.pid);
  p.pid = -1;
  std::error_code ec;
  struct Cleanup {
    const SumoProcess& p;
    ~Cleanup() {
      std::error_code e;
      fs::remove(p.fcd, e);
      fs::remove(p.log, e);
    }
  } cleanup{p};
  if (!(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    std::string msg = sumo_message(p.log);
    if (msg.empty()) msg = "sumo " + exit_text(status);
    throw std::runtime_error(msg);
  }
  if (vehicles.empty()) {
    Recording r;
    r.step_ms = in.step_ms;
    r.frames = frames;
    return r;
  }
  return parse_fcd(p.fcd, in.step_ms, frames, vehicles);
}

// The strict reader of SUMO's FCD output (see parse_fcd).
class FcdReader {
 public:
  FcdReader(std::string path) : path_(std::move(path)), s_(read_file(path_)) {}

  Recording read(std::int64_t step_ms, std::int64_t frames,
                 const std::vector<std::string>& vehicles) {
    const std::size_t n = vehicles.size();
    Recording r;
    r.step_ms = step_ms;
    r.frames = frames;
    r.vehicles = vehicles;
    r.states.resize(static_cast<std::size_t>(frames) * n);
    std::unordered_map<std::string_view, std::size_t> index;
    for (std::size_t v = 0; v < n; ++v) index.emplace(vehicles[v], v);
    std::vector<models::VehicleState> cur(
        n);  // zeros before departure, the last state after arrival
    auto store = [&](std::int64_t frame) {
      if (frame < frames)
        std::copy(cur.begin(), cur.end(), r.states.begin() + frame * static_cast<std::int64_t>(n));
    };
    skip_ws();
    if (take("<?xml")) skip_past("?>");
    skip_misc();
    expect("<fcd-export");
    std::int64_t last = 0;  // frame of the last timestep read (frame 0: before the first step)
    if (!attributes()) {
      for (;;) {
        skip_misc();
        if (take("</fcd-export")) {
          skip_ws();
          expect(">");
          break;
        }
        expect("<timestep");
        const bool empty = attributes();
        if (attrs_.size() != 1 || attrs_[0].first != "time")
          fail("expected <timestep time=\"...\">");
        const double t = number(attrs_[0].second);
        const auto ms = std::llround(t * 1000.0);
        if (std::abs(t * 1000.0 - static_cast<double>(ms)) > 1e-6 || ms % step_ms != 0 ||
            ms / step_ms + 1 != last + 1) {
          fail(fmt::format("timestep time=\"{}\" where {} s (step {} ms) was expected",
                           attrs_[0].second, ms_to_seconds(last * step_ms), step_ms));
        }
        ++last;
        for (auto& c : cur) c.present = false;
        std::vector<char> seen(n, 0);
        while (!empty) {
          skip_misc();
          if (take("</timestep")) {
            skip_ws();
            expect(">");
            break;
          }
          expect("<vehicle");
          if (!attributes()) fail("expected an empty <vehicle .../> element");
          vehicle(index, seen, cur);
        }
        store(last);
      }
    }
    skip_misc();
    if (i_ != s_.size()) fail("unexpected content after </fcd-export>");
    for (auto& c : cur) c.present = false;
    for (std::int64_t f = last + 1; f < frames; ++f) store(f);  // SUMO stopped early: nobody left
    return r;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(fmt::format("SUMO FCD output '{}', byte {}: {}", path_, i_, what));
  }
  bool skip_ws() {
    const std::size_t start = i_;
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\n' || s_[i_] == '\r' || s_[i_] == '\t'))
      ++i_;
    return i_ > start;
  }
  bool take(std::string_view t) {
    if (s_.compare(i_, t.size(), t) != 0) return false;
    i_ += t.size();
    return true;
  }
  void expect(std::string_view t) {
    if (!take(t))
      fail(fmt::format("expected '{}', found '{}'", t,
                       s_.substr(i_, std::min<std::size_t>(40, s_.size() - i_))));
  }
  void skip_past(std::string_view t) {
    const auto e = s_.find(t, i_);
    if (e == std::string::npos) fail(fmt::format("unterminated, expected '{}'", t));
    i_ = e + t.size();
  }
  void skip_misc() {  // whitespace and comments
    skip_ws();
    while (take("<!--")) {
      skip_past("-->");
      skip_ws();
    }
  }
  // Attributes up to '>' or '/>' (true when empty: '/>') into attrs_.
  bool attributes() {
    attrs_.clear();
    for (;;) {
      const bool ws = skip_ws();
      if (take("/>")) return true;
      if (take(">")) return false;
      if (!ws) fail("expected whitespace, '>' or '/>'");
      const std::size_t b = i_;
      while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) != 0 ||
                                s_[i_] == '_' || s_[i_] == ':' || s_[i_] == '-' || s_[i_] == '.')) {
        ++i_;
      }
      if (i_ == b) fail("expected an attribute name");
      std::string name = s_.substr(b, i_ - b);
      skip_ws();
      expect("=");
      skip_ws();
      expect("\"");
      const auto e = s_.find('"', i_);
      if (e == std::string::npos) fail("unterminated attribute value");
      std::string value = s_.substr(i_, e - i_);
      if (value.find_first_of("<&") != std::string::npos)
        fail(fmt::format("unexpected '<' or '&' in {}=\"{}\"", name, value));
      i_ = e + 1;
      attrs_.emplace_back(std::move(name), std::move(value));
    }
  }
  double number(const std::string& text) const {
    char* end = nullptr;
    errno = 0;
    const double x = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(x)) {
      fail(fmt::format("expected a finite number, got \"{}\"", text));
    }
    return x;
  }
  void vehicle(const std::unordered_map<std::string_view, std::size_t>& index,
               std::vector<char>& seen, std::vector<models::VehicleState>& cur) {
    static constexpr std::array<std::string_view, 6> kNames{"id",           "x",       "y", "speed",
                                                            "acceleration", "odometer"};
    if (attrs_.size() != kNames.size())
      fail("expected <vehicle id x y speed acceleration odometer/>");
    std::array<const std::string*, 6> v{};
    for (const auto& [name, value] : attrs_) {
      const auto it = std::find(kNames.begin(), kNames.end(), name);
      if (it == kNames.end()) fail(fmt::format("unexpected vehicle attribute '{}'", name));
      const auto k = static_cast<std::size_t>(it - kNames.begin());
      if (v[k] != nullptr) fail(fmt::format("vehicle attribute '{}' twice", name));
      v[k] = &value;
    }
    const auto it = index.find(*v[0]);
    if (it == index.end()) fail(fmt::format("vehicle \"{}\" was not asked for", *v[0]));
    if (seen[it->second] != 0) fail(fmt::format("vehicle \"{}\" twice in one timestep", *v[0]));
    seen[it->second] = 1;
    models::VehicleState& s = cur[it->second];
    s.x = number(*v[1]);
    s.y = number(*v[2]);
    s.speed = number(*v[3]);
    s.accel = number(*v[4]);
    s.pos = number(*v[5]);
    s.present = true;
  }

  std::string path_, s_;
  std::size_t i_ = 0;
  std::vector<std::pair<std::string, std::string>> attrs_;
};

// ---------------------------------------------------------------- live worker protocol
// Request (main -> worker): int64 frame to advance to. Reply: uint8 0 then, per named vehicle,
// uint8 present and the doubles x, y, pos, speed, accel (native layout: same machine); or
// uint8 1, uint32 length and an error message (the worker then exits). The worker replies once
// after loading the simulation (frame 0) and exits 0 at end of input.

constexpr std::size_t kStateBytes = 1 + 5 * sizeof(double);

bool write_all(int fd, const void* data, std::size_t n) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t k = ::send(fd, p, n, MSG_NOSIGNAL);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;
    p += k;
    n -= static_cast<std::size_t>(k);
  }
  return true;
}

bool read_all(int fd, void* data, std::size_t n) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t k = ::read(fd, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) return false;
    p += k;
    n -= static_cast<std::size_t>(k);
  }
  return true;
}

void put_state(std::string& buf, const models::VehicleState& s) {
  buf.push_back(s.present ? '\1' : '\0');
  for (double x : {s.x, s.y, s.pos, s.speed, s.accel})
    buf.append(reinterpret_cast<const char*>(&x), sizeof x);
}

bool send_error(int fd, const std::string& msg) {
  std::string buf(1, '\1');
  const auto len = static_cast<std::uint32_t>(msg.size());
  buf.append(reinterpret_cast<const char*>(&len), sizeof len);
  buf += msg;
  return write_all(fd, buf.data(), buf.size());
}

std::atomic<int> g_live_counter{0};

// One live run: `ncosim sumo-live` steps libsumo; this process only reads the states.
class WorkerRun final : public models::MobilityRun {
 public:
  WorkerRun(const SumoInputs& in, std::uint64_t seed, const std::vector<std::string>& vehicles)
      : seed_(seed), step_ns_(in.step_ms * 1'000'000), states_(vehicles.size()) {
    if (g_worker.empty()) {
      throw std::runtime_error(
          "SUMO live mode needs the ncosim executable as its worker (set_worker_executable)");
    }
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
      throw std::runtime_error(
          fmt::format("cannot create the SUMO live worker's socket: {}", std::strerror(errno)));
    }
    fd_ = sv[0];
    log_ = (fs::temp_directory_path() /
            fmt::format("ncosim-sumo-live-{}-{}.log", ::getpid(), g_live_counter++))
               .string();
    std::vector<std::string> argv{g_worker,    "sumo-live",
                                  "--seed",    std::to_string(seed),
                                  "--step-ms", std::to_string(in.step_ms)};
    for (const auto& v : vehicles) argv.insert(argv.end(), {"--vehicle", v});
    argv.emplace_back("--");
    argv.insert(argv.end(), in.args.begin(), in.args.end());
    try {
      pid_ = spawn(g_worker, argv, nullptr, log_, sv[1]);
    } catch (...) {
      ::close(sv[1]);
      ::close(fd_);
      std::error_code ec;
      fs::remove(log_, ec);
      throw;
    }
    ::close(sv[1]);  // only the worker holds its end: its death is end-of-file here
    receive();       // frame 0, or the load error
  }
  ~WorkerRun() override { shut_down(); }
  WorkerRun(const WorkerRun&) = delete;
  WorkerRun& operator=(const WorkerRun&) = delete;

  void advance(sim::SimTime t) override {
    const std::int64_t target = t / step_ns_;
    if (target <= frame_) return;
    if (pid_ < 0)
      throw std::runtime_error(fmt::format("SUMO live worker (seed {}) is gone", seed_));
    if (!write_all(fd_, &target, sizeof target)) died("did not take the request");
    receive();
    frame_ = target;
  }
  const models::VehicleState& vehicle(int index) const override {
    return states_[static_cast<std::size_t>(index)];
  }

 private:
  void receive() {
    std::uint8_t status = 0;
    if (!read_all(fd_, &status, 1)) died("closed the connection");
    if (status == 1) {
      std::uint32_t len = 0;
      if (!read_all(fd_, &len, sizeof len) || len > (1u << 20)) died("sent a broken error message");
      std::string msg(len, '\0');
      if (!read_all(fd_, msg.data(), len)) died("sent a broken error message");
      shut_down();
      throw std::runtime_error(fmt::format("SUMO (live, seed {}): {}", seed_, msg));
    }
    if (status != 0) died(fmt::format("sent an unexpected reply (byte {})", status));
    std::vector<char> buf(kStateBytes * states_.size());
    if (!read_all(fd_, buf.data(), buf.size())) died("closed the connection mid-reply");
    const char* p = buf.data();
    for (auto& s : states_) {
      if (*p != 0 && *p != 1) died("sent an unexpected reply (bad present flag)");
      s.present = *p++ != 0;
      for (double* x : {&s.x, &s.y, &s.pos, &s.speed, &s.accel}) {
        std::memcpy(x, p, sizeof *x);
        p += sizeof *x;
      }
    }
  }
  [[noreturn]] void died(const std::string& what) {
    ::close(fd_);
    fd_ = -1;
    std::string how = "running";
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);  // a worker that broke the protocol is stopped
      how = exit_text(wait_for(pid_));
      pid_ = -1;
    }
    std::string log = read_file(log_);
    while (!log.empty() && (log.back() == '\n' || log.back() == '\r')) log.pop_back();
    std::error_code ec;
    fs::remove(log_, ec);
    throw std::runtime_error(fmt::format("SUMO live worker (seed {}) {} ({}){}", seed_, what, how,
                                         log.empty() ? "" : ": " + log));
  }
  void shut_down() {
    if (fd_ >= 0) ::close(fd_);  // end of input: the worker exits
    fd_ = -1;
    if (pid_ > 0) wait_for(pid_);
    pid_ = -1;
    std::error_code ec;
    fs::remove(log_, ec);
  }

  std::uint64_t seed_;
  std::int64_t step_ns_;
  std::vector<models::VehicleState> states_;
  int fd_ = -1;
  pid_t pid_ = -1;
  std::string log_;
  std::int64_t frame_ = 0;
};

}  // namespace

std::string sumo_binary() {
  if (const char* e = std::getenv("NCOSIM_SUMO_BINARY"); e != nullptr && *e != '\0') {
    if (::access(e, X_OK) != 0)
      throw std::runtime_error(fmt::format("NCOSIM_SUMO_BINARY '{}' is not executable", e));
    return e;
  }
  std::vector<fs::path> tried;
  if (const char* path = std::getenv("PATH"); path != nullptr) {
    std::stringstream dirs(path);
    for (std::string d; std::getline(dirs, d, ':');)
      tried.push_back(fs::path(d.empty() ? "." : d) / "sumo");
  }
  if (const char* home = std::getenv("SUMO_HOME"); home != nullptr && *home != '\0') {
    tried.push_back(fs::path(home) / "bin" / "sumo");
  }
  for (const auto& p : tried) {
    std::error_code ec;
    if (fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0) return p.string();
  }
  throw std::runtime_error(
      "cannot find the `sumo` binary on PATH or in $SUMO_HOME/bin (apt install sumo)");
}

Recording parse_fcd(const std::string& path, std::int64_t step_ms, std::int64_t frames,
                    const std::vector<std::string>& vehicles) {
  if (!fs::is_regular_file(path))
    throw std::runtime_error(fmt::format("SUMO wrote no FCD output '{}'", path));
  return FcdReader(path).read(step_ms, frames, vehicles);
}

Recording record(const SumoInputs& in, std::uint64_t seed, std::int64_t frames,
                 const std::vector<std::string>& vehicles) {
  const SumoEnvironment env;
  const std::string stem =
      (fs::temp_directory_path() / fmt::format("ncosim-sumo-{}-{}", ::getpid(), g_live_counter++))
          .string();
  SumoProcess p = start_sumo(sumo_binary(), env.ptrs.data(), in, seed, frames, vehicles, stem);
  return finish_sumo(p, in, frames, vehicles);
}

std::unique_ptr<models::MobilityRun> start_live(const SumoInputs& in, std::uint64_t seed,
                                                const std::vector<std::string>& vehicles) {
  return std::make_unique<WorkerRun>(in, seed, vehicles);
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
  struct RemoveOnFailure {
    const std::string& file;
    bool done = false;
    ~RemoveOnFailure() {
      std::error_code ec;
      if (!done) fs::remove(file, ec);
    }
  } guard{tmp};
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
  guard.done = true;
}

Recording read_recording(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(fmt::format("cannot open '{}'", path));
  char magic[8];
  in.read(magic, sizeof magic);
  if (!in || std::memcmp(magic, kMagic, sizeof magic) != 0)
    throw std::runtime_error("not an ncosim SUMO recording");
  Recording r;
  std::uint32_t n = 0;
  get(in, r.step_ms);
  get(in, r.frames);
  get(in, n);
  if (r.step_ms <= 0 || r.frames <= 0 || n > 100000)
    throw std::runtime_error("corrupt recording header");
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

Mobility::Mobility(const sim::Table& t, const sim::RunSettings& run, const std::string& dir)
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
  for (const auto& f : inputs_.files) sim::note_input_file(f);  // part of the campaign's identity
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
  horizon_ns_ = (run.periods - 1) * sim::seconds_to_time(run.period);
  frames_ = horizon_ns_ / (inputs_.step_ms * 1'000'000) + 1;
  t.finish();
}

int Mobility::vehicle(const sim::Table& t, std::string_view key) {
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

void announce_vehicles(const toml::table& doc, const std::string& file, const std::string& dir) {
  try {
    const toml::table* sumo = doc["sumo"].as_table();
    if (sumo == nullptr) return;
    sim::RunSettings run;
    if (const auto* r = doc["run"].as_table()) {
      run.periods = (*r)["periods"].value_or(run.periods);
      run.period = (*r)["period"].value_or(run.period);
    }
    const sim::Table t(*sumo, "sumo", file);
    const Mobility m(t, run, dir);
    std::vector<std::string> v;
    if (doc["plant"]["kind"].value_or(std::string()) == "sumo_vehicle")
      add_unique(v, doc["plant"]["vehicle"].value_or(std::string()));
    if (const auto* links = doc["link"].as_array()) {
      for (const auto& l : *links) {
        const auto* lt = l.as_table();
        if (lt == nullptr || (*lt)["kind"].value_or(std::string()) != "sumo_distance") continue;
        add_unique(v, (*lt)["sender"].value_or(std::string()));
        add_unique(v, (*lt)["receiver"].value_or(std::string()));
      }
    }
    const std::lock_guard<std::mutex> lock(announced_mutex());
    auto& list = announced()[m.traffic_key()];
    for (const auto& x : v) add_unique(list, x);
  } catch (const std::exception&) {
  }
}

void Mobility::prepare() {
  auto fail = [&](const std::string& why) {
    throw sim::ScenarioError(
        sim::format_error(file_, line_, fmt::format("sumo.{}", config_key_), why));
  };
  std::error_code ec;
  fs::create_directories(cache_dir_, ec);
  if (!fs::is_directory(cache_dir_))
    fail(fmt::format("cannot create the recording cache '{}'", cache_dir_));
  struct Job {
    std::uint64_t seed;
    std::string path;
  };
  std::vector<Job> jobs, missing;
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
    Job j{seed, (fs::path(cache_dir_) / (key_for(seed) + ".traj")).string()};
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
    // One `sumo` process per realisation, at most one per core at a time.
    std::string exe;
    try {
      exe = sumo_binary();
    } catch (const std::exception& e) {
      fail(e.what());
    }
    const SumoEnvironment env;
    const std::size_t width = std::max(1u, std::thread::hardware_concurrency());
    std::string first_error;
    for (std::size_t b = 0; b < missing.size(); b += width) {
      std::vector<std::pair<SumoProcess, const Job*>> running;
      for (std::size_t i = b; i < std::min(missing.size(), b + width); ++i) {
        const Job& j = missing[i];
        try {
          running.emplace_back(
              start_sumo(exe, env.ptrs.data(), inputs_, j.seed, frames_, record_vehicles,
                         fmt::format("{}.{}", j.path, ::getpid())),
              &j);
        } catch (const std::exception& e) {
          if (first_error.empty()) first_error = e.what();
          break;
        }
      }
      for (auto& [proc, job] : running) {  // every started process is waited for
        try {
          const Recording r = finish_sumo(proc, inputs_, frames_, record_vehicles);
          if (first_error.empty()) write_recording(job->path, r);
        } catch (const std::exception& e) {
          if (first_error.empty())
            first_error = fmt::format("SUMO failed (seed {}): {}", job->seed, e.what());
        }
      }
      if (!first_error.empty()) fail(first_error);
    }
  }
  recordings_.clear();
  for (const Job& j : jobs) {
    try {
      const Recording all = read_recording(j.path);
      if (!holds(all, vehicles_) || all.frames != frames_)
        fail(fmt::format("recording '{}' does not match; remove it", j.path));
      recordings_.push_back(project(all, vehicles_));
    } catch (const sim::ScenarioError&) {
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
      if (!seen) {
        const Origin& o = origins_[v];
        throw sim::ScenarioError(sim::format_error(
            o.file, o.line, o.path,
            fmt::format("vehicle \"{}\" never drives in SUMO (seed {}) during the {:g} s horizon: "
                        "unknown id, or it "
                        "departs later",
                        vehicles_[v], j.seed, sim::time_to_seconds(horizon_ns_))));
      }
    }
  }
  std::cerr << fmt::format("sumo: {} realisation(s) recorded, {} reused (cache {})\n", recorded_,
                           reused_, cache_dir_);
}

std::unique_ptr<models::MobilityRun> Mobility::start(std::uint64_t run) const {
  const auto s = static_cast<std::size_t>(run % static_cast<std::uint64_t>(seeds_));
  if (live_) return start_live(inputs_, first_seed_ + s, vehicles_);
  return std::make_unique<ReplayRun>(recordings_[s]);
}

int live_worker_main(const std::vector<std::string>& args) {
  constexpr int fd = 3;  // the socket to the main process
  std::int64_t step_ns = 0;
  std::unique_ptr<models::MobilityRun> run;
  std::size_t n = 0;
  try {
    SumoInputs in;
    std::uint64_t seed = 0;
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
      if (a == "--seed")
        seed = std::stoull(value(a));
      else if (a == "--step-ms")
        in.step_ms = std::stoll(value(a));
      else if (a == "--vehicle")
        vehicles.push_back(value(a));
      else
        throw std::runtime_error("unknown option " + a);
    }
    if (in.step_ms < 1 || in.args.empty())
      throw std::runtime_error("expected --step-ms and -- SUMO inputs");
    step_ns = in.step_ms * 1'000'000;
    n = vehicles.size();
    run.reset(session_api().start_live(&in, seed, &vehicles));
  } catch (const std::exception& e) {
    if (!send_error(fd, e.what())) std::cerr << e.what() << "\n";
    return 2;
  }
  for (;;) {
    std::string reply(1, '\0');
    for (std::size_t v = 0; v < n; ++v) put_state(reply, run->vehicle(static_cast<int>(v)));
    if (!write_all(fd, reply.data(), reply.size())) return 1;  // the main process is gone
    std::int64_t frame = 0;
    if (!read_all(fd, &frame, sizeof frame)) return 0;  // end of input: done
    try {
      if (frame < 0 || frame > std::numeric_limits<std::int64_t>::max() / step_ns) {
        throw std::runtime_error(fmt::format("bad frame request {}", frame));
      }
      run->advance(frame * step_ns);
    } catch (const std::exception& e) {
      send_error(fd, e.what());
      return 2;
    }
  }
}

}  // namespace ncosim::sumo

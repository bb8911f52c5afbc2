// sumo/recording.cc — recording the traffic: `sumo` processes writing FCD output, its strict
// reader, and the binary recording files of the cache.
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "sumo/process.h"
#include "sumo/traffic.h"

extern char** environ;

namespace ncosim::sumo {

namespace fs = std::filesystem;

namespace {

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
      (fs::temp_directory_path() / fmt::format("ncosim-sumo-{}-{}", ::getpid(), next_temp_serial()))
          .string();
  SumoProcess p = start_sumo(sumo_binary(), env.ptrs.data(), in, seed, frames, vehicles, stem);
  return finish_sumo(p, in, frames, vehicles);
}

void record_all(const SumoInputs& in, std::int64_t frames, const std::vector<std::string>& vehicles,
                const std::vector<RecordingJob>& jobs) {
  const std::string exe = sumo_binary();
  const SumoEnvironment env;
  const std::size_t width = std::max(1u, std::thread::hardware_concurrency());
  std::string first_error;
  for (std::size_t b = 0; b < jobs.size(); b += width) {
    std::vector<std::pair<SumoProcess, const RecordingJob*>> running;
    for (std::size_t i = b; i < std::min(jobs.size(), b + width); ++i) {
      const RecordingJob& j = jobs[i];
      try {
        running.emplace_back(start_sumo(exe, env.ptrs.data(), in, j.seed, frames, vehicles,
                                        fmt::format("{}.{}", j.path, ::getpid())),
                             &j);
      } catch (const std::exception& e) {
        if (first_error.empty()) first_error = e.what();
        break;
      }
    }
    for (auto& [proc, job] : running) {  // every started process is waited for
      try {
        const Recording r = finish_sumo(proc, in, frames, vehicles);
        if (first_error.empty()) write_recording(job->path, r);
      } catch (const std::exception& e) {
        if (first_error.empty())
          first_error = fmt::format("SUMO failed (seed {}): {}", job->seed, e.what());
      }
    }
    if (!first_error.empty()) throw std::runtime_error(first_error);
  }
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

}  // namespace ncosim::sumo

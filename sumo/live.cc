// sumo/live.cc — `mode = "live"`: libsumo stepped in a worker process per run (`ncosim
// sumo-live`, which dlopens the libsumo module), driven over a socket by a small binary protocol.
#include <dlfcn.h>
#include <fmt/format.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <stdexcept>

#include "kernel/wire.h"
#include "sumo/process.h"
#include "sumo/traffic.h"

namespace ncosim::sumo {

namespace fs = std::filesystem;

namespace {

std::string g_worker;

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

// ---------------------------------------------------------------- live worker protocol
// Request (main -> worker): int64 frame to advance to. Reply: uint8 0 then, per named vehicle,
// uint8 present and the doubles x, y, pos, speed, accel (native layout: same machine); or
// uint8 1, uint32 length and an error message (the worker then exits). The worker replies once
// after loading the simulation (frame 0) and exits 0 at end of input.

constexpr std::size_t kStateBytes = 1 + 5 * sizeof(double);

using kernel::read_all;
using kernel::write_all;

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
            fmt::format("ncosim-sumo-live-{}-{}.log", ::getpid(), next_temp_serial()))
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

  void advance(kernel::SimTime t) override {
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

std::unique_ptr<models::MobilityRun> start_live(const SumoInputs& in, std::uint64_t seed,
                                                const std::vector<std::string>& vehicles) {
  return std::make_unique<WorkerRun>(in, seed, vehicles);
}

void set_worker_executable(const std::string& path) { g_worker = path; }

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

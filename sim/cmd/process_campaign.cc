// sim/cmd/process_campaign.cc — a campaign over worker processes (see process_campaign.h).
#include "sim/cmd/process_campaign.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "kernel/wire.h"
#include "sim/run/progress.h"
#include "sim/run/run.h"
#include "sim/store/store_format.h"

namespace ncosim::sim {

bool needs_worker_processes(const Scenario& sc) { return !sc.networks.empty(); }

namespace {
// A child process that died of a signal (bytes_from_child): e.g. ns-3 crashed in it.
struct ChildSignalled : std::runtime_error {
  using std::runtime_error::runtime_error;
};
}  // namespace

namespace {

// Worker -> parent messages: a type byte, the run, the length, then the bytes.
// kFailure: the run's process died (its body says why); the worker goes on.
enum : char { kResult = 'R', kError = 'E', kCurve = 'C', kFailure = 'F' };

using kernel::get_string;
using kernel::get_u64;
using kernel::put_string;
using kernel::put_u64;
using kernel::read_all;
using kernel::write_all;

bool send_message(int fd, char type, std::uint64_t run, const std::string& body) {
  std::string m(1, type);
  put_u64(m, run);
  put_u64(m, body.size());
  m += body;
  return write_all(fd, m.data(), m.size());
}

std::string exit_text(int status) {
  return WIFSIGNALED(status) ? fmt::format("signal {}", WTERMSIG(status))
                             : fmt::format("exit status {}", WEXITSTATUS(status));
}

// The text a process wrote on stderr, kept up to this many bytes (the tail, when more).
constexpr std::size_t kStderrKept = 1 << 20;

// The child's side of run_in_child: the run, then on `out` its result ('R': the serialized
// metrics, link counters and error curve, each length-prefixed) or its error ('E' and the text).
[[noreturn]] void child_run(const Scenario& sc, std::uint64_t run, bool link_counters, int out) {
  std::string msg;
  try {
    ErrorCurve curve = sc.run.error_curve ? error_curve_of(sc) : ErrorCurve();
    RunLinks links;
    const RunMetrics m = execute_run(sc, run, nullptr, nullptr, link_counters ? &links : nullptr,
                                     sc.run.error_curve ? &curve : nullptr);
    if (sc.run.error_curve) curve.add_run(run);
    msg = "R";
    put_string(msg, serialize_run(m));
    put_string(msg, link_counters ? serialize_links(links) : std::string());
    put_string(msg, sc.run.error_curve ? curve.serialize() : std::string());
  } catch (const std::exception& e) {
    msg = std::string("E") + e.what();
  } catch (...) {  // never unwind into the parent's code, which this process is a copy of
    ::_exit(2);
  }
  ::_exit(write_all(out, msg.data(), msg.size()) ? 0 : 1);
}

// Reads `result` and `err` until both are at end of file (the child has ended): the result's
// bytes, and the tail of what it wrote on stderr. Both at once, so that a child that writes much
// on stderr never blocks on a full pipe.
void drain(int result, int err, std::string& bytes, std::string& text) {
  pollfd fds[2] = {{result, POLLIN, 0}, {err, POLLIN, 0}};
  std::string* into[2] = {&bytes, &text};
  char buf[65536];
  while (fds[0].fd >= 0 || fds[1].fd >= 0) {
    if (::poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    for (int i = 0; i < 2; ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      const ssize_t r = ::read(fds[i].fd, buf, sizeof buf);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) {
        fds[i].fd = -1;  // poll ignores a negative descriptor
        continue;
      }
      into[i]->append(buf, static_cast<std::size_t>(r));
      if (i == 1 && text.size() > 2 * kStderrKept) text.erase(0, text.size() - kStderrKept);
    }
  }
}

// The last line of `text` that says something: libstdc++'s own line on std::terminate (which
// ns-3's NS_FATAL_ERROR calls after its message) is skipped.
std::string last_line(const std::string& text) {
  std::istringstream in(text);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (line.rfind("terminate called", 0) == 0) continue;
    last = line;
  }
  return last;
}

// `bytes`, a child's result message, into `out` (its error, or a failure when malformed).
void decode_child(const std::string& bytes, ChildRun& out) {
  if (!bytes.empty() && bytes[0] == 'E') {
    out.error = bytes.substr(1);
    return;
  }
  std::size_t at = 1;
  std::string metrics, links, curve;
  if (bytes.empty() || bytes[0] != 'R' || !get_string(bytes, at, metrics) ||
      !get_string(bytes, at, links) || !get_string(bytes, at, curve)) {
    out.failure = "its process ended without a complete result";
    return;
  }
  out.metrics = deserialize_run(metrics);
  if (!links.empty()) out.links = deserialize_links(links);
  if (!curve.empty()) out.curve = ErrorCurve::deserialize(curve);
}

// One run in a process of its own (run_in_child), for a worker: its result (and curve) or its
// failure to the parent on `fd`; false when the campaign cannot go on (an error was sent).
bool serve_one(const Scenario& sc, const CampaignOptions& options, std::uint64_t run, int fd) {
  ChildRun c = run_in_child(sc, run, options.link_counters);
  if (!c.error.empty()) {
    send_message(fd, kError, run, c.error);
    return false;
  }
  if (!c.failure.empty()) return send_message(fd, kFailure, run, c.failure);
  std::string body;
  const std::string metrics = serialize_run(c.metrics);
  put_u64(body, metrics.size());
  body += metrics;
  if (options.link_counters) body += serialize_links(c.links);
  if (!send_message(fd, kResult, run, body)) return false;
  return !sc.run.error_curve || send_message(fd, kCurve, run, c.curve.serialize());
}

// A worker: runs from `fd` until the parent shuts its side for writing, each in a process of its
// own (run_in_child). Never returns.
[[noreturn]] void serve(const Scenario& sc, const CampaignOptions& options, int fd) {
  char buf[8];
  while (read_all(fd, buf, 8)) {
    if (!serve_one(sc, options, get_u64(buf), fd)) ::_exit(0);
  }
  ::_exit(0);
}

struct Worker {
  pid_t pid = -1;
  int fd = -1;         // this process's end of the worker's socket (-1: the worker has ended)
  bool giving = true;  // runs may still be sent (false: shut for writing)
  bool busy = false;
  std::uint64_t run = 0;  // the run it is simulating, when busy
  std::string pending;    // bytes of a message not yet complete
};

class Distribution {
 public:
  Distribution(const Scenario& sc, const CampaignOptions& options, std::vector<std::uint64_t> todo)
      : sc_(sc), options_(options), todo_(std::move(todo)) {}
  Distribution(const Distribution&) = delete;
  Distribution& operator=(const Distribution&) = delete;
  // After a failure part-way (a fork, a malformed message): the workers left are stopped and
  // reaped, never left blocked on their sockets.
  ~Distribution() {
    for (Worker& w : workers_) {
      if (w.pid > 0) ::kill(w.pid, SIGKILL);
      reap(w);
    }
  }

  void start(int count) {
    for (int w = 0; w < count; ++w) {
      int sv[2];
      if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
        throw std::runtime_error(
            fmt::format("cannot create a socket pair: {}", std::strerror(errno)));
      const pid_t pid = ::fork();
      if (pid < 0)
        throw std::runtime_error(
            fmt::format("cannot start worker process {} of {}: {}; retry with a smaller --threads",
                        w + 1, count, std::strerror(errno)));
      if (pid == 0) {
        ::signal(SIGINT, SIG_IGN);  // the parent decides when to stop (options.stop)
        ::signal(SIGTERM, SIG_IGN);
        ::close(sv[0]);
        for (const Worker& o : workers_) ::close(o.fd);
        serve(sc_, options_, sv[1]);
      }
      ::close(sv[1]);
      Worker worker;
      worker.pid = pid;
      worker.fd = sv[0];
      workers_.push_back(std::move(worker));
    }
    for (Worker& w : workers_) give(w);
  }

  // Until every worker has ended: results delivered, curves merged; the first failure kept.
  void collect(ErrorCurve& curve) {
    std::vector<pollfd> fds;
    while (true) {
      fds.clear();
      for (const Worker& w : workers_) {
        if (w.fd >= 0) fds.push_back(pollfd{w.fd, POLLIN, 0});
      }
      if (fds.empty()) break;
      if (::poll(fds.data(), fds.size(), 200) < 0 && errno != EINTR)
        throw std::runtime_error(fmt::format("poll: {}", std::strerror(errno)));
      std::size_t i = 0;
      for (Worker& w : workers_) {
        if (w.fd < 0) continue;
        const short revents = fds[i++].revents;
        if (stopping()) finish_giving(w);
        // Only a worker with something to read: a read on another would wait for its run.
        if ((revents & (POLLIN | POLLHUP | POLLERR)) != 0) read_from(w, curve);
      }
    }
    for (Worker& w : workers_) reap(w);
    if (!error_.empty()) throw std::runtime_error(error_);
  }

  std::size_t done() const { return done_; }
  bool failed(std::uint64_t run) const {
    return std::find(failed_.begin(), failed_.end(), run) != failed_.end();
  }
  std::size_t runs() const { return todo_.size(); }

 private:
  bool stopping() const {
    return !error_.empty() || (options_.stop != nullptr && options_.stop->load() != 0);
  }

  void give(Worker& w) {
    if (stopping() || next_ >= todo_.size()) {
      finish_giving(w);
      return;
    }
    w.run = todo_[next_++];
    w.busy = true;
    char buf[8];
    for (int i = 0; i < 8; ++i) buf[i] = static_cast<char>((w.run >> (8 * i)) & 0xFF);
    if (!write_all(w.fd, buf, 8)) finish_giving(w);  // it died: read_from reports it
  }
  void finish_giving(Worker& w) {
    if (w.giving && !w.busy && w.fd >= 0) {
      ::shutdown(w.fd, SHUT_WR);
      w.giving = false;
    }
  }

  void read_from(Worker& w, ErrorCurve& curve) {
    char buf[65536];
    const ssize_t r = ::read(w.fd, buf, sizeof buf);
    if (r < 0 && (errno == EINTR || errno == EAGAIN)) return;
    if (r > 0) {
      w.pending.append(buf, static_cast<std::size_t>(r));
      while (w.pending.size() >= 17) {
        const std::uint64_t n = get_u64(w.pending.data() + 9);
        if (w.pending.size() < 17 + n) break;
        handle(w, w.pending[0], get_u64(w.pending.data() + 1), w.pending.substr(17, n), curve);
        w.pending.erase(0, 17 + n);
      }
      return;
    }
    // End of file: the worker has ended (after its curve), or died.
    ::close(w.fd);
    w.fd = -1;
    if (w.busy && error_.empty()) {
      const int status = reap(w);
      error_ = fmt::format("run {}: its worker process ended without a result ({})", w.run,
                           exit_text(status));
    }
  }

  void handle(Worker& w, char type, std::uint64_t run, const std::string& body, ErrorCurve& curve) {
    if (type == kError) {
      if (error_.empty()) error_ = fmt::format("run {}: {}", run, body);
      w.busy = false;
      return;
    }
    if (type == kCurve) {
      curve.merge(ErrorCurve::deserialize(body));
      return;
    }
    if (type == kFailure) {
      failed_.push_back(run);
      report_run_failure(run, body);
      options_.on_run(run, failed_run_metrics(sc_), RunLinks{});
    } else {
      const std::uint64_t n = get_u64(body.data());
      const std::string links = body.substr(8 + n);
      options_.on_run(run, deserialize_run(body.substr(8, n)),
                      links.empty() ? RunLinks{} : deserialize_links(links));
    }
    ++done_;
    if (options_.progress != nullptr) options_.progress->add_done();
    w.busy = false;
    give(w);
  }

  int reap(Worker& w) {
    int status = 0;
    if (w.fd >= 0) {
      ::close(w.fd);
      w.fd = -1;
    }
    if (w.pid > 0) {
      while (::waitpid(w.pid, &status, 0) < 0 && errno == EINTR) {
      }
      w.pid = -1;
    }
    return status;
  }

  const Scenario& sc_;
  const CampaignOptions& options_;
  std::vector<std::uint64_t> todo_;
  std::size_t next_ = 0, done_ = 0;
  std::vector<Worker> workers_;
  std::string error_;
  std::vector<std::uint64_t> failed_;  // the runs whose process died
};

// Doubles and integers of a trace row and of ns_per_period, as bytes (this machine's layout: the
// bytes never leave the machine).
template <class T>
void put_values(std::string& out, const std::vector<T>& v) {
  put_u64(out, v.size());
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}
template <class T>
std::vector<T> get_values(const std::string& in, std::size_t& at) {
  const std::uint64_t n = get_u64(in.data() + at);
  at += 8;
  if (n > (in.size() - at) / sizeof(T)) throw std::runtime_error("malformed replay message");
  std::vector<T> v(n);
  std::memcpy(v.data(), in.data() + at, n * sizeof(T));
  at += n * sizeof(T);
  return v;
}

std::string encode(const std::vector<double>& ns, const std::vector<TraceRow>& rows) {
  std::string out;
  put_values(out, ns);
  put_u64(out, rows.size());
  for (const TraceRow& r : rows) {
    put_values(out, std::vector<std::int64_t>{r.period, r.mode});
    put_values(out, r.x);
    put_u64(out, r.xhat.size());
    for (const auto& e : r.xhat) put_values(out, e);
    put_values(out, r.arrivals);
    put_values(out, r.mode_hat);
    put_values(out, r.u);
    put_values(out, r.y);
    put_values(out, std::vector<double>{r.reference});
  }
  return out;
}

void decode(const std::string& in, std::vector<double>& ns, std::vector<TraceRow>& rows) {
  std::size_t at = 0;
  ns = get_values<double>(in, at);
  const std::uint64_t n = get_u64(in.data() + at);
  at += 8;
  for (std::uint64_t i = 0; i < n; ++i) {
    TraceRow r;
    const auto head = get_values<std::int64_t>(in, at);
    r.period = head.at(0);
    r.mode = static_cast<int>(head.at(1));
    r.x = get_values<double>(in, at);
    const std::uint64_t e = get_u64(in.data() + at);
    at += 8;
    for (std::uint64_t j = 0; j < e; ++j) r.xhat.push_back(get_values<double>(in, at));
    r.arrivals = get_values<int>(in, at);
    r.mode_hat = get_values<int>(in, at);
    r.u = get_values<double>(in, at);
    r.y = get_values<double>(in, at);
    r.reference = get_values<double>(in, at).at(0);
    rows.push_back(std::move(r));
  }
}

// The trace of run `run` and the estimators' timing, simulated in a process of its own (so that
// this process never simulates a network: the workers it forks later start from its state).
void replay_in_child(const Scenario& sc, std::uint64_t run, bool trace, bool timed,
                     CampaignResult& result) {
  std::string bytes;
  try {
    bytes = bytes_from_child(
        [&] {
          std::vector<double> ns(sc.estimators.size(), std::nan(""));
          std::vector<TraceRow> rows;
          simulate_run(sc, run, trace ? &rows : nullptr, timed ? &ns : nullptr);
          return encode(ns, rows);
        },
        fmt::format("run {}: the replay for the trace and the timing", run));
  } catch (const ChildSignalled& e) {
    // A replay that died is the run's own crash again (its rows say network_failure): the
    // results go without the trace and the timing, said once here, rather than not at all.
    std::cerr << fmt::format("ncosim: {}; no trajectory.csv, no ns_per_period\n", e.what());
    return;
  }
  std::vector<double> ns;
  std::vector<TraceRow> rows;
  decode(bytes, ns, rows);
  if (timed) result.ns_per_period = std::move(ns);
  if (trace) result.trace = std::move(rows);
}

}  // namespace

std::string bytes_from_child(const std::function<std::string()>& work, const std::string& what) {
  int sv[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
    throw std::runtime_error(fmt::format("cannot create a socket pair: {}", std::strerror(errno)));
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(fmt::format("cannot fork: {}", std::strerror(errno)));
  if (pid == 0) {
    ::close(sv[0]);
    try {
      const std::string bytes = work();
      ::_exit(write_all(sv[1], bytes.data(), bytes.size()) ? 0 : 1);
    } catch (...) {  // never unwind into the parent's code, which this process is a copy of
      ::_exit(2);
    }
  }
  ::close(sv[1]);
  std::string bytes;
  char buf[65536];
  for (ssize_t r; (r = ::read(sv[0], buf, sizeof buf)) != 0;) {
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) break;
    bytes.append(buf, static_cast<std::size_t>(r));
  }
  ::close(sv[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status))
    throw ChildSignalled(fmt::format("{} ended abnormally ({})", what, exit_text(status)));
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error(
        fmt::format("{} ended without a result ({})", what, exit_text(status)));
  return bytes;
}

ChildRun run_in_child(const Scenario& sc, std::uint64_t run, bool link_counters) {
  ChildRun out;
  int sv[2], err[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
    out.error = fmt::format("cannot create a socket pair: {}", std::strerror(errno));
    return out;
  }
  if (::pipe2(err, O_CLOEXEC) != 0) {
    out.error = fmt::format("cannot create a pipe: {}", std::strerror(errno));
    ::close(sv[0]);
    ::close(sv[1]);
    return out;
  }
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(sv[0]);
    ::close(err[0]);
    ::dup2(err[1], STDERR_FILENO);
    ::close(err[1]);
    // The default actions on a crash: an MPI library's handlers (inherited from a rank) would
    // print their own report after ns-3's message, and they belong to the rank, not to this child.
    for (int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL}) ::signal(sig, SIG_DFL);
    child_run(sc, run, link_counters, sv[1]);
  }
  ::close(sv[1]);
  ::close(err[1]);
  std::string bytes, text;
  if (pid > 0) drain(sv[0], err[0], bytes, text);
  ::close(sv[0]);
  ::close(err[0]);
  if (pid < 0) {
    out.error = fmt::format("cannot fork: {}", std::strerror(errno));
    return out;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
    // Warnings of a run that ended normally are passed on, as if it had run here.
    if (!text.empty()) write_all(STDERR_FILENO, text);
    decode_child(bytes, out);
    return out;
  }
  const std::string line = last_line(text);
  out.failure = fmt::format("its process ended abnormally ({}){}", exit_text(status),
                            line.empty() ? "" : ": " + line);
  return out;
}

RunMetrics failed_run_metrics(const Scenario& sc) {
  RunMetrics m(sc.estimators.size());
  for (EstimatorRunMetrics& e : m) {
    e.diverged = true;
    e.status = kNetworkFailure;
    // Every per-state and per-sensor vector sized, with nothing counted: the exports index them.
    e.sse_state.assign(static_cast<std::size_t>(sc.model.plant.n()), 0.0);
    e.sensor_taken.assign(sc.model.sensors.size(), 0);
    e.sensor_sent.assign(sc.model.sensors.size(), 0);
    for (const auto& s : sc.model.sensors)
      e.sensor_virtual_sse.emplace_back(static_cast<std::size_t>(s.spec.ny()), 0.0);
  }
  return m;
}

void report_run_failure(std::uint64_t run, const std::string& failure) {
  std::cerr << fmt::format("ncosim: run {}: {}: {}; the campaign goes on without its results\n",
                           run, kNetworkFailure, failure)
            << std::flush;
}

std::vector<TraceRow> trace_in_child(const Scenario& sc, std::uint64_t run) {
  CampaignResult r;
  replay_in_child(sc, run, true, false, r);
  return std::move(r.trace);
}

std::vector<double> timing_in_child(const Scenario& sc, std::uint64_t run) {
  CampaignResult r;
  replay_in_child(sc, run, false, true, r);
  return std::move(r.ns_per_period);
}

CampaignResult run_in_processes(const Scenario& sc, const CampaignOptions& options) {
  std::vector<std::uint64_t> todo;
  if (options.only_runs) {
    todo = *options.only_runs;
  } else {
    for (std::int64_t r = 0; r < sc.run.runs; ++r) todo.push_back(static_cast<std::uint64_t>(r));
  }
  CampaignResult result;
  const int cores = static_cast<int>(std::thread::hardware_concurrency());
  const int count = std::max(1, std::min<int>(options.threads > 0 ? options.threads : cores,
                                              static_cast<int>(todo.size())));
  result.threads = count;
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t first = todo.empty() ? 0 : todo.front();
  Distribution d(sc, options, std::move(todo));
  d.start(count);
  d.collect(result.curve);
  result.runs_done = d.done();
  result.stopped = result.runs_done < d.runs();
  result.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.ns_per_period.assign(sc.estimators.size(), std::nan(""));
  const bool trace = options.trace && first == 0;
  // A run whose process died would die again in the replay: no trace or timing of it.
  if ((trace || options.time_estimators) && !result.stopped && d.runs() > 0 && !d.failed(first))
    replay_in_child(sc, first, trace, options.time_estimators, result);
  return result;
}

}  // namespace ncosim::sim

// sim/cmd/process_campaign.cc — a campaign over worker processes (see process_campaign.h).
#include "sim/cmd/process_campaign.h"

#include <fmt/format.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "sim/run/progress.h"
#include "sim/run/run.h"
#include "sim/store/store_format.h"

namespace ncosim::sim {

bool needs_worker_processes(const Scenario& sc) { return !sc.networks.empty(); }

namespace {

// Worker -> parent messages: a type byte, the run, the length, then the bytes.
enum : char { kResult = 'R', kError = 'E', kCurve = 'C' };

void put_u64(std::string& s, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
std::uint64_t get_u64(const char* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i)
    v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

bool write_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}
// Reads exactly n bytes; false at end of file (or an error) before them.
bool read_all(int fd, char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}

bool send_message(int fd, char type, std::uint64_t run, const std::string& body) {
  std::string m(1, type);
  put_u64(m, run);
  put_u64(m, body.size());
  m += body;
  return write_all(fd, m.data(), m.size());
}

// A worker: runs from `in` until it closes, results to `out`, then its error curve. Never returns.
[[noreturn]] void serve(const Scenario& sc, const CampaignOptions& options, int in, int out) {
  ErrorCurve curve = sc.run.error_curve ? error_curve_of(sc) : ErrorCurve();
  char buf[8];
  try {
    while (read_all(in, buf, 8)) {
      const std::uint64_t run = get_u64(buf);
      RunLinks links;
      RunMetrics m =
          execute_run(sc, run, nullptr, nullptr, options.link_counters ? &links : nullptr,
                      sc.run.error_curve ? &curve : nullptr);
      if (sc.run.error_curve) curve.add_run(run);
      std::string body;
      const std::string metrics = serialize_run(m);
      put_u64(body, metrics.size());
      body += metrics;
      if (options.link_counters) body += serialize_links(links);
      if (!send_message(out, kResult, run, body)) ::_exit(1);
    }
    if (sc.run.error_curve) send_message(out, kCurve, 0, curve.serialize());
  } catch (const std::exception& e) {
    send_message(out, kError, 0, e.what());
  }
  ::_exit(0);
}

struct Worker {
  pid_t pid = -1;
  int to = -1;    // runs to the worker (closed: no more)
  int from = -1;  // its messages
  bool busy = false;
  std::uint64_t run = 0;  // the run it is simulating, when busy
  std::string pending;    // bytes of a message not yet complete
};

class Distribution {
 public:
  Distribution(const Scenario& sc, const CampaignOptions& options, std::vector<std::uint64_t> todo)
      : sc_(sc), options_(options), todo_(std::move(todo)) {}

  void start(int count) {
    for (int w = 0; w < count; ++w) {
      int to[2], from[2];
      if (::pipe(to) != 0 || ::pipe(from) != 0)
        throw std::runtime_error(fmt::format("cannot create a pipe: {}", std::strerror(errno)));
      const pid_t pid = ::fork();
      if (pid < 0)
        throw std::runtime_error(
            fmt::format("cannot start worker process {} of {}: {}; retry with a smaller --threads",
                        w + 1, count, std::strerror(errno)));
      if (pid == 0) {
        ::signal(SIGINT, SIG_IGN);  // the parent decides when to stop (options.stop)
        ::signal(SIGTERM, SIG_IGN);
        ::close(to[1]);
        ::close(from[0]);
        for (const Worker& o : workers_) {
          ::close(o.to);
          ::close(o.from);
        }
        serve(sc_, options_, to[0], from[1]);
      }
      ::close(to[0]);
      ::close(from[1]);
      Worker worker;
      worker.pid = pid;
      worker.to = to[1];
      worker.from = from[0];
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
        if (w.from >= 0) fds.push_back(pollfd{w.from, POLLIN, 0});
      }
      if (fds.empty()) break;
      if (::poll(fds.data(), fds.size(), 200) < 0 && errno != EINTR)
        throw std::runtime_error(fmt::format("poll: {}", std::strerror(errno)));
      for (Worker& w : workers_) {
        if (w.from < 0) continue;
        if (stopping()) finish_giving(w);
        read_from(w, curve);
      }
    }
    for (Worker& w : workers_) reap(w);
    if (!error_.empty()) throw std::runtime_error(error_);
  }

  std::size_t done() const { return done_; }
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
    if (!write_all(w.to, buf, 8)) finish_giving(w);
  }
  void finish_giving(Worker& w) {
    if (w.to >= 0 && !w.busy) {
      ::close(w.to);
      w.to = -1;
    }
  }

  void read_from(Worker& w, ErrorCurve& curve) {
    char buf[65536];
    const ssize_t r = ::read(w.from, buf, sizeof buf);
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
    ::close(w.from);
    w.from = -1;
    if (w.busy && error_.empty()) {
      const int status = reap(w);
      error_ = fmt::format(
          "run {}: its worker process ended without a result ({}); the network simulation "
          "(ns-3) may have failed an assertion: run it alone with --threads 1 to see ns-3's "
          "message",
          w.run,
          WIFSIGNALED(status) ? fmt::format("signal {}", WTERMSIG(status))
                              : fmt::format("exit status {}", WEXITSTATUS(status)));
    }
  }

  void handle(Worker& w, char type, std::uint64_t run, const std::string& body, ErrorCurve& curve) {
    if (type == kError) {
      if (error_.empty()) error_ = fmt::format("run {}: {}", w.run, body);
      w.busy = false;
      return;
    }
    if (type == kCurve) {
      curve.merge(ErrorCurve::deserialize(body));
      return;
    }
    const std::uint64_t n = get_u64(body.data());
    const std::string links = body.substr(8 + n);
    options_.on_run(run, deserialize_run(body.substr(8, n)),
                    links.empty() ? RunLinks{} : deserialize_links(links));
    ++done_;
    if (options_.progress != nullptr) options_.progress->add_done();
    w.busy = false;
    give(w);
  }

  int reap(Worker& w) {
    int status = 0;
    if (w.to >= 0) {
      ::close(w.to);
      w.to = -1;
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
};

}  // namespace

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
  if ((trace || options.time_estimators) && !result.stopped && d.runs() > 0) {
    simulate_run(sc, first, trace ? &result.trace : nullptr,
                 options.time_estimators ? &result.ns_per_period : nullptr);
  }
  return result;
}

}  // namespace ncosim::sim

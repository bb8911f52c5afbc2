// sim/cmd/mpi_campaign.cc — runs over MPI ranks (see mpi_campaign.h).
#include "sim/cmd/mpi_campaign.h"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "kernel/wire.h"
#include "sim/run/progress.h"
#include "sim/store/store.h"

#if NCOSIM_HAVE_MPI
#include <boost/mpi/communicator.hpp>
#include <boost/mpi/environment.hpp>
#include <boost/serialization/string.hpp>
#include <boost/serialization/vector.hpp>
#endif

namespace ncosim::sim {

bool mpi_launched() {
  for (const char* var : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS"}) {
    const char* v = std::getenv(var);
    if (v != nullptr && std::atoi(v) > 1) return true;
  }
  return false;
}

#if NCOSIM_HAVE_MPI

bool mpi_available() { return true; }

namespace {

constexpr int kWork = 1;    // rank 0 -> worker: {case, run}
constexpr int kResult = 2;  // worker -> rank 0: 8 bytes case, 8 bytes run, 8 bytes n, n bytes of
                            // serialized metrics, the serialized link counters (empty: not counted)
constexpr int kError = 3;   // worker -> rank 0: what failed
constexpr int kStop = 4;    // rank 0 -> worker: no more work
constexpr int kCurve = 5;   // rank 0 -> worker: {case}; the reply: its error curve of that case
                            // (serialized, empty when none), which it then starts afresh
constexpr int kFailure = 6;  // worker -> rank 0: 8 bytes case, 8 bytes run, why the run's network
                             // died (its worker process: sim/run/campaign.h, campaign_run)

using kernel::put_u64;

}  // namespace

struct MpiSession::Impl {
  boost::mpi::environment env{boost::mpi::threading::serialized};
  boost::mpi::communicator world;
  int exit_code = 0;  // rank 0: the code sent to the workers; ranks > 0: the code rank 0 sent
  // Rank 0: every worker stops with exit_code; then MPI_Finalize (env's destructor, after this).
  ~Impl() {
    if (world.rank() == 0) {
      for (int w = 1; w < world.size(); ++w) world.send(w, kStop, exit_code);
    }
  }
};

MpiSession::MpiSession() : impl_(std::make_unique<Impl>()) {
  if (impl_->env.thread_level() < boost::mpi::threading::serialized) {
    throw std::runtime_error("MPI: the MPI library does not provide MPI_THREAD_SERIALIZED");
  }
}

// Not finalized here: the session ends while an error unwinds the stack on rank 0, and
// Boost.MPI's environment would then MPI_Abort (rc 255, the message lost); mpi_finish ends it
// once the error is reported and the exit code known.
MpiSession::~MpiSession() { ended() = std::move(impl_); }

std::unique_ptr<MpiSession::Impl>& MpiSession::ended() {
  static std::unique_ptr<Impl> impl;  // at exit without mpi_finish: stop with 0, MPI_Finalize
  return impl;
}

int MpiSession::finish(int exit_code) {
  std::unique_ptr<Impl>& impl = ended();
  if (!impl) return exit_code;
  if (impl->world.rank() == 0) {
    impl->exit_code = exit_code;
  } else if (exit_code == 0) {
    exit_code = impl->exit_code;
  }
  impl.reset();
  return exit_code;
}

int MpiSession::rank() const { return impl_->world.rank(); }
int MpiSession::size() const { return impl_->world.size(); }

namespace {

// The runs of a case: options.only_runs, else 0 .. runs - 1.
std::vector<std::uint64_t> runs_to_do(const Scenario& sc, const CampaignOptions& options) {
  std::vector<std::uint64_t> todo;
  if (options.only_runs) {
    todo = *options.only_runs;
  } else {
    for (std::int64_t r = 0; r < sc.run.runs; ++r) todo.push_back(static_cast<std::uint64_t>(r));
  }
  return todo;
}

// Rank 0's side of one case: the runs are handed out to its local threads and to the worker
// ranks alike, their results delivered to options.on_run under one lock; the first error stops
// the rest and is kept to be rethrown.
class CaseRunner {
 public:
  CaseRunner(const Scenario& sc, std::size_t case_index, const CampaignOptions& options,
             boost::mpi::communicator& world, int threads)
      : sc_(sc),
        case_index_(case_index),
        options_(options),
        world_(world),
        todo_(runs_to_do(sc, options)),
        curves_(static_cast<std::size_t>(threads)) {}

  std::size_t runs() const { return todo_.size(); }
  std::uint64_t first_run() const { return todo_[0]; }
  std::size_t done() const { return done_.load(); }
  // The first error of any rank or thread, rethrown.
  void rethrow() const {
    if (error_) std::rethrow_exception(error_);
  }

  // One local thread: runs taken in turn until none is left, a stop or an error.
  void local() {
    ErrorCurve* curve = nullptr;
    if (sc_.run.error_curve) {
      curve = &curves_[slots_.fetch_add(1)];
      *curve = error_curve_of(sc_);
    }
    while (!stop_requested()) {
      const std::size_t i = next_.fetch_add(1);
      if (i >= todo_.size()) return;
      try {
        RunLinks links;
        std::string failure;  // a run whose network died (sim/run/campaign.h)
        RunMetrics m =
            campaign_run(sc_, todo_[i], options_.link_counters ? &links : nullptr, curve, failure);
        if (!failure.empty()) report_run_failure(todo_[i], failure);
        deliver(todo_[i], std::move(m), std::move(links));
      } catch (...) {
        fail(std::current_exception());
        return;
      }
    }
  }

  // The service: this thread alone talks MPI. Two runs outstanding per worker rank, so a
  // worker never waits for its next run; polled, so that waiting costs no core.
  void serve_workers() {
    for (int w = 1; w < world_.size(); ++w) {
      give(w);
      give(w);
    }
    while (outstanding_ > 0) {
      if (auto st = world_.iprobe(boost::mpi::any_source, boost::mpi::any_tag)) {
        std::string msg;
        world_.recv(st->source(), st->tag(), msg);
        --outstanding_;
        if (receive(st->source(), st->tag(), msg)) give(st->source());
      } else {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
    }
  }

  // [run] error_curve: the local threads' curves, then each worker rank's of this case (kCurve),
  // so the result covers exactly the runs delivered.
  void collect_curves(ErrorCurve& into) {
    for (ErrorCurve& c : curves_) into.merge(std::move(c));
    for (int w = 1; w < world_.size(); ++w) {
      world_.send(w, kCurve, static_cast<std::uint64_t>(case_index_));
      std::string blob;
      world_.recv(w, kCurve, blob);
      if (!blob.empty()) into.merge(ErrorCurve::deserialize(blob));
    }
  }

 private:
  bool stop_requested() const {
    return (options_.stop != nullptr && options_.stop->load() != 0) || failed_.load();
  }

  void deliver(std::uint64_t run, RunMetrics&& m, RunLinks&& links) {
    std::lock_guard<std::mutex> lock(sink_mutex_);
    options_.on_run(run, std::move(m), std::move(links));
    done_.fetch_add(1);
    if (options_.progress != nullptr)
      options_.progress->add_done();  // rank 0 reports (sim/run/progress.h)
  }

  // Keeps the first error and stops every thread and rank.
  void fail(std::exception_ptr e) {
    std::lock_guard<std::mutex> lock(error_mutex_);
    if (!error_) error_ = std::move(e);
    failed_ = true;
  }

  // Sends worker rank w the next run, unless stopped or none is left.
  void give(int w) {
    if (stop_requested()) return;
    const std::size_t i = next_.fetch_add(1);
    if (i >= todo_.size()) return;
    world_.send(
        w, kWork,
        std::vector<std::uint64_t>{case_index_, todo_[i], options_.link_counters ? 1u : 0u});
    ++outstanding_;
  }

  // A worker's message: its result delivered (true), or its error or a malformed result kept
  // (false: the worker gets no more runs).
  bool receive(int source, int tag, const std::string& msg) {
    if (tag == kError) {
      fail(
          std::make_exception_ptr(std::runtime_error(fmt::format("MPI rank {}: {}", source, msg))));
      return false;
    }
    if (tag == kFailure && msg.size() >= 16) {
      report_run_failure(kernel::get_u64(msg.data() + 8), msg.substr(16));
      deliver(kernel::get_u64(msg.data() + 8), failed_run_metrics(sc_), RunLinks{});
      return true;
    }
    try {
      if (msg.size() < 24 || kernel::get_u64(msg.data() + 16) > msg.size() - 24)
        throw std::runtime_error("malformed result message");
      const auto n_metrics = static_cast<std::size_t>(kernel::get_u64(msg.data() + 16));
      const std::string links = msg.substr(24 + n_metrics);
      deliver(kernel::get_u64(msg.data() + 8), deserialize_run(msg.substr(24, n_metrics)),
              links.empty() ? RunLinks{} : deserialize_links(links));
    } catch (const std::exception& e) {
      fail(std::make_exception_ptr(
          std::runtime_error(fmt::format("MPI rank {}: {}", source, e.what()))));
      return false;
    }
    return true;
  }

  const Scenario& sc_;
  std::size_t case_index_;
  const CampaignOptions& options_;
  boost::mpi::communicator& world_;
  std::vector<std::uint64_t> todo_;
  std::atomic<std::size_t> next_{0}, done_{0};
  std::mutex sink_mutex_, error_mutex_;
  std::exception_ptr error_;
  std::atomic<bool> failed_{false};
  std::vector<ErrorCurve> curves_;  // [run] error_curve: one per local thread
  std::atomic<std::size_t> slots_{0};
  int outstanding_ = 0;  // runs sent to worker ranks and not yet answered
};

}  // namespace

CampaignResult MpiSession::run(const Scenario& sc, std::size_t case_index,
                               const CampaignOptions& options) {
  CampaignResult result;
  const int threads = std::max(1, options.threads);
  result.threads = threads;
  const auto start = std::chrono::steady_clock::now();
  CaseRunner runner(sc, case_index, options, impl_->world, threads);
  const std::size_t n = runner.runs();
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back([&runner] { runner.local(); });
  runner.serve_workers();
  for (auto& t : pool) t.join();
  runner.rethrow();
  if (sc.run.error_curve) runner.collect_curves(result.curve);
  result.runs_done = runner.done();
  result.stopped = result.runs_done < n;
  result.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.ns_per_period.assign(sc.estimators.size(), std::nan(""));
  if (options.time_estimators && !result.stopped && n > 0) {
    std::string failure;
    ReplayLog log;
    campaign_run(sc, runner.first_run(), nullptr, nullptr, failure, nullptr, &log);
    if (failure.empty())
      result.ns_per_period = time_estimators(sc, log, std::chrono::milliseconds(200));
  }
  return result;
}

void MpiSession::serve(const std::vector<const Scenario*>& cases) {
  auto& world = impl_->world;
  std::map<std::uint64_t, ErrorCurve>
      curves;  // per case: the runs of this rank ([run] error_curve)
  while (true) {
    auto st = world.iprobe(0, boost::mpi::any_tag);
    if (!st) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      continue;
    }
    if (st->tag() == kStop) {
      world.recv(0, kStop, impl_->exit_code);
      return;
    }
    if (st->tag() == kCurve) {
      std::uint64_t c = 0;
      world.recv(0, kCurve, c);
      const auto it = curves.find(c);
      world.send(0, kCurve, it == curves.end() ? std::string() : it->second.serialize());
      if (it != curves.end()) curves.erase(it);
      continue;
    }
    std::vector<std::uint64_t> work;
    world.recv(0, kWork, work);
    try {
      if (work.size() != 3 || work[0] >= cases.size())
        throw std::runtime_error("malformed work message");
      RunLinks links;
      const Scenario& sc = *cases[work[0]];
      ErrorCurve* curve = nullptr;
      if (sc.run.error_curve) {
        auto [it, fresh] = curves.try_emplace(work[0]);
        if (fresh) it->second = error_curve_of(sc);
        curve = &it->second;
      }
      std::string failure;  // a run whose network died (sim/run/campaign.h): rank 0 reports it
      RunMetrics m = campaign_run(sc, work[1], work[2] != 0 ? &links : nullptr, curve, failure);
      if (!failure.empty()) {
        std::string msg;
        put_u64(msg, work[0]);
        put_u64(msg, work[1]);
        world.send(0, kFailure, msg + failure);
        continue;
      }
      std::string msg;
      put_u64(msg, work[0]);
      put_u64(msg, work[1]);
      const std::string metrics = serialize_run(m);
      put_u64(msg, metrics.size());
      msg += metrics;
      if (work[2] != 0) msg += serialize_links(links);
      world.send(0, kResult, msg);
    } catch (const std::exception& e) {
      world.send(0, kError, std::string(e.what()));
    }
  }
}

#else  // no MPI support in this build

bool mpi_available() { return false; }
struct MpiSession::Impl {};
MpiSession::MpiSession() {
  throw std::runtime_error("this ncosim was built without MPI support (CMake option NCOSIM_MPI)");
}
MpiSession::~MpiSession() = default;
std::unique_ptr<MpiSession::Impl>& MpiSession::ended() {
  static std::unique_ptr<Impl> impl;
  return impl;
}
int MpiSession::finish(int exit_code) { return exit_code; }
int MpiSession::rank() const { return 0; }
int MpiSession::size() const { return 1; }
CampaignResult MpiSession::run(const Scenario&, std::size_t, const CampaignOptions&) { return {}; }
void MpiSession::serve(const std::vector<const Scenario*>&) {}

#endif

int mpi_finish(int exit_code) { return MpiSession::finish(exit_code); }

CampaignResult run_case(const Scenario& sc, std::size_t case_index, const CampaignOptions& options,
                        MpiSession* mpi) {
  return mpi != nullptr ? mpi->run(sc, case_index, options) : run_campaign(sc, options);
}

}  // namespace ncosim::sim

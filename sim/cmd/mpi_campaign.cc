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

void put_u64(std::string& s, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
std::uint64_t get_u64(const std::string& s, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i)
    v |= static_cast<std::uint64_t>(static_cast<unsigned char>(s[at + i])) << (8 * i);
  return v;
}

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

CampaignResult MpiSession::run(const Scenario& sc, std::size_t case_index,
                               const CampaignOptions& options) {
  auto& world = impl_->world;
  CampaignResult result;
  std::vector<std::uint64_t> todo;
  if (options.only_runs) {
    todo = *options.only_runs;
  } else {
    for (std::int64_t r = 0; r < sc.run.runs; ++r) todo.push_back(static_cast<std::uint64_t>(r));
  }
  const std::size_t n = todo.size();
  const int threads = std::max(1, options.threads);
  result.threads = threads;
  const auto start = std::chrono::steady_clock::now();
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex sink_mutex, error_mutex;
  std::exception_ptr error;
  std::atomic<bool> failed{false};
  auto stop_requested = [&] {
    return (options.stop != nullptr && options.stop->load() != 0) || failed.load();
  };
  auto deliver = [&](std::uint64_t run, RunMetrics&& m, RunLinks&& links) {
    std::lock_guard<std::mutex> lock(sink_mutex);
    options.on_run(run, std::move(m), std::move(links));
    done.fetch_add(1);
    if (options.progress != nullptr)
      options.progress->add_done();  // rank 0 reports (sim/run/progress.h)
  };
  // [run] error_curve: one curve per local thread; the worker ranks' curves are collected after
  // the case (kCurve), so the result covers exactly the runs delivered.
  std::vector<ErrorCurve> curves(static_cast<std::size_t>(threads));
  std::atomic<std::size_t> slots{0};
  auto local = [&] {
    ErrorCurve* curve = nullptr;
    if (sc.run.error_curve) {
      curve = &curves[slots.fetch_add(1)];
      *curve = error_curve_of(sc);
    }
    while (!stop_requested()) {
      const std::size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        RunLinks links;
        RunMetrics m = simulate_run(sc, todo[i], nullptr, nullptr,
                                    options.link_counters ? &links : nullptr, curve);
        deliver(todo[i], std::move(m), std::move(links));
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
        return;
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(local);
  // The service: this thread alone talks MPI. Two runs outstanding per worker rank, so a
  // worker never waits for its next run; polled, so that waiting costs no core.
  int outstanding = 0;
  auto give = [&](int w) {
    if (stop_requested()) return;
    const std::size_t i = next.fetch_add(1);
    if (i >= n) return;
    world.send(w, kWork,
               std::vector<std::uint64_t>{case_index, todo[i], options.link_counters ? 1u : 0u});
    ++outstanding;
  };
  for (int w = 1; w < world.size(); ++w) {
    give(w);
    give(w);
  }
  while (outstanding > 0) {
    if (auto st = world.iprobe(boost::mpi::any_source, boost::mpi::any_tag)) {
      std::string msg;
      world.recv(st->source(), st->tag(), msg);
      --outstanding;
      if (st->tag() == kError) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error)
          error = std::make_exception_ptr(
              std::runtime_error(fmt::format("MPI rank {}: {}", st->source(), msg)));
        failed = true;
        continue;
      }
      try {
        if (msg.size() < 24 || get_u64(msg, 16) > msg.size() - 24)
          throw std::runtime_error("malformed result message");
        const auto n_metrics = static_cast<std::size_t>(get_u64(msg, 16));
        const std::string links = msg.substr(24 + n_metrics);
        deliver(get_u64(msg, 8), deserialize_run(msg.substr(24, n_metrics)),
                links.empty() ? RunLinks{} : deserialize_links(links));
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error)
          error = std::make_exception_ptr(
              std::runtime_error(fmt::format("MPI rank {}: {}", st->source(), e.what())));
        failed = true;
        continue;
      }
      give(st->source());
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  if (sc.run.error_curve) {
    for (ErrorCurve& c : curves) result.curve.merge(std::move(c));
    for (int w = 1; w < world.size(); ++w) {
      world.send(w, kCurve, static_cast<std::uint64_t>(case_index));
      std::string blob;
      world.recv(w, kCurve, blob);
      if (!blob.empty()) result.curve.merge(ErrorCurve::deserialize(blob));
    }
  }
  result.runs_done = done.load();
  result.stopped = result.runs_done < n;
  result.wall_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.ns_per_period.assign(sc.estimators.size(), std::nan(""));
  if (options.time_estimators && !result.stopped && n > 0)
    simulate_run(sc, todo[0], nullptr, &result.ns_per_period);
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
      const RunMetrics m =
          simulate_run(sc, work[1], nullptr, nullptr, work[2] != 0 ? &links : nullptr, curve);
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

}  // namespace ncosim::sim

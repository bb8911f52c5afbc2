// sim/cmd/store_sink.h — a campaign's stop and its commits: the stop flag (set by SIGINT/SIGTERM
// or a failing store writer), the signal handlers installed for a campaign, and the writer thread
// that commits completed runs to the run store in batches.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "sim/run/run_results.h"
#include "sim/store/store.h"

namespace ncosim::sim {

// Set by SIGINT/SIGTERM (the signal number) or by a failing store writer (-1): no new run starts.
extern std::atomic<int> g_stop;

// SIGINT/SIGTERM handlers for the duration of a campaign; the first signal restores the
// default action (SA_RESETHAND), so a second one ends the process at once. With
// `second_aborts` false (an embedding interpreter, whose end would lose the user's session) every
// signal only stops the campaign.
class StopSignals {
 public:
  explicit StopSignals(bool second_aborts = true);
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

// "SIGINT", "SIGTERM" or "signal N".
std::string signal_name(int sig);

// Commits completed runs from a writer thread: every 250 ms, one transaction for all runs
// completed since the last commit. The store is used by one thread at a time (`with_store`).
class StoreSink {
 public:
  explicit StoreSink(RunStore& store)
      : store_(store), interval_(commit_interval()), thread_([this] { loop(); }) {}
  ~StoreSink() {
    try {
      finish();
    } catch (...) {  // reported by the explicit finish() of a normal exit
    }
  }
  StoreSink(const StoreSink&) = delete;
  StoreSink& operator=(const StoreSink&) = delete;

  void push(std::size_t case_index, std::uint64_t run, RunMetrics&& m, RunLinks&& links) {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_.push_back(StoredRun{case_index, run, std::move(m), std::move(links)});
  }
  // Commits everything pushed so far; rethrows a writer failure.
  void flush() {
    commit_pending();
    rethrow();
  }
  template <class F>
  void with_store(F f) {
    std::lock_guard<std::mutex> lock(db_mutex_);
    f(store_);
  }
  void finish() {
    if (thread_.joinable()) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done_ = true;
      }
      cv_.notify_all();
      thread_.join();
    }
    flush();
  }

 private:
  void loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!done_) {
      cv_.wait_for(lock, interval_, [&] { return done_; });
      lock.unlock();
      commit_pending();
      lock.lock();
    }
  }
  void commit_pending() {
    std::lock_guard<std::mutex> db(db_mutex_);
    std::vector<StoredRun> batch;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      batch.swap(pending_);
    }
    if (batch.empty() || error_) return;
    try {
      store_.put_runs(batch);
    } catch (...) {
      error_ = std::current_exception();
      int expected = 0;
      g_stop.compare_exchange_strong(expected, -1);
    }
  }
  void rethrow() {
    std::lock_guard<std::mutex> db(db_mutex_);
    if (error_) std::rethrow_exception(error_);
  }

  // 250 ms; NCOSIM_TEST_COMMIT_MS (tests only: 1..1000) shortens it so that a kill test finds
  // committed batches inside a short campaign on a fast machine.
  static std::chrono::milliseconds commit_interval() {
    if (const char* v = std::getenv("NCOSIM_TEST_COMMIT_MS")) {
      char* end = nullptr;
      const long ms = std::strtol(v, &end, 10);
      if (end != v && *end == '\0' && ms >= 1 && ms <= 1000) return std::chrono::milliseconds(ms);
    }
    return std::chrono::milliseconds(250);
  }

  RunStore& store_;
  std::chrono::milliseconds interval_;
  std::mutex mutex_, db_mutex_;
  std::condition_variable cv_;
  std::vector<StoredRun> pending_;
  bool done_ = false;
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace ncosim::sim

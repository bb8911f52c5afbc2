// sim/run/progress.h — the progress of a whole `ncosim run` campaign on stderr (issue 28, part 2):
// one line format, redrawn in place on a terminal and written as a new line in logs (stderr not
// a terminal: CI, batch jobs), over every case of the campaign, never restarted per case.
//
//   ncosim: case 2/3, 27/60 runs (24 stored before), 5.31 runs/s, elapsed 5s, ETA 6s
//
// The session (sim/cmd/batch.cc) owns it and hands it to run_campaign / MpiSession::run through
// CampaignOptions::progress; they count each completed run (add_done, from any thread). The
// clock and the writer are injected so that the timing is testable without sleeping.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace ncosim::sim {

// "5s", "1m05s", "2h03m"; "?" for a negative or non-finite duration.
std::string format_duration(double seconds);

class CampaignProgress {
 public:
  // observer: no text; the observer gets a Snapshot at every poll and at finish() (an embedding
  // program draws its own progress: the Python module's tqdm bar, python/).
  enum class Mode { off, terminal, log, observer };
  using Clock = std::function<double()>;                   // seconds, monotonic
  using Writer = std::function<void(const std::string&)>;  // writes the text as is
  struct Snapshot {
    std::uint64_t done = 0;   // runs done, stored ones included
    std::uint64_t total = 0;  // of the campaign (an upper bound with --target-ci)
    std::uint64_t stored = 0;
    bool upper_bound = false;
    std::size_t case_index = 0, cases = 1;
    bool final = false;  // the last call, from finish()
  };
  using Observer = std::function<void(const Snapshot&)>;

  // A terminal line is redrawn every kTerminalSeconds; a log gets its first line kLogFirstSeconds
  // after the start (so that a short campaign shows one too) and then one every kLogSeconds.
  static constexpr double kTerminalSeconds = 0.2;
  static constexpr double kLogFirstSeconds = 2.0;
  static constexpr double kLogSeconds = 5.0;

  // Defaults: std::chrono::steady_clock and stderr (flushed).
  explicit CampaignProgress(Mode mode, Clock clock = {}, Writer writer = {});
  // Mode::observer, with its observer (called from the progress thread, then from finish()).
  explicit CampaignProgress(Observer observer);
  ~CampaignProgress();  // finish()
  CampaignProgress(const CampaignProgress&) = delete;
  CampaignProgress& operator=(const CampaignProgress&) = delete;

  // The campaign's runs over all cases (with --target-ci: the upper bound, --max-runs per case)
  // and how many of them the run store already held at the start (--resume): counted as done.
  void set_total(std::uint64_t total, std::uint64_t stored, bool upper_bound);
  // The case being simulated (index from 0, of `cases`); `batch` names a --target-ci batch ("").
  void set_case(std::size_t index, std::size_t cases, const std::string& batch = "");
  void add_done(std::uint64_t runs = 1);  // thread-safe

  Snapshot snapshot() const;
  // The one line (no "\r", no newline) at time `now` of the clock.
  std::string line(double now) const;
  // What to write at `now`: the redrawn line (terminal), a new line when one is due (log), or "".
  std::string poll(double now);

  void start();   // a thread that polls every kTerminalSeconds until finish(); not in Mode::off
  void finish();  // stops the thread; on a terminal the last state stays, ended by a newline

  bool on() const { return mode_ != Mode::off; }

 private:
  void loop();

  const Mode mode_;
  Clock clock_;
  Writer writer_;
  Observer observer_;
  double start_ = 0.0;
  double next_log_ = 0.0;
  std::size_t drawn_ = 0;  // length of the line on the terminal (to blank a longer one)
  std::atomic<std::uint64_t> done_{0};
  mutable std::mutex state_mutex_;  // total, stored, case
  std::uint64_t total_ = 0, stored_ = 0;
  bool upper_bound_ = false;
  std::size_t case_ = 0, cases_ = 1;
  std::string batch_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool finished_ = false;
  std::thread thread_;
};

}  // namespace ncosim::sim

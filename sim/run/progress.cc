// sim/run/progress.cc — the campaign's progress line (see progress.h).
#include "sim/run/progress.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdio>

namespace ncosim::sim {

std::string format_duration(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const auto t = static_cast<long>(s + 0.5);
  if (t >= 3600) return fmt::format("{}h{:02}m", t / 3600, (t / 60) % 60);
  if (t >= 60) return fmt::format("{}m{:02}s", t / 60, t % 60);
  return fmt::format("{}s", t);
}

namespace {

// Three significant digits at most, never an exponent (a rate of 0.004 or of 12000 runs/s).
std::string format_rate(double r) {
  if (r >= 100.0) return fmt::format("{:.0f}", r);
  if (r >= 10.0) return fmt::format("{:.1f}", r);
  return fmt::format("{:.2f}", r);
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void write_stderr(const std::string& text) {
  std::fputs(text.c_str(), stderr);
  std::fflush(stderr);
}

}  // namespace

CampaignProgress::CampaignProgress(Mode mode, Clock clock, Writer writer)
    : mode_(mode),
      clock_(clock ? std::move(clock) : Clock(steady_seconds)),
      writer_(writer ? std::move(writer) : Writer(write_stderr)) {
  start_ = clock_();
  next_log_ = start_ + kLogFirstSeconds;
}

CampaignProgress::CampaignProgress(Observer observer)
    : CampaignProgress(Mode::observer, {}, [](const std::string&) {}) {
  observer_ = std::move(observer);
}

CampaignProgress::~CampaignProgress() { finish(); }

CampaignProgress::Snapshot CampaignProgress::snapshot() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  Snapshot s;
  s.stored = stored_;
  s.done = stored_ + done_.load();
  s.total = total_;
  s.upper_bound = upper_bound_;
  s.case_index = case_;
  s.cases = cases_;
  return s;
}

void CampaignProgress::set_total(std::uint64_t total, std::uint64_t stored, bool upper_bound) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  total_ = total;
  stored_ = stored;
  upper_bound_ = upper_bound;
}

void CampaignProgress::set_case(std::size_t index, std::size_t cases, const std::string& batch) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  case_ = index;
  cases_ = cases;
  batch_ = batch;
}

void CampaignProgress::add_done(std::uint64_t runs) { done_.fetch_add(runs); }

std::string CampaignProgress::line(double now) const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  const std::uint64_t simulated = done_.load();
  const std::uint64_t done = stored_ + simulated;
  const double elapsed = now - start_;
  // The rate and the ETA count the runs simulated in this session only (stored ones are free).
  const double rate = elapsed > 0.0 ? static_cast<double>(simulated) / elapsed : 0.0;
  const std::uint64_t left = total_ > done ? total_ - done : 0;
  const std::string eta =
      simulated > 0 && rate > 0.0 ? format_duration(static_cast<double>(left) / rate) : "?";
  std::string where;
  if (cases_ > 1) where = fmt::format("case {}/{}", case_ + 1, cases_);
  if (!batch_.empty()) where += where.empty() ? batch_ : fmt::format(" ({})", batch_);
  if (!where.empty()) where += ", ";
  const std::string runs = upper_bound_
                               ? fmt::format("{} of at most {} runs (--target-ci)", done, total_)
                               : fmt::format("{}/{} runs", done, total_);
  return fmt::format("ncosim: {}{}{}, {} runs/s, elapsed {}, ETA {}{}", where, runs,
                     stored_ > 0 ? fmt::format(" ({} stored before)", stored_) : "",
                     format_rate(rate), format_duration(elapsed), upper_bound_ ? "at most " : "",
                     eta);
}

std::string CampaignProgress::poll(double now) {
  switch (mode_) {
    case Mode::off:
    case Mode::observer:
      return "";
    case Mode::terminal: {
      const std::string text = line(now);
      // Blank what is left of a longer line drawn before.
      const std::string pad(drawn_ > text.size() ? drawn_ - text.size() : 0, ' ');
      drawn_ = text.size();
      return "\r" + text + pad;
    }
    case Mode::log:
      if (now < next_log_) return "";
      // The next on the 5 s grid from the start: a late wake-up does not shift the lines after it.
      next_log_ = start_ + kLogSeconds * (std::floor((now - start_) / kLogSeconds) + 1.0);
      return line(now) + "\n";
  }
  return "";
}

void CampaignProgress::start() {
  if (mode_ == Mode::off || thread_.joinable()) return;
  thread_ = std::thread([this] { loop(); });
}

void CampaignProgress::loop() {
  const auto interval = std::chrono::duration<double>(kTerminalSeconds);
  std::unique_lock<std::mutex> lock(mutex_);
  while (!cv_.wait_for(lock, interval, [&] { return finished_; })) {
    if (observer_) {
      lock.unlock();  // the observer may take its time (a Python callback waits for the GIL)
      observer_(snapshot());
      lock.lock();
      continue;
    }
    const std::string text = poll(clock_());
    if (!text.empty()) writer_(text);
  }
}

void CampaignProgress::finish() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = true;
  }
  cv_.notify_all();
  thread_.join();
  if (mode_ == Mode::terminal) writer_(poll(clock_()) + "\n");
  if (observer_) {
    Snapshot last = snapshot();
    last.final = true;
    observer_(last);
  }
}

}  // namespace ncosim::sim

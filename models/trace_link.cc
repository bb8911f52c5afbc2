// models/trace_link.cc — the replayed trace link of models/link.h and the trace reader.
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <string_view>

#include "config/config.h"  // escape_text
#include "kernel/check.h"
#include "models/link.h"

namespace ncosim::models {

// ---------------------------------------------------------------------------------------
// TraceLink

TraceLink::TraceLink(std::vector<std::optional<std::int64_t>> delays, std::size_t segment)
    : delays_(std::move(delays)), segment_(segment) {
  for (const auto& d : delays_) NCOSIM_CHECK(!d || *d >= 0);
  NCOSIM_CHECK(segment_ <= delays_.size());
}

std::unique_ptr<Link> TraceLink::clone() const {
  auto copy = std::make_unique<TraceLink>(*this);
  copy->start_ = 0;
  copy->next_ = 0;
  return copy;
}

void TraceLink::bind_run(const MobilityRun* mobility, std::uint64_t seed, std::uint64_t run) {
  (void)mobility, (void)seed;
  start_ =
      segment_ > 0 ? static_cast<std::size_t>(run % (delays_.size() / segment_)) * segment_ : 0;
}

void TraceLink::reset(kernel::Rng& rng) {
  (void)rng;
  next_ = start_;
}

std::int64_t TraceLink::transmit(kernel::Rng& rng) {
  (void)rng;
  NCOSIM_CHECK(next_ < (segment_ > 0 ? start_ + segment_ : delays_.size()));
  const auto& d = delays_[next_++];
  return d ? *d : kLost;
}

std::vector<double> TraceLink::delay_pmf(int max_delay) const {
  NCOSIM_CHECK(max_delay >= 0);
  std::vector<double> out(static_cast<std::size_t>(max_delay) + 1, 0.0);
  if (delays_.empty()) return out;
  for (const auto& d : delays_) {
    if (d && *d <= max_delay) out[static_cast<std::size_t>(*d)] += 1.0;
  }
  for (double& p : out) p /= static_cast<double>(delays_.size());
  return out;
}

double TraceLink::loss_probability() const {
  if (delays_.empty()) return 1.0;  // carries no packet: nothing is ever delivered
  const auto lost =
      std::count_if(delays_.begin(), delays_.end(), [](const auto& d) { return !d.has_value(); });
  return static_cast<double>(lost) / static_cast<double>(delays_.size());
}

std::optional<double> TraceLink::mean_loss_burst(std::optional<int> gap) const {
  if (!gap) return std::nullopt;
  std::int64_t runs = 0, lost = 0;
  bool in_run = false;
  for (const auto& d : delays_) {
    if (!d) {
      ++lost;
      if (!in_run) ++runs;
    }
    in_run = !d;
  }
  if (runs == 0) return std::nullopt;
  return static_cast<double>(lost) / static_cast<double>(runs);
}

// ---------------------------------------------------------------------------------------
// load_trace

namespace {

std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

// A whole field holding a non-negative decimal integer (no sign, no fraction).
std::optional<std::int64_t> parse_count(std::string_view field) {
  field = trim(field);
  if (field.empty()) return std::nullopt;
  std::int64_t value = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || end != field.data() + field.size() || value < 0) return std::nullopt;
  return value;
}

}  // namespace

namespace {

// Input limits of a trace (models/link.h load_trace; documented in scenarios/README.md).
constexpr std::int64_t kMaxTraceBytes = 1'000'000'000;
constexpr std::size_t kMaxTraceLineBytes = 4096;
constexpr std::int64_t kMaxTracePackets = 50'000'000;

// Lines of a regular file read through a bounded buffer (a line longer than the limit is an
// error at its line, never an allocation of the whole file).
class TraceReader {
 public:
  explicit TraceReader(const std::string& path) : path_(path) {
    fd_ =
        ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);  // a FIFO must not block the open
    if (fd_ < 0)
      throw TraceError(path, 0, "cannot open trace file '" + path + "': " + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
      const char* what = S_ISFIFO(st.st_mode)   ? "a FIFO"
                         : S_ISCHR(st.st_mode)  ? "a character device"
                         : S_ISBLK(st.st_mode)  ? "a block device"
                         : S_ISDIR(st.st_mode)  ? "a folder"
                         : S_ISSOCK(st.st_mode) ? "a socket"
                                                : "not a regular file";
      ::close(fd_);
      fd_ = -1;
      throw TraceError(path, 0,
                       "expected a regular file, got " + std::string(what) + " '" + path + "'");
    }
    if (st.st_size > kMaxTraceBytes) {
      ::close(fd_);
      fd_ = -1;
      throw TraceError(path, 0,
                       "trace file '" + path + "' holds " + std::to_string(st.st_size) +
                           " bytes; at most " + std::to_string(kMaxTraceBytes) + " are read");
    }
    // O_NONBLOCK stays: a "regular" file that blocks on read (/proc/kmsg) is refused, not waited
    // on.
  }
  ~TraceReader() {
    if (fd_ >= 0) ::close(fd_);
  }
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  // The next line (without its '\n') into `line`; false at the end of the file.
  bool next(std::string& line, int line_number) {
    line.clear();
    while (true) {
      if (pos_ == len_) {
        if (eof_) return !line.empty();
        const ssize_t n = ::read(fd_, buf_, sizeof buf_);
        if (n < 0) {
          if (errno == EINTR) continue;
          if (errno == EAGAIN || errno == EWOULDBLOCK) {
            throw TraceError(path_, 0,
                             "cannot read trace file '" + path_ +
                                 "' without waiting (a file whose content comes and goes, not a "
                                 "recorded trace)");
          }
          throw TraceError(path_, line_number,
                           "cannot read trace file '" + path_ + "': " + std::strerror(errno));
        }
        if (n == 0) {
          eof_ = true;
          return !line.empty();
        }
        pos_ = 0;
        len_ = static_cast<std::size_t>(n);
        total_ += n;
        if (total_ > kMaxTraceBytes) {
          throw TraceError(path_, line_number,
                           "trace file '" + path_ + "' grew beyond " +
                               std::to_string(kMaxTraceBytes) + " bytes while it was read");
        }
      }
      const char* start = buf_ + pos_;
      const void* nl = std::memchr(start, '\n', len_ - pos_);
      const std::size_t take =
          nl ? static_cast<std::size_t>(static_cast<const char*>(nl) - start) : len_ - pos_;
      if (line.size() + take > kMaxTraceLineBytes) {
        throw TraceError(path_, line_number,
                         "line longer than " + std::to_string(kMaxTraceLineBytes) + " bytes");
      }
      line.append(start, take);
      pos_ += take;
      if (nl) {
        ++pos_;
        return true;
      }
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
  char buf_[65536];
  std::size_t pos_ = 0, len_ = 0;
  std::int64_t total_ = 0;
  bool eof_ = false;
};

}  // namespace

TraceError::TraceError(std::string f, int l, const std::string& what)
    : std::runtime_error(config::escape_text(what)), file(std::move(f)), line(l) {}

std::vector<std::optional<std::int64_t>> load_trace(const std::string& path, int* first_row_line) {
  TraceReader in(path);
  if (first_row_line != nullptr) *first_row_line = 1;

  std::vector<std::optional<std::int64_t>> delays;
  std::string raw;
  int line = 0;
  int first_blank = 0;  // first blank line seen; only trailing blank lines are allowed
  while (in.next(raw, line + 1)) {
    ++line;
    if (static_cast<std::int64_t>(delays.size()) >= kMaxTracePackets) {
      throw TraceError(
          path, line,
          "more than " + std::to_string(kMaxTracePackets) + " packets (the limit of a trace)");
    }
    std::string_view text = raw;
    if (line == 1 && text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 BOM
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);           // CRLF
    if (trim(text).empty()) {
      if (first_blank == 0) first_blank = line;
      continue;
    }
    if (first_blank != 0) {
      throw TraceError(path, first_blank,
                       "blank line inside the trace (only trailing blank lines are allowed)");
    }
    const std::size_t comma = text.find(',');
    const std::size_t columns =
        1 + static_cast<std::size_t>(std::count(text.begin(), text.end(), ','));
    if (columns != 2) {
      throw TraceError(path, line,
                       "expected 'seq,delay' (2 columns), got " + std::to_string(columns) +
                           (columns == 1 ? " column" : " columns") + " in '" + std::string(text) +
                           "'");
    }
    const std::string_view seq_field = trim(text.substr(0, comma));
    const std::string_view delay_field = trim(text.substr(comma + 1));
    if (seq_field == "seq" && delay_field == "delay") {
      if (line == 1) continue;
      throw TraceError(path, line, "header 'seq,delay' is only allowed on the first line");
    }

    std::optional<std::int64_t> delay;
    if (!delay_field.empty()) {
      delay = parse_count(delay_field);
      if (!delay) {
        throw TraceError(path, line,
                         "expected 'seq,delay' with a non-negative integer delay, got '" +
                             std::string(text) + "'");
      }
    }
    const std::optional<std::int64_t> seq = parse_count(seq_field);
    const auto expected = static_cast<std::int64_t>(delays.size());
    if (!seq || *seq != expected) {
      throw TraceError(path, line,
                       "expected 'seq,delay' with seq " + std::to_string(expected) +
                           " (consecutive from 0), got '" + std::string(text) + "'");
    }
    if (delays.empty() && first_row_line != nullptr) *first_row_line = line;
    delays.push_back(delay);
  }
  return delays;
}

}  // namespace ncosim::models

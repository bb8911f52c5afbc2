// config/input_files.cc — the external files a scenario reads (see input_files.h).
#include "config/input_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <filesystem>

namespace ncosim::config {

namespace {

thread_local InputFiles* t_recorder = nullptr;
thread_local std::string t_dir;  // the recording scenario's folder, absolute and normal

constexpr std::uint64_t kFnvBasis = 0xcbf29ce484222325ULL;  // FNV-1a 64: offset basis

std::uint64_t fnv1a(std::uint64_t h, const char* p, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(p[i]);
    h *= 1099511628211ULL;
  }
  return h;
}

std::string hex(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

}  // namespace

InputFileRecorder::InputFileRecorder(InputFiles& files, const std::string& scenario_dir)
    : previous_(t_recorder), previous_dir_(t_dir) {
  t_recorder = &files;
  std::error_code ec;
  const auto abs = std::filesystem::absolute(scenario_dir.empty() ? "." : scenario_dir, ec);
  t_dir = (ec ? std::filesystem::path(scenario_dir) : abs).lexically_normal().string();
}

InputFileRecorder::~InputFileRecorder() {
  t_recorder = previous_;
  t_dir = previous_dir_;
}

std::string content_hash(const std::string& bytes) {
  return hex(fnv1a(kFnvBasis, bytes.data(), bytes.size()));
}

std::string file_content_hash(const std::string& path) {
  // O_NONBLOCK: a FIFO named by mistake must not block; only regular files are hashed.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errno == ENOENT ? "missing" : "unreadable";
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return "unreadable";
  }
  std::uint64_t h = kFnvBasis;  // streamed: memory does not grow with the file
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      ::close(fd);
      return "unreadable";
    }
    if (n == 0) break;
    h = fnv1a(h, buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return hex(h);
}

void note_input_file(const std::string& path) {
  if (t_recorder == nullptr) return;
  std::error_code ec;
  const auto abs = std::filesystem::absolute(path, ec).lexically_normal();
  const auto key = ec ? std::filesystem::path(path) : abs.lexically_relative(t_dir);
  (*t_recorder)[key.empty() ? path : key.generic_string()] = file_content_hash(path);
}

}  // namespace ncosim::config

// sim/files/output_set.cc — the atomic output set and the output-folder lock (see output_set.h).
//
// Why RENAME_EXCHANGE: a directory cannot be atomically replaced by rename(2) when the target is
// a non-empty directory, and replacing files one by one leaves mixed sets. renameat2(2) with
// RENAME_EXCHANGE swaps two paths in one atomic step (ext4, xfs, btrfs, tmpfs, overlayfs since
// Linux 3.15-4.x), so the live name always points at a complete set. Where the filesystem
// refuses it (EINVAL/ENOTSUP), the fallback moves the previous folder aside and renames the new
// one in; a kill between those two renames leaves no live folder, and the next writer renames the
// previous set back before it does anything else (so a reader after recovery again sees either
// set, never a mix).
#include "sim/files/output_set.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <stdio.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "config/config.h"

#ifndef RENAME_EXCHANGE
#define RENAME_EXCHANGE (1 << 1)
#endif
#ifndef RENAME_NOREPLACE
#define RENAME_NOREPLACE (1 << 0)
#endif

namespace ncosim::sim {

namespace fs = std::filesystem;

namespace {

struct HeldLock {
  int fd = -1;
  int count = 0;
};

std::mutex& lock_mutex() {
  static std::mutex m;
  return m;
}

std::map<std::string, HeldLock>& held_locks() {
  static std::map<std::string, HeldLock> m;
  return m;
}

std::string errno_text(int e) { return std::strerror(e); }

// Test hook: SIGKILL just before step NCOSIM_TEST_KILL_AT; NCOSIM_TEST_OUTPUT_STEPS=1 lists them.
class Steps {
 public:
  Steps() {
    if (const char* k = std::getenv("NCOSIM_TEST_KILL_AT")) kill_at_ = std::atol(k);
    const char* s = std::getenv("NCOSIM_TEST_OUTPUT_STEPS");
    print_ = s != nullptr && std::string(s) == "1";
  }
  void operator()(const std::string& what) {
    ++count_;
    if (print_) std::cerr << fmt::format("ncosim: output step {}: {}\n", count_, what);
    if (kill_at_ == count_) ::raise(SIGKILL);
  }

 private:
  long kill_at_ = 0;
  long count_ = 0;
  bool print_ = false;
};

int rename2(const fs::path& from, const fs::path& to, unsigned flags) {
  return static_cast<int>(
      ::syscall(SYS_renameat2, AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), flags));
}

void fsync_path(const fs::path& p, bool directory) {
  const int fd = ::open(p.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0)
    throw std::runtime_error(
        fmt::format("cannot open '{}' to sync it: {}", p.string(), errno_text(errno)));
  const int rc = ::fsync(fd);
  const int e = errno;
  ::close(fd);
  // Some filesystems do not sync directories (EINVAL): nothing more can be done there.
  if (rc != 0 && !(directory && (e == EINVAL || e == EROFS))) {
    throw std::runtime_error(fmt::format("cannot sync '{}': {}", p.string(), errno_text(e)));
  }
}

void write_file(const fs::path& p, const std::string& content, Steps& step,
                const std::string& name) {
  step("write " + name);
  const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0)
    throw std::runtime_error(fmt::format("cannot write '{}': {}", p.string(), errno_text(errno)));
  std::size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd);
      throw std::runtime_error(fmt::format("cannot write '{}': {}", p.string(), errno_text(e)));
    }
    done += static_cast<std::size_t>(n);
  }
  step("fsync " + name);
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    throw std::runtime_error(fmt::format("cannot sync '{}': {}", p.string(), errno_text(e)));
  }
  if (::close(fd) != 0)
    throw std::runtime_error(fmt::format("cannot write '{}': {}", p.string(), errno_text(errno)));
}

// Carries `src` (file, symlink or folder) over to `dst`: hard links, so an open database keeps
// writing to the same inode; a copy where the filesystem has no hard links.
void carry_over(const fs::path& src, const fs::path& dst) {
  std::error_code ec;
  const auto st = fs::symlink_status(src, ec);
  if (ec) throw std::runtime_error(fmt::format("cannot read '{}': {}", src.string(), ec.message()));
  if (fs::is_directory(st)) {
    fs::create_directory(dst, ec);
    if (ec)
      throw std::runtime_error(fmt::format("cannot create '{}': {}", dst.string(), ec.message()));
    for (const auto& e : fs::directory_iterator(src))
      carry_over(e.path(), dst / e.path().filename());
    return;
  }
  if (::linkat(AT_FDCWD, src.c_str(), AT_FDCWD, dst.c_str(), 0) == 0) return;
  const int e = errno;
  if (e != EPERM && e != EXDEV && e != EMLINK && e != ENOTSUP) {
    throw std::runtime_error(
        fmt::format("cannot carry '{}' over: {}", src.string(), errno_text(e)));
  }
  if (fs::is_symlink(st)) {
    fs::copy_symlink(src, dst, ec);
  } else {
    fs::copy_file(src, dst, ec);
  }
  if (ec)
    throw std::runtime_error(fmt::format("cannot carry '{}' over: {}", src.string(), ec.message()));
}

bool all_digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// ".NAME.new.PID" / ".NAME.old.PID" siblings of the folder NAME.
bool is_sibling_temp(const std::string& entry, const std::string& name, const char* kind) {
  const std::string prefix = fmt::format(".{}.{}.", name, kind);
  return entry.starts_with(prefix) && all_digits(std::string_view(entry).substr(prefix.size()));
}

// ".FILE.tmpPID": temporaries of the per-file writer of earlier versions, and the write probe.
bool is_inner_temp(const std::string& entry) {
  if (entry.size() < 2 || entry[0] != '.') return false;
  const std::size_t t = entry.rfind(".tmp");
  return t != std::string::npos && t > 0 && all_digits(std::string_view(entry).substr(t + 4));
}

// Under the lock: a previous set moved aside by an interrupted fallback swap (.NAME.old.PID) is put
// back when the live folder is missing, or is an empty folder that a writer created after the
// interruption. Returns whether it restored one.
bool restore_moved_aside(const fs::path& parent, const std::string& name, const fs::path& folder) {
  std::error_code ec;
  std::vector<fs::path> olds;
  for (const auto& e : fs::directory_iterator(parent, ec)) {
    if (is_sibling_temp(e.path().filename().string(), name, "old")) olds.push_back(e.path());
  }
  if (olds.empty()) return false;
  const auto st = fs::symlink_status(folder, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st) || !fs::is_empty(folder, ec) || ec) return false;
    if (::rmdir(folder.c_str()) != 0) return false;
  }
  // Killed between "move previous folder aside" and "rename new folder": the previous set is
  // the one a reader saw last; put it back.
  if (rename2(olds.front(), folder, RENAME_NOREPLACE) == 0 ||
      ::rename(olds.front().c_str(), folder.c_str()) == 0) {
    std::cerr << fmt::format(
        "ncosim: restored the previous result set of '{}' (a write was interrupted)\n",
        folder.string());
    return true;
  }
  return false;
}

// Whether `entry` is named by `stale` (exact names, or prefixes written "prefix*").
bool is_stale(const std::string& entry, const std::vector<std::string>& stale) {
  for (const auto& s : stale) {
    if (!s.empty() && s.back() == '*') {
      if (entry.starts_with(std::string_view(s).substr(0, s.size() - 1))) return true;
    } else if (entry == s) {
      return true;
    }
  }
  return false;
}

// Under the lock: restores a previous set moved aside by an interrupted fallback swap, then
// removes every leftover temporary sibling. Returns how many were removed.
int clean_siblings(const fs::path& parent, const std::string& name, const fs::path& folder) {
  std::error_code ec;
  restore_moved_aside(parent, name, folder);
  std::vector<fs::path> news, olds;
  for (const auto& e : fs::directory_iterator(parent, ec)) {
    const std::string n = e.path().filename().string();
    if (is_sibling_temp(n, name, "new")) news.push_back(e.path());
    if (is_sibling_temp(n, name, "old")) olds.push_back(e.path());
  }
  int removed = 0;
  for (const auto& v : {news, olds}) {
    for (const auto& p : v) {
      fs::remove_all(p, ec);
      if (!ec) ++removed;
    }
  }
  return removed;
}

void report(int removed, const fs::path& folder) {
  if (removed > 0) {
    std::cerr << fmt::format(
        "ncosim: removed {} leftover temporar{} of an interrupted write of '{}'\n", removed,
        removed == 1 ? "y" : "ies", folder.string());
  }
}

}  // namespace

std::string output_set_folder(const std::string& dir) {
  if (dir.empty())
    throw config::ScenarioError("--out: expected a folder name, got an empty string");
  std::error_code ec;
  fs::path p = fs::absolute(fs::path(dir), ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("cannot resolve the output folder '{}': {}", dir, ec.message()));
  p = fs::weakly_canonical(p, ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("cannot resolve the output folder '{}': {}", dir, ec.message()));
  if (p.filename().empty() || p.filename() == "." || p.filename() == "..") p = p.parent_path();
  if (p == p.root_path() || p.filename().empty()) {
    throw config::ScenarioError(
        fmt::format("--out: expected a folder below the root, got '{}'", dir));
  }
  const fs::path cwd = fs::current_path(ec);
  if (!ec) {
    const auto rel = cwd.lexically_relative(p);
    if (!rel.empty() && *rel.begin() != "..") {
      throw config::ScenarioError(
          fmt::format("--out: expected a folder that is not the current directory or one of its "
                      "parents, got '{}' (a result "
                      "set replaces its folder as a whole)",
                      dir));
    }
  }
  return p.string();
}

namespace {

// The processes that hold the flock on the open file `fd` refers to, this one aside: every
// descriptor of every process (that /proc lets us see) on the same file whose fdinfo lists a
// lock. The PID written in the file names the process that took the lock, which may have ended
// while a process it started still holds its descriptor; these are the live holders.
std::vector<long> lock_holders(int fd) {
  struct stat locked {};
  std::vector<long> out;
  if (::fstat(fd, &locked) != 0) return out;
  std::error_code ec;
  for (const auto& proc : fs::directory_iterator("/proc", ec)) {
    const std::string name = proc.path().filename().string();
    if (name.empty() || name.find_first_not_of("0123456789") != std::string::npos) continue;
    const long pid = std::atol(name.c_str());
    if (pid == static_cast<long>(::getpid())) continue;
    std::error_code fd_ec;
    for (const auto& entry : fs::directory_iterator(proc.path() / "fd", fd_ec)) {
      struct stat st {};
      if (::stat(entry.path().c_str(), &st) != 0 || st.st_dev != locked.st_dev ||
          st.st_ino != locked.st_ino)
        continue;
      std::ifstream info(proc.path() / "fdinfo" / entry.path().filename());
      std::string line;
      bool holds = false;
      while (std::getline(info, line)) holds = holds || line.rfind("lock:", 0) == 0;
      if (holds && std::find(out.begin(), out.end(), pid) == out.end()) out.push_back(pid);
    }
  }
  return out;
}

// The parent of process `pid` (/proc/PID/stat's fourth field, after the command in parentheses),
// or 0 when /proc does not say.
long parent_of(long pid) {
  std::ifstream in(fmt::format("/proc/{}/stat", pid));
  std::string stat;
  std::getline(in, stat);
  const std::size_t close = stat.rfind(')');
  if (close == std::string::npos) return 0;
  std::istringstream rest(stat.substr(close + 1));
  std::string state;
  long parent = 0;
  rest >> state >> parent;
  return parent;
}

// The holders that got their descriptor from no other holder: a process started by a holder
// (mpirun and its ranks under the shell that took the lock, a worker of ncosim) inherits its
// descriptors, and with them the lock, but is not a holder of its own; naming only the first of
// each line keeps the message the same whoever asks (one ncosim or a rank under mpirun).
std::vector<long> first_holders(const std::vector<long>& holders) {
  std::vector<long> out;
  for (const long h : holders) {
    bool inherited = false;
    long p = h;
    for (int up = 0; up < 64 && !inherited && (p = parent_of(p)) > 1; ++up)
      inherited = std::find(holders.begin(), holders.end(), p) != holders.end();
    if (!inherited) out.push_back(h);
  }
  return out;
}

// "PID 123" for the live holders of the lock on `fd` (several: "PID 123, 456"), saying who took
// it when that was another process (a worker that outlived ncosim); `written` (the PID the taker
// wrote in the file) when /proc shows none.
std::string holder_text(int fd, const std::string& written) {
  const std::vector<long> live = first_holders(lock_holders(fd));
  if (live.empty()) return fmt::format("PID {}", written.empty() ? "unknown" : written);
  std::string pids;
  for (const long p : live) pids += (pids.empty() ? "" : ", ") + std::to_string(p);
  const long taker = std::atol(written.c_str());
  if (taker <= 0 || std::find(live.begin(), live.end(), taker) != live.end())
    return fmt::format("PID {}", pids);
  const bool ended = ::kill(static_cast<pid_t>(taker), 0) != 0 && errno == ESRCH;
  return fmt::format("PID {}, which holds the lock PID {} took{}", pids, taker,
                     ended ? " before it ended" : "");
}

}  // namespace

OutputFolderLock::OutputFolderLock(const std::string& dir) {
  const fs::path folder = output_set_folder(dir);
  const fs::path parent = folder.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("cannot create the output directory '{}': {}", dir, ec.message()));
  std::lock_guard<std::mutex> g(lock_mutex());
  auto& held = held_locks()[folder.string()];
  key_ = folder.string();
  if (held.count > 0) {
    ++held.count;
    return;
  }
  const fs::path lock_path = parent / fmt::format(".{}.lock", folder.filename().string());
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (fd < 0) {
    held_locks().erase(key_);
    throw std::runtime_error(
        fmt::format("cannot open the lock file '{}': {}", lock_path.string(), errno_text(errno)));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    std::string pid;
    char buf[32] = {};
    const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
    if (n > 0) pid.assign(buf, static_cast<std::size_t>(n));
    while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
    const std::string holder = e == EWOULDBLOCK ? holder_text(fd, pid) : std::string();
    ::close(fd);
    held_locks().erase(key_);
    if (e == EWOULDBLOCK) {
      throw config::ScenarioError(
          fmt::format("{}: the output folder is in use by another ncosim process ({}; lock "
                      "{}); wait for it to finish or "
                      "choose another --out",
                      dir, holder, lock_path.string()));
    }
    throw std::runtime_error(
        fmt::format("cannot lock '{}': {}", lock_path.string(), errno_text(e)));
  }
  const std::string text = fmt::format("{}\n", static_cast<long>(::getpid()));
  if (::ftruncate(fd, 0) == 0) {
    [[maybe_unused]] const ssize_t w = ::pwrite(fd, text.data(), text.size(), 0);
  }
  held.fd = fd;
  held.count = 1;
  restore_moved_aside(parent, folder.filename().string(), folder);
}

OutputFolderLock::~OutputFolderLock() {
  std::lock_guard<std::mutex> g(lock_mutex());
  auto it = held_locks().find(key_);
  if (it == held_locks().end()) return;
  if (--it->second.count == 0) {
    // The lock file stays: removing it would race with a process that has just opened it.
    ::close(it->second.fd);
    held_locks().erase(it);
  }
}

namespace {

// The new set in `tmp`: created, `files` written and `installs` made, then every entry of the
// previous set in `folder` (if any) that is neither written again nor stale carried over (temporary
// leftovers inside it are counted in `removed` and dropped), and `tmp` fsynced. Returns whether a
// previous set exists.
bool fill_new_set(const fs::path& tmp, const fs::path& folder,
                  const std::vector<std::pair<std::string, std::string>>& files,
                  const std::vector<InstalledFile>& installs, const std::vector<std::string>& names,
                  const std::vector<std::string>& stale, Steps& step, int& removed) {
  step("create the temporary folder");
  if (::mkdir(tmp.c_str(), 0777) != 0) {
    throw std::runtime_error(
        fmt::format("cannot create '{}': {}", tmp.string(), errno_text(errno)));
  }
  for (const auto& [fname, content] : files) write_file(tmp / fname, content, step, fname);
  for (const auto& f : installs) {
    step("install " + f.name);
    f.make(tmp / f.name);
  }
  std::error_code ec;
  const bool exists = fs::is_directory(folder, ec);
  if (exists) {
    struct stat st {};
    if (::stat(folder.c_str(), &st) == 0) ::chmod(tmp.c_str(), st.st_mode & 07777);
    for (const auto& e : fs::directory_iterator(folder)) {
      const std::string n = e.path().filename().string();
      const bool written = std::find(names.begin(), names.end(), n) != names.end();
      if (written || is_stale(n, stale)) continue;
      if (is_inner_temp(n)) {
        ++removed;  // dropped with the previous folder
        continue;
      }
      step("carry over " + n);
      carry_over(e.path(), tmp / n);
    }
  }
  step("fsync the temporary folder");
  fsync_path(tmp, true);
  return exists;
}

}  // namespace

int write_output_set(const std::string& dir,
                     const std::vector<std::pair<std::string, std::string>>& files,
                     const std::vector<std::string>& stale,
                     const std::vector<InstalledFile>& installs) {
  std::vector<std::string> names;
  for (const auto& f : files) names.push_back(f.first);
  for (const auto& f : installs) names.push_back(f.name);
  for (const auto& name : names) {
    if (name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos) {
      throw std::invalid_argument(fmt::format("write_output_set: bad file name '{}'", name));
    }
  }
  OutputFolderLock lock(dir);
  const fs::path folder = output_set_folder(dir);
  const fs::path parent = folder.parent_path();
  const std::string name = folder.filename().string();
  Steps step;
  std::error_code ec;
  int removed = clean_siblings(parent, name, folder);
  const fs::path tmp = parent / fmt::format(".{}.new.{}", name, static_cast<long>(::getpid()));
  bool tmp_is_new = true;  // false once the exchange has put the previous set there
  try {
    const bool exists = fill_new_set(tmp, folder, files, installs, names, stale, step, removed);
    if (exists) {
      step("exchange the folders");
      const char* no_exchange =
          std::getenv("NCOSIM_TEST_NO_EXCHANGE");  // test hook: the fallback path
      const bool exchanged = !(no_exchange != nullptr && std::string(no_exchange) == "1") &&
                             rename2(tmp, folder, RENAME_EXCHANGE) == 0;
      if (!exchanged && no_exchange == nullptr) {
        if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP) {
          throw std::runtime_error(
              fmt::format("cannot swap '{}' in: {}", folder.string(), errno_text(errno)));
        }
      }
      if (exchanged) {
        tmp_is_new = false;
      } else {
        const fs::path old =
            parent / fmt::format(".{}.old.{}", name, static_cast<long>(::getpid()));
        step("move the previous folder aside");
        if (::rename(folder.c_str(), old.c_str()) != 0) {
          throw std::runtime_error(
              fmt::format("cannot move '{}' aside: {}", folder.string(), errno_text(errno)));
        }
        step("rename the new folder");
        if (::rename(tmp.c_str(), folder.c_str()) != 0) {
          const int e = errno;
          ::rename(old.c_str(), folder.c_str());
          throw std::runtime_error(
              fmt::format("cannot rename into '{}': {}", folder.string(), errno_text(e)));
        }
        step("fsync the parent folder");
        fsync_path(parent, true);
        step("remove the previous folder");
        fs::remove_all(old, ec);
        report(removed, folder);
        return removed;
      }
    } else {
      step("rename the new folder");
      if (::rename(tmp.c_str(), folder.c_str()) != 0) {
        throw std::runtime_error(
            fmt::format("cannot rename into '{}': {}", folder.string(), errno_text(errno)));
      }
      tmp_is_new = false;
    }
    step("fsync the parent folder");
    fsync_path(parent, true);
    step("remove the previous folder");
    fs::remove_all(tmp, ec);
  } catch (...) {
    if (tmp_is_new) fs::remove_all(tmp, ec);
    throw;
  }
  report(removed, folder);
  return removed;
}

void restore_interrupted_write(const std::string& dir) {
  fs::path folder;
  try {
    folder = output_set_folder(dir);
  } catch (const std::exception&) {
    return;  // not a folder a set can be written to: the reader says what it cannot read
  }
  std::error_code ec;
  const auto st = fs::symlink_status(folder, ec);
  if (fs::exists(st) && !(fs::is_directory(st) && fs::is_empty(folder, ec))) return;
  const std::string name = folder.filename().string();
  bool moved_aside = false;
  for (const auto& e : fs::directory_iterator(folder.parent_path(), ec))
    moved_aside = moved_aside || is_sibling_temp(e.path().filename().string(), name, "old");
  if (!moved_aside) return;
  // The lock restores it (restore_moved_aside, with its message); a writer holding the lock is
  // told as for any writer.
  const OutputFolderLock lock(dir);
}

void prepare_output_dir(const std::string& dir) {
  namespace fs = std::filesystem;
  const fs::path folder = output_set_folder(dir);  // refuses "", "/", the current folder
  // Under the folder's lock, which first restores a set left aside by an interrupted swap: the
  // folder created here must never stand in for it.
  const OutputFolderLock lock(dir);
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec)
    throw std::runtime_error(
        fmt::format("cannot create the output directory '{}': {}", dir, ec.message()));
  // The result set is written into a sibling folder and swapped in: the parent must be writable.
  const fs::path probe =
      folder.parent_path() /
      fmt::format(".{}.probe.tmp{}", folder.filename().string(), static_cast<long>(::getpid()));
  fs::create_directory(probe, ec);
  if (ec) {
    throw std::runtime_error(
        fmt::format("cannot write next to the output directory '{}' (in '{}'): {}", dir,
                    folder.parent_path().string(), ec.message()));
  }
  fs::remove(probe, ec);
}

void write_files_atomically(const std::string& dir,
                            const std::vector<std::pair<std::string, std::string>>& files,
                            const std::vector<std::string>& stale) {
  write_output_set(dir, files, stale);  // sim/files/output_set.h
}

}  // namespace ncosim::sim

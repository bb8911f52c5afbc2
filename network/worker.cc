// network/worker.cc — the caller's side of the network workers (network/worker.h): the fork
// servers, and a run in a child of one, driven over its socket (network/worker_protocol.h).
#include "network/worker.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "network/networks.h"
#include "network/worker_protocol.h"

extern char** environ;

namespace ncosim::network {

namespace {

std::mutex& executable_mutex() {
  static std::mutex m;
  return m;
}
std::string& executable() {
  static std::string path;
  return path;
}

std::string exit_text(int status) {
  return WIFSIGNALED(status) ? fmt::format("signal {}", WTERMSIG(status))
                             : fmt::format("exit status {}", WEXITSTATUS(status));
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

std::runtime_error system_error(const std::string& what) {
  return std::runtime_error(fmt::format("{}: {}", what, std::strerror(errno)));
}

}  // namespace

void set_worker_executable(const std::string& path) {
  const std::lock_guard<std::mutex> lock(executable_mutex());
  executable() = path;
}

std::string worker_executable() {
  const std::lock_guard<std::mutex> lock(executable_mutex());
  return executable();
}

// One fork server: `EXE network-worker` with its socket as file descriptor 3.
class WorkerServer {
 public:
  WorkerServer() {
    const std::string exe = worker_executable();
    if (exe.empty()) {
      throw std::runtime_error(
          "a packet network's runs need a worker process, and no worker executable is set "
          "(network::set_worker_executable: the ncosim executable, or a program whose main calls "
          "run_cli)");
    }
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
      throw system_error("cannot create a network worker's socket");
    fd_ = sv[0];
    pid_ = spawn(exe, sv[1]);
    ::close(sv[1]);  // only the server holds its end: its death is end of file here
  }
  ~WorkerServer() {
    ::close(fd_);  // end of file: the server ends (with its child, if any)
    wait();
  }
  WorkerServer(const WorkerServer&) = delete;
  WorkerServer& operator=(const WorkerServer&) = delete;

  // A child that serves `run_fd` (the server's copy of it is closed by the server).
  void fork_child(int run_fd) {
    if (!kernel::send_fd(fd_, run_fd, 'F'))
      died_ = true;  // its end-of-run report says more (wait_child)
  }

  // The end of the child: its exit status and what it wrote; false when the server itself died
  // (then `status` is the server's).
  bool wait_child(int& status, std::string& text) {
    char head[9];
    if (!died_ && kernel::read_all(fd_, head, sizeof head) && head[0] == 'X') {
      status = static_cast<int>(kernel::get_u64(head + 1));
      char size[8];
      if (kernel::read_all(fd_, size, 8)) {
        text.resize(kernel::get_u64(size));
        if (kernel::read_all(fd_, text.data(), text.size())) return true;
      }
    }
    died_ = true;
    ::kill(pid_, SIGKILL);  // a server that broke the protocol is stopped
    status = wait();
    return false;
  }
  bool alive() const { return !died_; }

 private:
  static pid_t spawn(const std::string& exe, int fd) {
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&fa, fd, 3);
    // SIGINT and SIGTERM blocked until the server ignores them (the campaign decides when to
    // stop, and a terminal's Ctrl-C reaches the whole process group).
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t mask;
    sigemptyset(&mask);
    sigaddset(&mask, SIGINT);
    sigaddset(&mask, SIGTERM);
    posix_spawnattr_setsigmask(&attr, &mask);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK);
    std::string arg0 = exe, arg1 = "network-worker";
    char* argv[] = {arg0.data(), arg1.data(), nullptr};
    pid_t pid = -1;
    const int rc = ::posix_spawn(&pid, exe.c_str(), &fa, &attr, argv, environ);
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
      ::close(fd);
      errno = rc;
      throw system_error(
          fmt::format("cannot start the network worker process '{} network-worker'", exe));
    }
    return pid;
  }
  int wait() {
    int status = 0;
    if (pid_ > 0) {
      while (::waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
      }
      pid_ = -1;
      status_ = status;
    }
    return status_;
  }

  int fd_ = -1;
  pid_t pid_ = -1;
  int status_ = 0;
  bool died_ = false;
};

namespace {

// One run in a child of a server: the calls of network/backend.h as messages, sends and moves
// held until the next advance_to or counters (one write and one reply per advance).
class RemoteRun final : public NetworkRun {
 public:
  RemoteRun(WorkerPool& pool, std::unique_ptr<WorkerServer> server, std::uint64_t run)
      : pool_(pool), server_(std::move(server)), run_(run) {}
  ~RemoteRun() override {
    if (fd_ >= 0) {
      ::close(fd_);  // end of file: the child exits
      fd_ = -1;
      int status = 0;
      std::string text;
      if (server_->wait_child(status, text)) {
        // Warnings of a run that ended normally are passed on, as if it had run here.
        if (!text.empty()) std::cerr << text << std::flush;
        pool_.give_back(std::move(server_));
      }
    }
  }
  RemoteRun(const RemoteRun&) = delete;
  RemoteRun& operator=(const RemoteRun&) = delete;

  void open(const std::vector<WorkerNetwork>& networks, const std::vector<Sender>& senders,
            std::uint64_t seed) {
    int sv[2];
    if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
      throw system_error("cannot create a network run's socket");
    fd_ = sv[0];
    server_->fork_child(sv[1]);
    ::close(sv[1]);
    out_ = "I";
    kernel::put_u64(out_, seed);
    kernel::put_u64(out_, run_);
    kernel::put_u64(out_, networks.size());
    for (const WorkerNetwork& n : networks) {
      kernel::put_string(out_, n.kind);
      kernel::put_string(out_, n.table);
    }
    kernel::put_u64(out_, senders.size());
    for (const Sender& s : senders) wire::put_sender(out_, s);
    flush();
    const char reply = read_type();
    if (reply == 'E') {
      const std::string message = read_string();
      close_after_error();
      throw std::runtime_error(message);
    }
    if (reply != 'R') died();
  }

  void send(int sender, std::uint64_t id, Nanoseconds t) override {
    out_.push_back('S');
    kernel::put_u64(out_, static_cast<std::uint64_t>(sender));
    kernel::put_u64(out_, id);
    wire::put_i64(out_, t);
  }
  void advance_to(Nanoseconds t, std::vector<Fate>& fates) override {
    out_.push_back('A');
    wire::put_i64(out_, t);
    flush();
    stale_ = true;
    if (read_type() != 'F') died();
    const std::uint64_t n = read_u64();
    buffer_.resize(n * 8 * wire::kFateWords);
    if (!kernel::read_all(fd_, buffer_.data(), buffer_.size())) died();
    for (std::uint64_t i = 0; i < n; ++i) {
      const char* p = buffer_.data() + i * 8 * wire::kFateWords;
      fates.push_back(Fate{static_cast<int>(kernel::get_u64(p)), kernel::get_u64(p + 8),
                           wire::get_i64(p + 16), static_cast<Drop>(kernel::get_u64(p + 24))});
    }
  }
  void move_sender(int sender, double x, double y, double z, Nanoseconds t) override {
    move('M', sender, x, y, z, t);
  }
  void move_sink(int network, double x, double y, double z, Nanoseconds t) override {
    move('N', network, x, y, z, t);
  }
  MacCounters counters(int sender) const override {
    if (stale_) const_cast<RemoteRun*>(this)->fetch_counters();
    return counters_.at(static_cast<std::size_t>(sender));
  }

 private:
  void move(char type, int who, double x, double y, double z, Nanoseconds t) {
    out_.push_back(type);
    kernel::put_u64(out_, static_cast<std::uint64_t>(who));
    wire::put_double(out_, x);
    wire::put_double(out_, y);
    wire::put_double(out_, z);
    wire::put_i64(out_, t);
  }
  void fetch_counters() {
    out_.push_back('C');
    flush();
    if (read_type() != 'K') died();
    const std::uint64_t n = read_u64();
    buffer_.resize(n * 8 * wire::kCounterWords);
    if (!kernel::read_all(fd_, buffer_.data(), buffer_.size())) died();
    counters_.resize(n);
    for (std::uint64_t i = 0; i < n; ++i)
      counters_[i] = wire::get_counters(buffer_.data() + i * 8 * wire::kCounterWords);
    stale_ = false;
  }
  void flush() {
    if (!kernel::write_all(fd_, out_)) died();
    out_.clear();
  }
  char read_type() {
    char c = 0;
    if (!kernel::read_all(fd_, &c, 1)) died();
    return c;
  }
  std::uint64_t read_u64() {
    char b[8];
    if (!kernel::read_all(fd_, b, 8)) died();
    return kernel::get_u64(b);
  }
  std::string read_string() {
    std::string s(read_u64(), '\0');
    if (!kernel::read_all(fd_, s.data(), s.size())) died();
    return s;
  }
  void close_after_error() {
    ::close(fd_);
    fd_ = -1;
    int status = 0;
    std::string text;
    if (server_->wait_child(status, text)) pool_.give_back(std::move(server_));
  }

  // The child ended mid-run (its socket's end of file): why, from its server. A child that died
  // loses this run (EngineFailure); a server that died ends the campaign.
  [[noreturn]] void died() {
    ::close(fd_);
    fd_ = -1;
    int status = 0;
    std::string text;
    if (!server_->wait_child(status, text)) {
      throw std::runtime_error(fmt::format("run {}: its worker process ended without a result ({})",
                                           run_, exit_text(status)));
    }
    pool_.give_back(std::move(server_));
    const std::string line = last_line(text);
    throw EngineFailure(fmt::format("its process ended abnormally ({}){}", exit_text(status),
                                    line.empty() ? "" : ": " + line));
  }

  WorkerPool& pool_;
  std::unique_ptr<WorkerServer> server_;
  std::uint64_t run_;
  int fd_ = -1;
  std::string out_, buffer_;
  bool stale_ = true;  // counters_ is older than the last advance
  std::vector<MacCounters> counters_;
};

}  // namespace

WorkerPool::WorkerPool() = default;
WorkerPool::~WorkerPool() = default;

std::unique_ptr<NetworkRun> WorkerPool::start(const std::vector<WorkerNetwork>& networks,
                                              const std::vector<Sender>& senders,
                                              std::uint64_t seed, std::uint64_t run) {
  std::unique_ptr<WorkerServer> server;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!idle_.empty()) {
      server = std::move(idle_.back());
      idle_.pop_back();
    }
  }
  if (!server) server = std::make_unique<WorkerServer>();
  auto r = std::make_unique<RemoteRun>(*this, std::move(server), run);
  r->open(networks, senders, seed);
  return r;
}

void WorkerPool::give_back(std::unique_ptr<WorkerServer> server) {
  if (!server || !server->alive()) return;
  const std::lock_guard<std::mutex> lock(mutex_);
  idle_.push_back(std::move(server));
}

}  // namespace ncosim::network

// network/worker_main.cc — the worker's side (network/worker.h): `EXE network-worker`, a
// single-threaded fork server, and its children, each one run of networks served over its socket
// (network/worker_protocol.h).
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <toml++/toml.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <exception>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "network/networks.h"
#include "network/worker.h"
#include "network/worker_protocol.h"

namespace ncosim::network {

namespace {

constexpr int kServerFd = 3;
// What a child wrote on stderr (and stdout), kept up to this many bytes (the tail, when more).
constexpr std::size_t kTextKept = 1 << 20;

// Reads the run socket in large chunks: one read per batch of messages, not per field.
class Reader {
 public:
  explicit Reader(int fd) : fd_(fd) {}
  // The next n bytes (valid until the next call); nullptr at end of file before them.
  const char* take(std::size_t n) {
    while (end_ - at_ < n) {
      if (at_ > 0) {
        buf_.erase(0, at_);
        end_ -= at_;
        at_ = 0;
      }
      buf_.resize(std::max<std::size_t>(end_ + n, 1 << 16));
      const ssize_t r = ::read(fd_, buf_.data() + end_, buf_.size() - end_);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) return nullptr;
      end_ += static_cast<std::size_t>(r);
    }
    const char* p = buf_.data() + at_;
    at_ += n;
    return p;
  }
  bool u64(std::uint64_t& v) {
    const char* p = take(8);
    if (p != nullptr) v = kernel::get_u64(p);
    return p != nullptr;
  }
  bool string(std::string& s) {
    std::uint64_t n = 0;
    if (!u64(n) || n > (std::uint64_t{1} << 30)) return false;
    const char* p = take(n);
    if (p != nullptr) s.assign(p, n);
    return p != nullptr;
  }

 private:
  int fd_;
  std::string buf_;
  std::size_t at_ = 0, end_ = 0;
};

// The run's networks, read again from their tables with the worker's registry.
struct Built {
  std::vector<toml::table> docs;
  std::vector<std::shared_ptr<const NetworkDesign>> designs;
  std::size_t senders = 0;
  std::unique_ptr<NetworkRun> run;
};

// The 'I' message: the networks built and started. Throws on a malformed message or a table the
// registry refuses.
void build(Reader& in, const NetworkRegistry& kinds, Built& b) {
  const char* type = in.take(1);
  std::uint64_t seed = 0, run = 0, networks = 0, senders = 0;
  if (type == nullptr || *type != 'I' || !in.u64(seed) || !in.u64(run) || !in.u64(networks))
    throw std::runtime_error("malformed start message");
  b.docs.reserve(networks);
  for (std::uint64_t n = 0; n < networks; ++n) {
    std::string kind, table;
    if (!in.string(kind) || !in.string(table)) throw std::runtime_error("malformed network");
    b.docs.push_back(toml::parse(table));
    const config::Table t(b.docs.back(), "network[" + std::to_string(n) + "]", "<network worker>");
    b.designs.push_back(kinds.lookup(t, "kind", "").factory(t));
  }
  if (!in.u64(senders)) throw std::runtime_error("malformed senders");
  std::vector<Sender> all;
  for (std::uint64_t s = 0; s < senders; ++s) {
    const char* p = in.take(8 * wire::kSenderWords);
    if (p == nullptr) throw std::runtime_error("malformed sender");
    all.push_back(wire::get_sender(p));
  }
  std::vector<const NetworkDesign*> designs;
  for (const auto& d : b.designs) designs.push_back(d.get());
  b.senders = all.size();
  b.run = start_here(designs, all, seed, run);
}

// One message after the start; false at end of file (the run is over) or on a malformed one.
bool serve_one(Reader& in, Built& b, int fd, std::vector<Fate>& fates, std::string& out) {
  NetworkRun& run = *b.run;
  const char* type = in.take(1);
  if (type == nullptr) return false;
  const std::size_t words = *type == 'S' || *type == 'A'   ? (*type == 'S' ? 3 : 1)
                            : *type == 'M' || *type == 'N' ? 5
                                                           : 0;
  const char* p = words > 0 ? in.take(8 * words) : nullptr;
  if (words > 0 && p == nullptr) return false;
  switch (*type) {
    case 'S':
      run.send(static_cast<int>(kernel::get_u64(p)), kernel::get_u64(p + 8), wire::get_i64(p + 16));
      return true;
    case 'M':
    case 'N': {
      const int who = static_cast<int>(kernel::get_u64(p));
      const double x = wire::get_double(p + 8), y = wire::get_double(p + 16),
                   z = wire::get_double(p + 24);
      if (*type == 'M')
        run.move_sender(who, x, y, z, wire::get_i64(p + 32));
      else
        run.move_sink(who, x, y, z, wire::get_i64(p + 32));
      return true;
    }
    case 'A': {
      fates.clear();
      run.advance_to(wire::get_i64(p), fates);
      out = "F";
      kernel::put_u64(out, fates.size());
      for (const Fate& f : fates) {
        kernel::put_u64(out, static_cast<std::uint64_t>(f.sender));
        kernel::put_u64(out, f.id);
        wire::put_i64(out, f.time);
        kernel::put_u64(out, static_cast<std::uint64_t>(f.drop));
      }
      return kernel::write_all(fd, out);
    }
    case 'C': {
      out = "K";  // every sender of the run, in order
      kernel::put_u64(out, b.senders);
      for (std::size_t s = 0; s < b.senders; ++s)
        wire::put_counters(out, run.counters(static_cast<int>(s)));
      return kernel::write_all(fd, out);
    }
    default:
      return false;
  }
}

// A child of the server: one run served on `fd`. Returns its exit status.
int serve_run(int fd, const NetworkRegistry& kinds) {
  Reader in(fd);
  Built b;
  try {
    build(in, kinds, b);
  } catch (const std::exception& e) {
    std::string out = "E";
    kernel::put_string(out, e.what());
    kernel::write_all(fd, out);
    return 2;
  }
  if (!kernel::write_all(fd, "R", 1)) return 1;
  std::vector<Fate> fates;
  std::string out;
  while (serve_one(in, b, fd, fates, out)) {
  }
  return 0;
}

// Receives the next run socket from the parent (-1 at end of file: the parent has gone).
int receive_fd() { return kernel::receive_fd(kServerFd, 'F'); }

// Until child `pid` ends: what it writes (the tail), then its exit status. When the parent goes
// (end of file on the server's socket), the child is killed and the server exits.
int watch(pid_t pid, int text_fd, std::string& text) {
  pollfd fds[2] = {{kServerFd, POLLRDHUP, 0}, {text_fd, POLLIN, 0}};
  char buf[65536];
  while (fds[1].fd >= 0) {
    if (::poll(fds, 2, -1) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    if ((fds[0].revents & (POLLRDHUP | POLLHUP | POLLERR)) != 0) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
      ::_exit(0);
    }
    if (fds[1].revents == 0) continue;
    const ssize_t r = ::read(text_fd, buf, sizeof buf);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    text.append(buf, static_cast<std::size_t>(r));
    if (text.size() > 2 * kTextKept) text.erase(0, text.size() - kTextKept);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  return status;
}

// One child: forked, it serves `run_fd` and exits; the server reports its end.
bool fork_run(int run_fd, const NetworkRegistry& kinds) {
  int text[2];
  if (::pipe2(text, O_CLOEXEC) != 0) return false;
  const pid_t server = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Dies with the server (single-threaded: the signal cannot come from a thread's end).
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != server) ::_exit(1);
    ::close(kServerFd);
    ::close(text[0]);
    ::dup2(text[1], STDOUT_FILENO);
    ::dup2(text[1], STDERR_FILENO);
    ::close(text[1]);
    int code = 3;
    try {
      code = serve_run(run_fd, kinds);
    } catch (const std::exception& e) {
      std::cerr << "ncosim network worker: " << e.what() << std::endl;
    }
    std::cout.flush();
    std::cerr.flush();
    ::_exit(code);
  }
  ::close(run_fd);
  ::close(text[1]);
  std::string out;
  int status = 0;
  if (pid < 0) {
    out = std::string("cannot fork: ") + std::strerror(errno);
    status = 1 << 8;  // as an exit status 1
  } else {
    status = watch(pid, text[0], out);
  }
  ::close(text[0]);
  std::string report = "X";
  kernel::put_u64(report, static_cast<std::uint64_t>(status));
  kernel::put_string(report, out);
  return kernel::write_all(kServerFd, report);
}

}  // namespace

int worker_main(const NetworkRegistry& kinds) {
  ::signal(SIGINT, SIG_IGN);  // the parent decides when to stop; its end ends this process
  ::signal(SIGTERM, SIG_IGN);
  ::signal(SIGPIPE, SIG_IGN);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  if (::fcntl(kServerFd, F_GETFD) < 0) {
    std::cerr << "ncosim network-worker: started without its socket (it is started by ncosim)\n";
    return 2;
  }
  for (int fd; (fd = receive_fd()) >= 0;) {
    if (!fork_run(fd, kinds)) return 1;
  }
  return 0;
}

}  // namespace ncosim::network

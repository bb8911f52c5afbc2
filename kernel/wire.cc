// kernel/wire.cc — bytes between processes (kernel/wire.h).
#include "kernel/wire.h"

#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace ncosim::kernel {

void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

std::uint64_t get_u64(const char* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i)
    v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

std::uint64_t get_u64(const std::string& in, std::size_t& pos, const char* what) {
  if (pos > in.size() || in.size() - pos < 8)
    throw std::runtime_error(std::string(what) + ": truncated record");
  const std::uint64_t v = get_u64(in.data() + pos);
  pos += 8;
  return v;
}

void put_string(std::string& out, const std::string& s) {
  put_u64(out, s.size());
  out += s;
}

bool get_string(const std::string& in, std::size_t& pos, std::string& s) {
  if (pos > in.size() || in.size() - pos < 8) return false;
  const std::uint64_t n = get_u64(in.data() + pos);
  if (n > in.size() - pos - 8) return false;
  s.assign(in, pos + 8, n);
  pos += 8 + n;
  return true;
}

bool write_all(int fd, const void* data, std::size_t n) {
  const char* p = static_cast<const char*>(data);
  bool socket = true;
  while (n > 0) {
    ssize_t w = socket ? ::send(fd, p, n, MSG_NOSIGNAL) : ::write(fd, p, n);
    if (w < 0 && errno == ENOTSOCK && socket) {
      socket = false;
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

namespace {

// One byte (`byte`) with room for one descriptor in its control message.
struct FdMessage {
  explicit FdMessage(char* byte) : iov{byte, 1} {
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
  }
  iovec iov;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
  msghdr msg{};
};

}  // namespace

bool send_fd(int socket, int fd, char tag) {
  FdMessage m(&tag);
  cmsghdr* c = CMSG_FIRSTHDR(&m.msg);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_RIGHTS;
  c->cmsg_len = CMSG_LEN(sizeof(int));
  std::memcpy(CMSG_DATA(c), &fd, sizeof(int));
  ssize_t sent;
  while ((sent = ::sendmsg(socket, &m.msg, MSG_NOSIGNAL)) < 0 && errno == EINTR) {
  }
  return sent == 1;
}

int receive_fd(int socket, char tag) {
  char byte = 0;
  FdMessage m(&byte);
  ssize_t r;
  while ((r = ::recvmsg(socket, &m.msg, MSG_CMSG_CLOEXEC)) < 0 && errno == EINTR) {
  }
  if (r != 1 || byte != tag) return -1;
  const cmsghdr* c = CMSG_FIRSTHDR(&m.msg);
  if (c == nullptr || c->cmsg_type != SCM_RIGHTS) return -1;
  int fd = -1;
  std::memcpy(&fd, CMSG_DATA(c), sizeof fd);
  return fd;
}

bool read_all(int fd, void* data, std::size_t n) {
  char* p = static_cast<char*>(data);
  while (n > 0) {
    const ssize_t r = ::read(fd, p, n);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return false;
    p += r;
    n -= static_cast<std::size_t>(r);
  }
  return true;
}

}  // namespace ncosim::kernel

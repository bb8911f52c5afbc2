// kernel/wire.h — bytes between processes: fixed-width little-endian integers and
// length-prefixed strings in a byte string (whatever the host's order), and whole reads and
// writes on a file descriptor. One helper for every protocol of the project: the network
// workers (network/worker.cc), the MPI ranks (sim/cmd/mpi_campaign.cc), the SUMO live workers
// (sumo/live.cc) and the stored error curve (sim/run/error_curve.cc).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace ncosim::kernel {

// Appends v as 8 bytes, least significant first.
void put_u64(std::string& out, std::uint64_t v);
// The 8 bytes at p, least significant first (the caller checked that 8 are there).
std::uint64_t get_u64(const char* p);
// The 8 bytes of `in` at `pos`, which moves past them; throws std::runtime_error naming `what`
// (e.g. "error curve") when fewer than 8 are left.
std::uint64_t get_u64(const std::string& in, std::size_t& pos, const char* what);
// A length-prefixed string (put_u64 of its size, then its bytes), and its reader: false when `in`
// holds fewer bytes than announced at `pos` (pos unchanged).
void put_string(std::string& out, const std::string& s);
bool get_string(const std::string& in, std::size_t& pos, std::string& s);

// Writes the n bytes at p to `fd`, retrying after signals and short writes. On a socket the
// write is a send with MSG_NOSIGNAL, so a peer that has gone gives false instead of killing this
// process with SIGPIPE (on a pipe or a terminal it is a plain write). False on any error.
bool write_all(int fd, const void* p, std::size_t n);
inline bool write_all(int fd, const std::string& bytes) {
  return write_all(fd, bytes.data(), bytes.size());
}
// Reads exactly n bytes from `fd` into p, retrying after signals and short reads; false at end of
// file (the peer closed or died) or on an error before them.
bool read_all(int fd, void* p, std::size_t n);

// Passes the descriptor `fd` over the Unix socket `socket` (SCM_RIGHTS) with the one byte `tag`,
// retrying after signals; false when the peer has gone or on an error.
bool send_fd(int socket, int fd, char tag);
// Receives a descriptor sent by send_fd with `tag` (close-on-exec here); -1 at end of file (the
// peer has gone), on an error, or when the byte or the message is not what send_fd sends.
int receive_fd(int socket, char tag);

}  // namespace ncosim::kernel

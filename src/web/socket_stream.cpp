#include "web/socket_stream.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace ks {

namespace {

void address_of(const sockaddr_storage& a, std::string& ip, int& port) {
  char text[INET6_ADDRSTRLEN] = {0};
  if (a.ss_family == AF_INET) {
    const auto* v4 = reinterpret_cast<const sockaddr_in*>(&a);
    ::inet_ntop(AF_INET, &v4->sin_addr, text, sizeof text);
    port = ntohs(v4->sin_port);
  } else if (a.ss_family == AF_INET6) {
    const auto* v6 = reinterpret_cast<const sockaddr_in6*>(&a);
    ::inet_ntop(AF_INET6, &v6->sin6_addr, text, sizeof text);
    port = ntohs(v6->sin6_port);
  }
  ip = text;
}

}  // namespace

SocketStream::SocketStream(int fd, int read_timeout_ms, int write_timeout_ms)
    : fd_(fd), read_timeout_ms_(read_timeout_ms), write_timeout_ms_(write_timeout_ms) {
  // The library writes a reply's head and body separately: without this, Nagle's algorithm holds
  // the body back until the client's delayed ACK of the head (40 ms a reply on keep-alive).
  const int one = 1;
  ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

SocketStream::~SocketStream() {
  if (!finished_) finish(0, 0);
}

bool SocketStream::wait(short events, int timeout_ms) const {
  pollfd p{fd_, events, 0};
  for (;;) {
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0 && errno == EINTR) continue;
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR)) != 0;
  }
}

SocketStream::Head SocketStream::read_head(size_t max_head_bytes, int wait_ms) {
  // Bytes of an earlier request's pipelined successor may already be buffered.
  buf_.erase(0, buf_pos_);
  buf_pos_ = 0;
  if (buf_.empty() && !wait(POLLIN, wait_ms)) return Head::kTimeout;
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(read_timeout_ms_);
  size_t scanned = 0;
  for (;;) {
    const size_t end = buf_.find("\r\n\r\n", scanned > 3 ? scanned - 3 : 0);
    if (end != std::string::npos) return end + 4 > max_head_bytes ? Head::kTooLarge : Head::kReady;
    scanned = buf_.size();
    if (buf_.size() > max_head_bytes) return Head::kTooLarge;
    const int left = int(std::chrono::duration_cast<std::chrono::milliseconds>(
                             deadline - std::chrono::steady_clock::now())
                             .count());
    if (left <= 0 || !wait(POLLIN, left)) return buf_.empty() ? Head::kClosed : Head::kTimeout;
    char chunk[4096];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Head::kClosed;
    buf_.append(chunk, size_t(n));
  }
}

bool SocketStream::is_readable() const {
  return buf_pos_ < buf_.size() || wait(POLLIN, read_timeout_ms_);
}

bool SocketStream::is_writable() const {
  if (!wait(POLLOUT, write_timeout_ms_)) return false;
  // Still connected: a readable socket with nothing to read has been closed by the client.
  pollfd p{fd_, POLLIN, 0};
  if (::poll(&p, 1, 0) > 0) {
    char c;
    if (::recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT) == 0) return false;
  }
  return true;
}

ssize_t SocketStream::read(char* ptr, size_t size) {
  if (buf_pos_ < buf_.size()) {
    const size_t n = std::min(size, buf_.size() - buf_pos_);
    std::memcpy(ptr, buf_.data() + buf_pos_, n);
    buf_pos_ += n;
    if (buf_pos_ == buf_.size()) {
      buf_.clear();
      buf_pos_ = 0;
    }
    return ssize_t(n);
  }
  // The library reads a line byte by byte: small reads are served from a refilled buffer.
  if (!wait(POLLIN, read_timeout_ms_)) return -1;
  if (size >= 4096) {
    ssize_t n;
    do n = ::recv(fd_, ptr, size, 0);
    while (n < 0 && errno == EINTR);
    return n;
  }
  char chunk[4096];
  ssize_t n;
  do n = ::recv(fd_, chunk, sizeof chunk, 0);
  while (n < 0 && errno == EINTR);
  if (n <= 0) return n;
  const size_t give = std::min(size, size_t(n));
  std::memcpy(ptr, chunk, give);
  buf_.assign(chunk + give, size_t(n) - give);
  buf_pos_ = 0;
  return ssize_t(give);
}

ssize_t SocketStream::write(const char* ptr, size_t size) {
  if (!is_writable()) return -1;
  ssize_t n;
  do n = ::send(fd_, ptr, size, MSG_NOSIGNAL);
  while (n < 0 && errno == EINTR);
  return n;
}

bool SocketStream::write_all(const std::string& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = write(bytes.data() + done, bytes.size() - done);
    if (n <= 0) return false;
    done += size_t(n);
  }
  return true;
}

void SocketStream::finish(int drain_ms, size_t drain_bytes) {
  if (finished_) return;
  finished_ = true;
  ::shutdown(fd_, SHUT_WR);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(drain_ms);
  char sink[16384];
  for (size_t total = 0; total < drain_bytes;) {
    const int left = int(std::chrono::duration_cast<std::chrono::milliseconds>(
                             deadline - std::chrono::steady_clock::now())
                             .count());
    if (left <= 0 || !wait(POLLIN, left)) break;
    const ssize_t n = ::recv(fd_, sink, sizeof sink, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    total += size_t(n);
  }
  ::close(fd_);
}

void SocketStream::get_remote_ip_and_port(std::string& ip, int& port) const {
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  if (::getpeername(fd_, reinterpret_cast<sockaddr*>(&a), &len) == 0) address_of(a, ip, port);
}

void SocketStream::get_local_ip_and_port(std::string& ip, int& port) const {
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) == 0) address_of(a, ip, port);
}

}  // namespace ks

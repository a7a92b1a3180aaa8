#pragma once
// A raw HTTP/1.1 client for the server tests: requests sent byte for byte as written (no
// normalisation of the target), replies read by their Content-Length (or to the close).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <string>

namespace ks::test {

struct Reply {
  int status = 0;
  std::string head, body;
  std::string header(const std::string& name) const {
    std::string h = head, key = "\r\n" + name + ":";
    for (auto& c : h) c = char(std::tolower(static_cast<unsigned char>(c)));
    for (auto& c : key) c = char(std::tolower(static_cast<unsigned char>(c)));
    const size_t p = h.find(key);
    if (p == std::string::npos) return "";
    size_t s = p + key.size();
    while (s < head.size() && head[s] == ' ') ++s;
    return head.substr(s, head.find("\r\n", s) - s);
  }
};

class Connection {
 public:
  explicit Connection(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(uint16_t(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~Connection() { close(); }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  bool ok() const { return fd_ >= 0; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  void shutdown_write() { ::shutdown(fd_, SHUT_WR); }
  bool send(const std::string& bytes) {
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
      if (n <= 0) return false;
      done += size_t(n);
    }
    return true;
  }
  // One reply: its head, then its body by Content-Length, chunked, or to the close. Status 0 when
  // nothing (or no complete head) came within `seconds`.
  Reply read_reply(double seconds = 10) {
    Reply r;
    const auto end = deadline(seconds);
    size_t head_end;
    while ((head_end = buf_.find("\r\n\r\n")) == std::string::npos)
      if (!fill(end)) return r;
    r.head = buf_.substr(0, head_end + 2);
    buf_.erase(0, head_end + 4);
    if (r.head.rfind("HTTP/1.", 0) == 0) r.status = std::stoi(r.head.substr(9, 3));
    if (r.status == 100) return read_reply(seconds);  // 100 Continue comes before the reply
    const std::string len = r.header("Content-Length");
    if (!len.empty()) {
      const size_t n = std::stoul(len);
      while (buf_.size() < n)
        if (!fill(end)) break;
      r.body = buf_.substr(0, n);
      buf_.erase(0, std::min(n, buf_.size()));
    } else if (r.header("Transfer-Encoding") == "chunked") {
      for (;;) {
        size_t eol;
        while ((eol = buf_.find("\r\n")) == std::string::npos)
          if (!fill(end)) return r;
        const size_t n = std::stoul(buf_.substr(0, eol), nullptr, 16);
        while (buf_.size() < eol + 2 + n + 2)
          if (!fill(end)) return r;
        r.body += buf_.substr(eol + 2, n);
        buf_.erase(0, eol + 2 + n + 2);
        if (n == 0) break;
      }
    } else {
      while (fill(end)) {
      }
      r.body = buf_;
      buf_.clear();
    }
    return r;
  }
  // Bytes as they come (an event stream), up to `seconds`.
  std::string read_some(double seconds) {
    const auto end = deadline(seconds);
    fill(end);
    std::string out;
    out.swap(buf_);
    return out;
  }
  // True when the server closed the connection within `seconds`.
  bool closed_within(double seconds) {
    const auto end = deadline(seconds);
    while (fill(end)) {
    }
    return eof_;
  }

 private:
  static std::chrono::steady_clock::time_point deadline(double seconds) {
    return std::chrono::steady_clock::now() +
           std::chrono::duration_cast<std::chrono::steady_clock::duration>(
               std::chrono::duration<double>(seconds));
  }
  bool fill(std::chrono::steady_clock::time_point end) {
    if (fd_ < 0 || eof_) return false;
    const int ms = int(std::chrono::duration_cast<std::chrono::milliseconds>(
                           end - std::chrono::steady_clock::now())
                           .count());
    if (ms <= 0) return false;
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, ms) <= 0) return false;
    char b[65536];
    const ssize_t n = ::recv(fd_, b, sizeof b, 0);
    if (n <= 0) {
      eof_ = true;
      return false;
    }
    buf_.append(b, size_t(n));
    return true;
  }
  int fd_ = -1;
  bool eof_ = false;
  std::string buf_;
};

// One request on its own connection (closed after the reply).
inline Reply request(int port, const std::string& bytes, double seconds = 10) {
  Connection c(port);
  if (!c.ok() || !c.send(bytes)) return {};
  return c.read_reply(seconds);
}

inline Reply get(int port, const std::string& target, const std::string& method = "GET",
                 const std::string& extra_headers = "") {
  return request(port, method + " " + target +
                           " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\n" +
                           extra_headers + "Connection: close\r\n\r\n");
}

}  // namespace ks::test

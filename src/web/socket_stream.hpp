#pragma once
// One accepted TCP connection as cpp-httplib's Stream, buffered, for web/web_server's own
// connection loop. What the library's stream does not bound, this does:
//  - read_head(): reads until the end of the request head (CRLF CRLF) is buffered, refusing a head
//    longer than a limit before the library parses it (cpp-httplib 0.11 bounds each header line
//    but not their number);
//  - finish(): closes gracefully: our side's FIN after the last reply, then the bytes the client
//    still sends (say the rest of a refused upload) read and dropped for a short while, so that
//    the kernel does not answer them with a reset that would discard the reply unread.
// Reads and writes wait at most the read / write time-out.
#include "web/httplib.hpp"

#include <string>

namespace ks {

class SocketStream : public httplib::Stream {
 public:
  SocketStream(int fd, int read_timeout_ms, int write_timeout_ms);
  ~SocketStream() override;  // finish() when not called yet
  SocketStream(const SocketStream&) = delete;
  SocketStream& operator=(const SocketStream&) = delete;

  enum class Head { kReady, kClosed, kTimeout, kTooLarge };
  // Waits up to `wait_ms` for a request to begin, then reads until its head is complete.
  Head read_head(size_t max_head_bytes, int wait_ms);
  // Writes a whole small reply (the connection loop's own refusals).
  bool write_all(const std::string& bytes);
  // Half-closes, drops what the client still sends (at most `drain_ms`, `drain_bytes`), closes.
  void finish(int drain_ms = 1000, size_t drain_bytes = size_t(256) << 20);

  // httplib::Stream
  bool is_readable() const override;
  bool is_writable() const override;
  ssize_t read(char* ptr, size_t size) override;
  ssize_t write(const char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override;
  void get_local_ip_and_port(std::string& ip, int& port) const override;
  int socket() const override { return fd_; }

 private:
  bool wait(short events, int timeout_ms) const;
  int fd_;
  int read_timeout_ms_, write_timeout_ms_;
  std::string buf_;  // bytes read but not yet consumed, from buf_pos_
  size_t buf_pos_ = 0;
  bool finished_ = false;
};

}  // namespace ks

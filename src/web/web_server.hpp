#pragma once
// The HTTP server of `kinesplat view` and `kinesplat studio`: Debian's cpp-httplib (0.11) with
// kinesplat's limits around it.
//  - Binds one numeric address (127.0.0.1 by default); a fixed pool of connection workers with a
//    bounded queue of accepted connections (beyond it the acceptor waits, and new connections wait
//    in the kernel's backlog); keep-alive with a short idle time-out; read and write time-outs.
//  - A request head (request line + headers) longer than `max_head_bytes` gets 431 before the
//    library parses it; a body longer than its route allows gets 413 before it is read (from its
//    Content-Length, or at once to `Expect: 100-continue`); a body without a length, 411.
//  - Routes are registered with their methods: a path no route matches is 404; a method its route
//    does not take is 405 with `Allow` (HEAD is answered wherever GET is).
//  - With a token: every request must carry it (an `X-Kinesplat-Token` header, a `token=` query
//    parameter, which also sets a cookie for the page's later requests, or that cookie); else 401.
//  - Bound to a loopback address, a request must name it as its Host (no DNS rebinding), and a
//    request that changes something (not GET / HEAD) from a page must come from this origin.
//  - Connections close gracefully: after a refusal the rest of the request is read and dropped
//    for a moment, so the client reads the reply instead of a reset.
#include "web/httplib.hpp"

#include <atomic>
#include <cstddef>
#include <functional>
#include <memory>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace ks {

struct WebServerOptions {
  std::string host = "127.0.0.1";  // numeric IPv4 or IPv6 address to bind
  int port = 8080;                 // 0: any free port (see WebServer::port())
  int threads = 16;                // connection workers
  int queued_connections = 64;     // accepted connections waiting for a worker, at most
  size_t max_head_bytes = 16 * 1024;
  int read_timeout_ms = 10000, write_timeout_ms = 10000;
  int keep_alive_ms = 2000;  // an idle keep-alive connection is closed after this long
  int keep_alive_requests = 100;
  std::string token;  // empty: no token asked for
};

class WebServer {
 public:
  using Request = httplib::Request;
  using Response = httplib::Response;
  using Handler = std::function<void(const Request&, Response&)>;
  using ReaderHandler =
      std::function<void(const Request&, Response&, const httplib::ContentReader&)>;

  // Binds and listens (serving starts with run() or start()). Throws ks::Error when the address
  // is not numeric or cannot be bound (e.g. the port is in use).
  explicit WebServer(const WebServerOptions& opt = {});
  ~WebServer();  // stops and joins every thread
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Routes: `pattern` is a regular expression matched against the whole decoded path (its groups
  // in req.matches). Register before serving starts. `max_body` bounds the request body.
  void get(const std::string& pattern, Handler h);  // GET and HEAD
  void post(const std::string& pattern, Handler h, size_t max_body = 64 * 1024);
  // The handler reads the body itself (streamed, up to max_body bytes). `too_large` words the
  // 413 refusal of a longer body (given its declared length and the limit).
  using TooLarge = std::function<std::string(size_t declared, size_t limit)>;
  void post(const std::string& pattern, ReaderHandler h, size_t max_body, TooLarge too_large = {});
  void del(const std::string& pattern, Handler h);

  int port() const { return port_; }
  const std::string& host() const { return host_; }
  std::string url() const;  // "http://HOST:PORT/" (IPv6 in brackets)

  // Serves on the calling thread until stop() is called or `should_stop` (polled every 100 ms,
  // may be empty) returns true.
  void run(const std::function<bool()>& should_stop = {});
  // Serves on a background thread (for tests); stop() or the destructor ends it.
  void start();
  void stop();
  // True once stop() was called: long replies (event streams) end when they see it.
  bool stopping() const { return stopping_.load(); }

  // Requests answered (any status) so far.
  size_t requests_served() const { return served_.load(); }

  // For a handler: close this connection once the reply is sent (the request's body was not
  // read, say).
  static void close_after_reply(Response& res);
  // A JSON error reply {"error": message} with this status.
  static void reply_error(Response& res, int status, const std::string& message);

 private:
  class Impl;
  struct Route {
    std::string pattern;
    std::regex re;
    std::vector<std::string> methods;
    size_t max_body = 0;
    TooLarge too_large;
  };
  int check(const Request& req, Response& res) const;  // 0: go on; else the status answered
  void add_route(const std::string& pattern, const std::string& method, size_t max_body,
                 TooLarge too_large = {});

  std::unique_ptr<Impl> impl_;
  std::vector<Route> routes_;
  WebServerOptions opt_;
  std::string host_;
  int port_ = 0;
  bool loopback_ = true;
  std::atomic<bool> stopping_{false};
  std::atomic<size_t> served_{0};
  std::thread listener_;
  friend class Impl;
};

}  // namespace ks

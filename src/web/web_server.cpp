#include "web/web_server.hpp"

#include <arpa/inet.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "web/socket_stream.hpp"

namespace ks {

namespace {

// Set by a handler (close_after_reply) on the connection's own worker thread, read by the
// connection loop once the reply is written.
thread_local bool t_close_after_reply = false;

constexpr const char* kTokenCookie = "kinesplat_token";

// The connection workers: a fixed number of threads and a bounded queue; enqueue waits while the
// queue is full (the acceptor then stops accepting until a worker is free).
class BoundedPool : public httplib::TaskQueue {
 public:
  BoundedPool(size_t threads, size_t max_waiting) : max_waiting_(std::max<size_t>(1, max_waiting)) {
    for (size_t i = 0; i < std::max<size_t>(1, threads); ++i)
      threads_.emplace_back([this] { work(); });
  }
  ~BoundedPool() override { shutdown(); }
  void enqueue(std::function<void()> fn) override {
    std::unique_lock<std::mutex> lock(m_);
    space_.wait(lock, [&] { return jobs_.size() < max_waiting_ || closing_; });
    jobs_.push_back(std::move(fn));
    ready_.notify_one();
  }
  void shutdown() override {
    {
      std::lock_guard<std::mutex> lock(m_);
      if (closing_ && threads_.empty()) return;
      closing_ = true;
    }
    ready_.notify_all();
    space_.notify_all();
    for (auto& t : threads_) t.join();
    threads_.clear();
  }

 private:
  void work() {
    for (;;) {
      std::function<void()> fn;
      {
        std::unique_lock<std::mutex> lock(m_);
        ready_.wait(lock, [&] { return closing_ || !jobs_.empty(); });
        if (jobs_.empty()) return;
        fn = std::move(jobs_.front());
        jobs_.pop_front();
        space_.notify_one();
      }
      fn();
    }
  }
  size_t max_waiting_;
  std::mutex m_;
  std::condition_variable ready_, space_;
  std::deque<std::function<void()>> jobs_;
  std::vector<std::thread> threads_;
  bool closing_ = false;
};

bool is_loopback(const std::string& host) {
  in_addr a4{};
  if (::inet_pton(AF_INET, host.c_str(), &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
  return host == "::1";
}

bool equal_constant_time(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char d = 0;
  for (size_t i = 0; i < a.size(); ++i) d |= static_cast<unsigned char>(a[i] ^ b[i]);
  return d == 0;
}

std::string cookie_value(const httplib::Request& req, const std::string& name) {
  const std::string all = req.get_header_value("Cookie");
  size_t p = 0;
  while (p < all.size()) {
    size_t e = all.find(';', p);
    if (e == std::string::npos) e = all.size();
    std::string part = all.substr(p, e - p);
    part.erase(0, part.find_first_not_of(' '));
    if (part.rfind(name + "=", 0) == 0) return part.substr(name.size() + 1);
    p = e + 1;
  }
  return "";
}

// The reason phrases of the statuses this server answers with (the library keeps its table
// inside the shared library).
const char* reason(int status) {
  switch (status) {
    case 400:
      return "Bad Request";
    case 401:
      return "Unauthorized";
    case 403:
      return "Forbidden";
    case 404:
      return "Not Found";
    case 405:
      return "Method Not Allowed";
    case 408:
      return "Request Timeout";
    case 409:
      return "Conflict";
    case 411:
      return "Length Required";
    case 413:
      return "Payload Too Large";
    case 414:
      return "URI Too Long";
    case 415:
      return "Unsupported Media Type";
    case 416:
      return "Range Not Satisfiable";
    case 431:
      return "Request Header Fields Too Large";
    case 500:
      return "Internal Server Error";
    case 503:
      return "Service Unavailable";
    default:
      return status < 500 ? "Client Error" : "Server Error";
  }
}

}  // namespace

// The library's server with kinesplat's connection loop (socket_stream.hpp) in place of its own.
class WebServer::Impl : public httplib::Server {
 public:
  explicit Impl(WebServer& owner) : owner_(owner) {}
  // The library listens with a backlog of 5 (compiled into it); a burst of new connections
  // beyond that would wait for SYN retransmits (1 s). Linux takes a new backlog from a second
  // listen() on the bound socket.
  void widen_backlog(int n) {
    if (svr_sock_ != INVALID_SOCKET) ::listen(svr_sock_, n);
  }

 private:
  bool process_and_close_socket(socket_t sock) override {
    const WebServerOptions& o = owner_.opt_;
    SocketStream conn(sock, o.read_timeout_ms, o.write_timeout_ms);
    bool ok = true;
    for (int left = std::max(1, o.keep_alive_requests); left > 0; --left) {
      if (svr_sock_ == INVALID_SOCKET) break;
      const bool first = left == std::max(1, o.keep_alive_requests);
      const SocketStream::Head h =
          conn.read_head(o.max_head_bytes, first ? o.read_timeout_ms : o.keep_alive_ms);
      if (h == SocketStream::Head::kTooLarge) {
        const std::string body = "431 Request Header Fields Too Large: the request head is over " +
                                 std::to_string(o.max_head_bytes) + " bytes\n";
        conn.write_all(
            "HTTP/1.1 431 Request Header Fields Too Large\r\nContent-Type: text/plain; "
            "charset=utf-8\r\nContent-Length: " +
            std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body);
        owner_.served_++;
        break;
      }
      if (h != SocketStream::Head::kReady) break;
      bool closed = false;
      t_close_after_reply = false;
      ok = process_request(conn, left == 1, closed, nullptr);
      if (!ok || closed || t_close_after_reply) break;
    }
    conn.finish();
    return ok;
  }

  WebServer& owner_;
};

WebServer::WebServer(const WebServerOptions& opt) : impl_(new Impl(*this)), opt_(opt) {
  host_ = opt.host;
  in_addr a4{};
  in6_addr a6{};
  if (::inet_pton(AF_INET, host_.c_str(), &a4) != 1 &&
      ::inet_pton(AF_INET6, host_.c_str(), &a6) != 1)
    throw Error("http server: \"" + host_ + "\" is not a numeric IPv4 or IPv6 address");
  if (opt.port < 0 || opt.port > 65535)
    throw Error("http server: port " + std::to_string(opt.port) + " is outside 0-65535");
  loopback_ = is_loopback(host_);
  Impl& s = *impl_;
  const size_t threads = size_t(std::max(1, opt.threads));
  const size_t queued = size_t(std::max(1, opt.queued_connections));
  s.new_task_queue = [threads, queued] { return new BoundedPool(threads, queued); };
  // SO_REUSEADDR only: the library's default adds SO_REUSEPORT, which would let a second server
  // bind the same port and share its connections.
  s.set_socket_options([](socket_t sock) {
    const int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  s.set_read_timeout(opt.read_timeout_ms / 1000, (opt.read_timeout_ms % 1000) * 1000);
  s.set_write_timeout(opt.write_timeout_ms / 1000, (opt.write_timeout_ms % 1000) * 1000);
  s.set_keep_alive_timeout(std::max(1, (opt.keep_alive_ms + 999) / 1000));
  s.set_keep_alive_max_count(size_t(std::max(1, opt.keep_alive_requests)));
  s.set_pre_routing_handler([this](const Request& req, Response& res) {
    return check(req, res) != 0 ? httplib::Server::HandlerResponse::Handled
                                : httplib::Server::HandlerResponse::Unhandled;
  });
  s.set_expect_100_continue_handler([this](const Request& req, Response& res) {
    return check(req, res) != 0 ? res.status : 100;
  });
  s.set_error_handler([](const Request&, Response& res) {
    if (res.body.empty() && !res.content_provider_)
      res.set_content(std::to_string(res.status) + " " + reason(res.status) + "\n",
                      "text/plain; charset=utf-8");
  });
  s.set_exception_handler([](const Request&, Response& res, std::exception_ptr ep) {
    std::string what = "internal error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    reply_error(res, 500, what);
  });
  s.set_logger([this](const Request&, const Response& res) {
    served_++;
    // After an error the request may not have been read to its end: no next request on it.
    if (res.status >= 400) t_close_after_reply = true;
  });
  httplib::Headers defaults = {{"Cache-Control", "no-store"},
                               {"X-Content-Type-Options", "nosniff"},
                               {"Referrer-Policy", "no-referrer"}};
  s.set_default_headers(defaults);

  errno = 0;
  bool bound;
  if (opt.port == 0) {
    port_ = s.bind_to_any_port(host_);
    bound = port_ > 0;
  } else {
    bound = s.bind_to_port(host_, opt.port);
    port_ = opt.port;
  }
  if (bound) s.widen_backlog(128);
  if (!bound) {
    const std::string why = errno != 0 ? std::string(": ") + std::strerror(errno) : "";
    throw Error("http server: cannot listen on " + host_ + ":" + std::to_string(opt.port) + why +
                (opt.port != 0 ? " (choose another port, or 0 for any free one)" : ""));
  }
}

WebServer::~WebServer() {
  stop();
}

std::string WebServer::url() const {
  const bool v6 = host_.find(':') != std::string::npos;
  return "http://" + (v6 ? "[" + host_ + "]" : host_) + ":" + std::to_string(port_) + "/";
}

void WebServer::add_route(const std::string& pattern, const std::string& method, size_t max_body,
                          TooLarge too_large) {
  for (auto& r : routes_)
    if (r.pattern == pattern) {
      r.methods.push_back(method);
      r.max_body = std::max(r.max_body, max_body);
      if (too_large) r.too_large = too_large;
      return;
    }
  routes_.push_back({pattern, std::regex(pattern), {method}, max_body, too_large});
}

void WebServer::get(const std::string& pattern, Handler h) {
  add_route(pattern, "GET", 0);
  impl_->Get(pattern, std::move(h));
}

void WebServer::post(const std::string& pattern, Handler h, size_t max_body) {
  add_route(pattern, "POST", max_body);
  impl_->Post(pattern, std::move(h));
}

void WebServer::post(const std::string& pattern, ReaderHandler h, size_t max_body,
                     TooLarge too_large) {
  add_route(pattern, "POST", max_body, std::move(too_large));
  impl_->Post(pattern, std::move(h));
  // The library bounds every body by one limit: the largest route's (each route's own limit is
  // checked in check()).
  size_t most = 64 * 1024;
  for (const auto& r : routes_) most = std::max(most, r.max_body);
  impl_->set_payload_max_length(most);
}

void WebServer::del(const std::string& pattern, Handler h) {
  add_route(pattern, "DELETE", 0);
  impl_->Delete(pattern, std::move(h));
}

void WebServer::close_after_reply(Response& res) {
  t_close_after_reply = true;
  res.set_header("Connection", "close");
}

void WebServer::reply_error(Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(nlohmann::json({{"error", message}}).dump() + "\n", "application/json");
}

int WebServer::check(const Request& req, Response& res) const {
  auto refuse = [&](int status, const std::string& message) {
    reply_error(res, status, message);
    close_after_reply(res);
    return status;
  };
  if (!opt_.token.empty()) {
    const std::string given = req.has_header("X-Kinesplat-Token")
                                  ? req.get_header_value("X-Kinesplat-Token")
                              : req.has_param("token") ? req.get_param_value("token")
                                                       : cookie_value(req, kTokenCookie);
    if (!equal_constant_time(given, opt_.token))
      return refuse(401, "this server needs its access token (printed when it started)");
    if (req.has_param("token"))
      res.set_header("Set-Cookie", std::string(kTokenCookie) + "=" + opt_.token +
                                       "; Path=/; HttpOnly; SameSite=Strict");
  }
  if (loopback_) {
    // The Host a browser sends for this address; a name that resolves here by DNS rebinding
    // (evil.example -> 127.0.0.1) is refused.
    const std::string host = req.get_header_value("Host");
    const std::string port = ":" + std::to_string(port_);
    const bool ours = host.empty() || host == host_ + port || host == "localhost" + port ||
                      host == "[" + host_ + "]" + port || host == host_ || host == "localhost";
    if (!ours) return refuse(403, "Host \"" + host + "\" is not this server's address");
  }
  if (req.method != "GET" && req.method != "HEAD" && req.has_header("Origin")) {
    const std::string origin = req.get_header_value("Origin");
    if (origin != "http://" + req.get_header_value("Host"))
      return refuse(403, "a request from another site (Origin " + origin + ") is refused");
  }
  const Route* route = nullptr;
  for (const auto& r : routes_)
    if (std::regex_match(req.path, r.re)) {
      route = &r;
      break;
    }
  if (!route) return refuse(404, "no such page: " + req.path);
  const std::string method = req.method == "HEAD" ? "GET" : req.method;
  if (std::find(route->methods.begin(), route->methods.end(), method) == route->methods.end()) {
    std::string allow;
    for (const auto& m : route->methods) allow += (allow.empty() ? "" : ", ") + m;
    if (std::find(route->methods.begin(), route->methods.end(), "GET") != route->methods.end())
      allow += ", HEAD";
    res.set_header("Allow", allow);
    return refuse(405, req.method + " is not allowed here (allowed: " + allow + ")");
  }
  const bool chunked =
      req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
  if (chunked) return refuse(411, "a request body needs a Content-Length");
  const std::string len = req.get_header_value("Content-Length");
  if (!len.empty()) {
    unsigned long long n = 0;
    try {
      size_t used = 0;
      n = std::stoull(len, &used);
      if (used != len.size()) throw std::invalid_argument(len);
    } catch (const std::exception&) {
      return refuse(400, "Content-Length \"" + len + "\" is not a number");
    }
    if (n > route->max_body && route->too_large)
      return refuse(413, route->too_large(size_t(n), route->max_body));
    if (n > route->max_body)
      return refuse(413, "the request body (" + std::to_string(n) + " bytes) is over the " +
                             std::to_string(route->max_body) + " bytes this page takes");
  }
  return 0;
}

void WebServer::run(const std::function<bool()>& should_stop) {
  start();
  while (!stopping_ && !(should_stop && should_stop()))
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  stop();
}

void WebServer::start() {
  if (listener_.joinable()) return;
  stopping_ = false;
  auto ended = std::make_shared<std::atomic<bool>>(false);
  listener_ = std::thread([this, ended] {
    impl_->listen_after_bind();
    *ended = true;
  });
  // listen_after_bind marks the server running as it begins; stop() before that would be lost.
  while (!impl_->is_running() && !*ended) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void WebServer::stop() {
  stopping_ = true;
  if (listener_.joinable()) {
    impl_->stop();
    listener_.join();
  }
}

}  // namespace ks

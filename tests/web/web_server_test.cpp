// The HTTP server of `kinesplat view` and `studio` (cpp-httplib with kinesplat's limits): files,
// content types, refused paths, 404 / 405, head and body limits, the access token, the Host and
// Origin checks, keep-alive, bounded workers and clients that go away.
#include "web/web_server.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <thread>

#include "core/error.hpp"
#include "http_client.hpp"
#include "temp_dir.hpp"
#include "web/static_files.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

using test::Connection;
using test::get;
using test::Reply;
using test::request;

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

WebServerOptions any_port() {
  WebServerOptions o;
  o.port = 0;
  return o;
}

std::string head_of(int port, const std::string& line, const std::string& headers = "") {
  return line + "\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\n" + headers + "\r\n";
}

TEST(HttpServer, ContentTypes) {
  EXPECT_EQ(mime_type_for("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(mime_type_for("a/kinesplat-viewer.js"), "text/javascript; charset=utf-8");
  EXPECT_EQ(mime_type_for("x.WASM"), "application/wasm");
  EXPECT_EQ(mime_type_for("avatar.ply"), "application/octet-stream");
  EXPECT_EQ(mime_type_for("motions.json"), "application/json");
  EXPECT_EQ(mime_type_for("shot.png"), "image/png");
  EXPECT_EQ(mime_type_for("turntable.mp4"), "video/mp4");
  EXPECT_EQ(mime_type_for("noext"), "application/octet-stream");
}

TEST(HttpServer, ResolvesAndRefusesPaths) {
  test::TempDir dir("http_resolve");
  const fs::path root = dir.path() / "site";
  write(root / "a" / "b.json", "{}");
  EXPECT_EQ(resolve_request_path(root, "/a/b.json?x=1#y"), root / "a" / "b.json");
  EXPECT_EQ(resolve_request_path(root, "/a/./b%2Ejson"), root / "a" / "b.json");
  EXPECT_EQ(resolve_request_path(root, "/"), root / "index.html");
  EXPECT_EQ(resolve_request_path(root, "//a//b.json"), root / "a" / "b.json");
  for (const char* bad : {"a/b.json", "/../x", "/a/../../x", "/a/%2e%2e/%2e%2e/x", "/%2E%2E/x",
                          "/a%5c..%5cx", "/a%00.json", "/bad%zzescape", "/trailing%2", ""})
    EXPECT_FALSE(resolve_request_path(root, bad)) << bad;
}

TEST(HttpServer, ServesFilesAndRefusesTraversal) {
  test::TempDir dir("http_serve");
  const fs::path root = dir.path() / "site";
  write(root / "index.html", "<!doctype html><p>hi</p>");
  std::string wasm("\0asm\1\0\0\0", 8);
  write(root / "lib" / "x.wasm", wasm);
  std::string big(300000, '\0');
  for (size_t i = 0; i < big.size(); ++i) big[i] = char(i * 7 % 251);
  write(root / "avatar.ply", big);
  write(dir.path() / "secret.txt", "top secret");
  fs::create_symlink(dir.path() / "secret.txt", root / "link.txt");

  WebServer server(any_port());
  serve_folder(server, "", root);
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(server.url(), "http://127.0.0.1:" + std::to_string(server.port()) + "/");
  server.start();
  const int port = server.port();

  Reply r = get(port, "/");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "text/html; charset=utf-8");
  EXPECT_EQ(r.header("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(r.body, "<!doctype html><p>hi</p>");
  r = get(port, "/lib/x.wasm");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "application/wasm");
  EXPECT_EQ(r.body, wasm);
  r = get(port, "/avatar.ply?v=2");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "application/octet-stream");
  EXPECT_EQ(r.header("Content-Length"), std::to_string(big.size()));
  EXPECT_TRUE(r.body == big);
  r = get(port, "/avatar.ply", "HEAD");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Length"), std::to_string(big.size()));
  r = get(port, "/avatar.ply", "GET", "Range: bytes=1000-1999\r\n");  // as video players ask
  EXPECT_EQ(r.status, 206);
  EXPECT_TRUE(r.body == big.substr(1000, 1000));

  EXPECT_EQ(get(port, "/missing.js").status, 404);
  EXPECT_EQ(get(port, "/lib/").status, 404);  // a folder without index.html
  EXPECT_EQ(get(port, "/index.html", "POST").status, 405);
  EXPECT_EQ(get(port, "/index.html", "PUT").header("Allow"), "GET, HEAD");
  EXPECT_EQ(get(port, "/index.html", "DELETE").status, 405);
  EXPECT_EQ(get(port, "/index.html", "TRACE").status, 405);
  for (const char* t :
       {"/../secret.txt", "/lib/../../secret.txt", "/%2e%2e/secret.txt",
        "/lib/%2E%2E/%2e%2e/secret.txt", "/link.txt", "/%2e%2e%2fsecret.txt", "/..%5csecret.txt"}) {
    r = get(port, t);
    EXPECT_EQ(r.status, 403) << t;
    EXPECT_EQ(r.body.find("top secret"), std::string::npos) << t;
  }
  r = get(port, "..%2fsecret.txt");  // not a path at all
  EXPECT_GE(r.status, 400);
  EXPECT_EQ(r.body.find("top secret"), std::string::npos);
  EXPECT_EQ(request(port, "garbage\r\n\r\n").status, 400);
  server.stop();
  EXPECT_GE(server.requests_served(), 20u);
}

TEST(HttpServer, RefusesOversizedHeads) {
  WebServer server(any_port());
  server.get("/", [](const WebServer::Request&, WebServer::Response& res) {
    res.set_content("ok", "text/plain");
  });
  server.start();
  const int port = server.port();
  // A long request line, and many short headers (the library bounds each line, not their sum).
  EXPECT_EQ(request(port, "GET /" + std::string(20000, 'a') + " HTTP/1.1\r\n\r\n").status, 431);
  std::string many;
  for (int i = 0; i < 2000; ++i) many += "X-Filler-" + std::to_string(i) + ": 0123456789\r\n";
  const Reply r = request(port, head_of(port, "GET / HTTP/1.1", many));
  EXPECT_EQ(r.status, 431);
  EXPECT_NE(r.body.find("over 16384 bytes"), std::string::npos) << r.body;
  // One header line over the library's 8 KiB line limit, the head under ours: refused too.
  EXPECT_EQ(
      request(port, head_of(port, "GET / HTTP/1.1", "X-A: " + std::string(9000, 'b') + "\r\n"))
          .status,
      400);
  EXPECT_EQ(get(port, "/").status, 200);  // and the server goes on
}

TEST(HttpServer, BodyLimitsAnsweredBeforeTheBody) {
  std::atomic<size_t> got{0};
  std::atomic<int> incomplete{0};
  WebServer server(any_port());
  server.post(
      "/up",
      [&](const WebServer::Request&, WebServer::Response& res, const httplib::ContentReader& rd) {
        size_t n = 0;
        const bool ok = rd([&](const char*, size_t len) {
          n += len;
          return true;
        });
        if (!ok) {
          incomplete++;
          return;
        }
        got = n;
        res.set_content(std::to_string(n), "text/plain");
      },
      1000000);
  server.post("/small", [](const WebServer::Request& req, WebServer::Response& res) {
    res.set_content(std::to_string(req.body.size()), "text/plain");
  });
  server.start();
  const int port = server.port();

  // The head alone: the refusal comes without the body being sent.
  {
    Connection c(port);
    ASSERT_TRUE(c.send(head_of(port, "POST /up HTTP/1.1", "Content-Length: 60000000\r\n")));
    const Reply r = c.read_reply(3);
    EXPECT_EQ(r.status, 413);
    EXPECT_NE(r.body.find("60000000 bytes"), std::string::npos) << r.body;
    EXPECT_EQ(r.header("Connection"), "close");
  }
  // A client that sends the body anyway still reads the refusal (no reset).
  {
    Connection c(port);
    ASSERT_TRUE(c.send(head_of(port, "POST /up HTTP/1.1", "Content-Length: 3000000\r\n")));
    c.send(std::string(3000000, 'x'));
    EXPECT_EQ(c.read_reply(5).status, 413);
  }
  // Expect: 100-continue: refused instead of "100 Continue", or continued.
  {
    Connection c(port);
    ASSERT_TRUE(c.send(
        head_of(port, "POST /up HTTP/1.1", "Content-Length: 2000000\r\nExpect: 100-continue\r\n")));
    const std::string first = c.read_some(3);
    EXPECT_EQ(first.rfind("HTTP/1.1 413", 0), 0u) << first;
  }
  {
    Connection c(port);
    ASSERT_TRUE(c.send(
        head_of(port, "POST /up HTTP/1.1", "Content-Length: 5\r\nExpect: 100-continue\r\n")));
    const std::string first = c.read_some(3);
    EXPECT_EQ(first.rfind("HTTP/1.1 100 Continue", 0), 0u) << first;
    c.send("hello");
    const Reply r = c.read_reply(3);
    EXPECT_EQ(r.status, 200);
    EXPECT_EQ(r.body, "5");
  }
  EXPECT_EQ(
      request(port, head_of(port, "POST /small HTTP/1.1", "Content-Length: 70000\r\n")).status,
      413);
  EXPECT_EQ(request(port, head_of(port, "POST /small HTTP/1.1", "Transfer-Encoding: chunked\r\n") +
                              "5\r\nhello\r\n0\r\n\r\n")
                .status,
            411);
  EXPECT_EQ(request(port, head_of(port, "POST /small HTTP/1.1", "Content-Length: 12x\r\n")).status,
            400);
  // A client that goes away mid-body: the handler sees an incomplete body; the server goes on.
  {
    Connection c(port);
    ASSERT_TRUE(c.send(head_of(port, "POST /up HTTP/1.1", "Content-Length: 500000\r\n")));
    c.send(std::string(100000, 'y'));
    c.close();
  }
  for (int i = 0; i < 100 && incomplete == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(incomplete.load(), 1);
  const Reply ok =
      request(port, head_of(port, "POST /up HTTP/1.1", "Content-Length: 4\r\n") + "abcd");
  EXPECT_EQ(ok.status, 200);
  EXPECT_EQ(got.load(), 4u);
}

TEST(HttpServer, KeepsConnectionsAliveAndBoundsWorkers) {
  WebServerOptions o = any_port();
  o.threads = 2;
  o.queued_connections = 1;
  o.read_timeout_ms = 400;
  WebServer server(o);
  server.get("/", [](const WebServer::Request&, WebServer::Response& res) {
    res.set_content("ok", "text/plain");
  });
  server.start();
  const int port = server.port();
  {
    Connection c(port);  // three requests on one connection
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE(c.send(head_of(port, "GET / HTTP/1.1")));
      const Reply r = c.read_reply(3);
      EXPECT_EQ(r.status, 200) << i;
      EXPECT_EQ(r.body, "ok");
    }
  }
  // Two clients that connect and say nothing hold both workers until the read time-out; a third
  // is answered once one of them is dropped.
  Connection idle1(port), idle2(port);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const auto t0 = std::chrono::steady_clock::now();
  const Reply r = get(port, "/");
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.status, 200);
  EXPECT_GT(waited, 0.2);
  EXPECT_LT(waited, 3.0);
  EXPECT_TRUE(idle1.closed_within(2));
}

TEST(HttpServer, TokenHostAndOrigin) {
  WebServerOptions o = any_port();
  o.token = "s3cr3t";
  WebServer server(o);
  server.get("/", [](const WebServer::Request&, WebServer::Response& res) {
    res.set_content("ok", "text/plain");
  });
  server.post("/do", [](const WebServer::Request&, WebServer::Response& res) {
    res.set_content("done", "text/plain");
  });
  server.start();
  const int port = server.port();
  EXPECT_EQ(get(port, "/").status, 401);
  EXPECT_EQ(get(port, "/nothing-here").status, 401);  // before routing: nothing is revealed
  EXPECT_EQ(get(port, "/?token=wrong").status, 401);
  EXPECT_EQ(get(port, "/", "GET", "X-Kinesplat-Token: s3cr3t\r\n").status, 200);
  const Reply q = get(port, "/?token=s3cr3t");
  EXPECT_EQ(q.status, 200);
  EXPECT_NE(q.header("Set-Cookie").find("kinesplat_token=s3cr3t"), std::string::npos);
  EXPECT_NE(q.header("Set-Cookie").find("HttpOnly"), std::string::npos);
  EXPECT_EQ(get(port, "/", "GET", "Cookie: a=b; kinesplat_token=s3cr3t\r\n").status, 200);
  EXPECT_EQ(get(port, "/", "GET", "Cookie: kinesplat_token=s3cr3\r\n").status, 401);
  // Another name for this address (DNS rebinding) and another site's page are refused.
  EXPECT_EQ(request(port, "GET /?token=s3cr3t HTTP/1.1\r\nHost: evil.example:" +
                              std::to_string(port) + "\r\nConnection: close\r\n\r\n")
                .status,
            403);
  EXPECT_EQ(request(port, "GET /?token=s3cr3t HTTP/1.1\r\nHost: localhost:" + std::to_string(port) +
                              "\r\nConnection: close\r\n\r\n")
                .status,
            200);
  const std::string tok = "X-Kinesplat-Token: s3cr3t\r\nContent-Length: 0\r\n";
  EXPECT_EQ(get(port, "/do", "POST", tok + "Origin: http://evil.example\r\n").status, 403);
  EXPECT_EQ(
      get(port, "/do", "POST", tok + "Origin: http://127.0.0.1:" + std::to_string(port) + "\r\n")
          .status,
      200);
  EXPECT_EQ(get(port, "/do", "POST", tok).status, 200);  // not from a page (curl)
}

TEST(HttpServer, ReportsABusyPortAndABadAddress) {
  WebServer first(any_port());
  WebServerOptions o;
  o.port = first.port();
  try {
    WebServer second(o);
    FAIL() << "a second server bound the same port";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1:" + std::to_string(o.port)),
              std::string::npos)
        << e.what();
  }
  o.port = 0;
  o.host = "localhost";
  EXPECT_THROW(WebServer{o}, Error);
  o.host = "127.0.0.1";
  o.port = 70000;
  EXPECT_THROW(WebServer{o}, Error);
}

}  // namespace
}  // namespace ks

// The static HTTP server of `kinesplat view`: files, content types, 404, 405, and refused paths.
#include "web/http_server.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

struct Reply {
  int status = 0;
  std::string head, body;
  std::string header(const std::string& name) const {
    const std::string key = "\r\n" + name + ": ";
    const size_t p = head.find(key);
    if (p == std::string::npos) return "";
    const size_t s = p + key.size();
    return head.substr(s, head.find("\r\n", s) - s);
  }
};

// Sends `request` verbatim (no client-side path normalisation) and reads until the server closes.
Reply raw_request(int port, const std::string& request) {
  Reply r;
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(uint16_t(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    return r;
  }
  ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string all;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    all.append(buf, size_t(n));
  }
  ::close(fd);
  const size_t end = all.find("\r\n\r\n");
  if (end == std::string::npos) return r;
  r.head = all.substr(0, end + 2);
  r.body = all.substr(end + 4);
  if (r.head.rfind("HTTP/1.1 ", 0) == 0) r.status = std::stoi(r.head.substr(9, 3));
  return r;
}

Reply get(int port, const std::string& target, const std::string& method = "GET") {
  return raw_request(port, method + " " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
}

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

TEST(HttpServer, ContentTypes) {
  EXPECT_EQ(mime_type_for("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(mime_type_for("a/kinesplat-viewer.js"), "text/javascript; charset=utf-8");
  EXPECT_EQ(mime_type_for("x.WASM"), "application/wasm");
  EXPECT_EQ(mime_type_for("avatar.ply"), "application/octet-stream");
  EXPECT_EQ(mime_type_for("motions.json"), "application/json");
  EXPECT_EQ(mime_type_for("shot.png"), "image/png");
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

  HttpServerOptions opt;
  opt.port = 0;
  StaticHttpServer server(root.string(), opt);
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(server.url(), "http://127.0.0.1:" + std::to_string(server.port()) + "/");
  server.start();
  const int port = server.port();

  Reply r = get(port, "/");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.header("Content-Type"), "text/html; charset=utf-8");
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
  EXPECT_EQ(r.body, "");

  EXPECT_EQ(get(port, "/missing.js").status, 404);
  EXPECT_EQ(get(port, "/lib/").status, 404);  // a folder without index.html
  EXPECT_EQ(get(port, "/index.html", "POST").status, 405);
  EXPECT_EQ(get(port, "/index.html", "PUT").header("Allow"), "GET, HEAD");
  for (const char* t : {"/../secret.txt", "/lib/../../secret.txt", "/%2e%2e/secret.txt",
                        "/link.txt", "..%2fsecret.txt"}) {
    r = get(port, t);
    EXPECT_EQ(r.status, 403) << t;
    EXPECT_EQ(r.body.find("top secret"), std::string::npos) << t;
  }
  EXPECT_EQ(raw_request(port, "garbage\r\n\r\n").status, 400);
  EXPECT_EQ(raw_request(port, "GET /" + std::string(20000, 'a') + " HTTP/1.1\r\n\r\n").status, 431);
  server.stop();
  EXPECT_EQ(server.requests_served(), 15u);
}

TEST(HttpServer, ReportsABusyPortAndABadRoot) {
  test::TempDir dir("http_busy");
  HttpServerOptions opt;
  opt.port = 0;
  StaticHttpServer first(dir.path().string(), opt);
  opt.port = first.port();
  try {
    StaticHttpServer second(dir.path().string(), opt);
    FAIL() << "a second server bound the same port";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot listen on 127.0.0.1:" + std::to_string(opt.port)),
              std::string::npos)
        << e.what();
  }
  opt.port = 0;
  EXPECT_THROW(StaticHttpServer((dir.path() / "nope").string(), opt), Error);
}

}  // namespace
}  // namespace ks

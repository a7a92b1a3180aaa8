// The studio's server with a stand-in kinesplat (fake_kinesplat.hpp): uploads and their refusals,
// the queue (one at a time, the rest waiting), progress, cancel, failure and resume, a studio
// stopped mid-create seen as interrupted next time, downloads, removal, the event stream, 404 /
// 405 and path traversal on every route.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "core/fileio.hpp"
#include "fake_kinesplat.hpp"
#include "http_client.hpp"
#include "io/image_io.hpp"
#include "studio/studio.hpp"
#include "studio/studio_routes.hpp"
#include "temp_dir.hpp"
#include "web/web_server.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {
namespace {

using test::Connection;
using test::Reply;

// A process that still runs (not gone, and not a zombie waiting for a parent to reap it) a
// moment later: a process that closed its files may still be on its way out.
bool running(pid_t pid) {
  for (int i = 0; i < 100; ++i) {
    std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!std::getline(stat, line)) return false;
    const size_t p = line.rfind(')');
    if (p == std::string::npos || p + 2 >= line.size() || line[p + 2] == 'Z') return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

std::string png_bytes(int w = 24, int h = 36) {
  Image img(w, h, 3, 0.5f);
  for (int y = 0; y < h; ++y) img.at(w / 2, y, 0) = 1.f;
  const std::vector<uint8_t> b = encode_png(img);
  return std::string(b.begin(), b.end());
}

std::string jpeg_bytes() {
  cv::Mat m(40, 30, CV_8UC3, cv::Scalar(40, 120, 200));
  std::vector<uint8_t> b;
  cv::imencode(".jpg", m, b);
  return std::string(b.begin(), b.end());
}

class StudioServer : public ::testing::Test {
 protected:
  test::TempDir dir{"studio_server"};
  fs::path ws = dir.path() / "ws";
  std::string fail_file = (dir.path() / "fail").string();
  std::string pid_file = (dir.path() / "pids").string();
  std::unique_ptr<Studio> studio;
  std::unique_ptr<WebServer> server;
  int port = 0;

  void start(double sleep_seconds = 0.2, size_t max_photo = size_t(1) << 20) {
    StudioOptions o;
    o.workspace = ws.string();
    o.program = test::fake_kinesplat(dir.path(), sleep_seconds, fail_file, pid_file);
    o.page_dir = std::string(KS_SOURCE_DIR) + "/studio";
    o.max_photo_bytes = max_photo;
    o.event_stream_seconds = 3;
    o.event_ping_seconds = 0.5;
    o.max_event_streams = 2;
    studio = std::make_unique<Studio>(o);
    WebServerOptions so;
    so.port = 0;
    server = std::make_unique<WebServer>(so);
    add_studio_routes(*server, *studio);
    server->start();
    port = server->port();
  }
  void stop() {
    studio->shutdown();
    server->stop();
    server.reset();
    studio.reset();
  }
  void TearDown() override {
    if (studio) stop();
  }
  std::string host() const { return "Host: 127.0.0.1:" + std::to_string(port) + "\r\n"; }
  Reply call(const std::string& method, const std::string& target, const std::string& body = "",
             const std::string& headers = "") {
    return test::request(port, method + " " + target + " HTTP/1.1\r\n" + host() + headers +
                                   "Content-Length: " + std::to_string(body.size()) +
                                   "\r\nConnection: close\r\n\r\n" + body);
  }
  Reply upload(const std::string& bytes, const std::string& name = "me.png") {
    return call("POST", "/api/avatars", bytes, "X-Filename: " + name + "\r\n");
  }
  json state() { return json::parse(call("GET", "/api/state").body); }
  json avatar(const std::string& id) { return json::parse(call("GET", "/api/avatars/" + id).body); }
  // Waits until the avatar is in `want` (its JSON then; the last seen on a time-out).
  json wait_for(const std::string& id, const std::string& want, double seconds = 20) {
    json a;
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      a = avatar(id);
      if (a.value("state", "") == want) return a;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return a;
  }
  std::string new_avatar(const std::string& bytes = png_bytes(),
                         const std::string& name = "me.png") {
    const Reply r = upload(bytes, name);
    EXPECT_EQ(r.status, 201) << r.body;
    return json::parse(r.body).value("id", "");
  }
  size_t leftovers() {
    size_t n = 0;
    for (const auto& e : fs::directory_iterator(ws / "uploads")) n += bool(e.path().c_str());
    return n;
  }
};

TEST_F(StudioServer, UploadsAreCheckedAndNamedByTheServer) {
  start();
  EXPECT_EQ(call("GET", "/").status, 200);
  EXPECT_NE(call("GET", "/").body.find("kinesplat studio"), std::string::npos);
  EXPECT_EQ(call("GET", "/static/app.js").header("Content-Type"), "text/javascript; charset=utf-8");
  const json s0 = state();
  EXPECT_EQ(s0["limits"]["photo_bytes"], 1 << 20);
  EXPECT_TRUE(s0["avatars"].empty());

  // Not an image (whatever its name says), an image type create does not read, an empty body,
  // a PNG that does not decode: refused, nothing kept.
  Reply r = upload("<html><script>alert(1)</script></html>", "photo.png");
  EXPECT_EQ(r.status, 415);
  EXPECT_NE(r.body.find("not a PNG or JPEG image"), std::string::npos) << r.body;
  r = upload("GIF89a\x01\x00\x01\x00\x00\x00\x00", "x.gif");
  EXPECT_EQ(r.status, 415);
  r = upload("", "x.png");
  EXPECT_EQ(r.status, 400);
  EXPECT_NE(r.body.find("empty"), std::string::npos) << r.body;
  r = upload(std::string("\x89PNG\r\n\x1a\n", 8) + std::string(500, 'z'), "broken.png");
  EXPECT_EQ(r.status, 415);
  EXPECT_NE(r.body.find("cannot be read"), std::string::npos) << r.body;
  // Too large, by its Content-Length, before any of it is sent.
  {
    Connection c(port);
    ASSERT_TRUE(
        c.send("POST /api/avatars HTTP/1.1\r\n" + host() + "Content-Length: 5000000\r\n\r\n"));
    const Reply big = c.read_reply(3);
    EXPECT_EQ(big.status, 413);
    EXPECT_NE(big.body.find("the photo is 4.8 MB, over the 1 MB the studio takes"),
              std::string::npos)
        << big.body;
  }
  // A client gone mid-upload.
  {
    Connection c(port);
    ASSERT_TRUE(c.send("POST /api/avatars HTTP/1.1\r\n" + host() +
                       "Content-Length: 900000\r\n\r\n" + png_bytes().substr(0, 60)));
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(leftovers(), 0u) << "a refused or cut-off upload left a file";
  EXPECT_TRUE(state()["avatars"].empty());

  // A JPEG, its name a traversal attempt: stored as photo.jpg inside its own folder.
  const std::string id = new_avatar(jpeg_bytes(), "..%2F..%2F..%2Fetc%2Fpasswd.jpg");
  const json a = avatar(id);
  EXPECT_EQ(a["label"], "passwd.jpg");
  EXPECT_TRUE(fs::is_regular_file(ws / "avatars" / id / "photo.jpg"));
  EXPECT_EQ(leftovers(), 0u);
  const Reply photo = call("GET", "/api/avatars/" + id + "/files/photo?download=1");
  EXPECT_EQ(photo.status, 200);
  EXPECT_EQ(photo.header("Content-Type"), "image/jpeg");
  EXPECT_EQ(photo.header("Content-Disposition"),
            "attachment; filename=\"kinesplat-" + id + "-photo.jpg\"");
  EXPECT_TRUE(photo.body == jpeg_bytes());
}

TEST_F(StudioServer, MakesQueuedAvatarsOneAtATimeWithDownloads) {
  start(1.0);
  const std::string first = new_avatar(png_bytes(), "first.png");
  const std::string second = new_avatar(png_bytes(30, 40), "second.png");
  json a = wait_for(first, "running");
  EXPECT_EQ(avatar(second)["state"], "queued");
  EXPECT_EQ(avatar(second)["position"], 1);
  // Progress as create prints it.
  for (int i = 0;
       i < 100 && a.value("progress", json::object()).value("stage", "") != "reconstruct"; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    a = avatar(first);
  }
  EXPECT_EQ(a["progress"]["stage"], "reconstruct");
  EXPECT_GT(a["progress"]["percent"].get<double>(), 5);
  EXPECT_EQ(a["progress"]["stages"][0]["status"], "done");
  EXPECT_EQ(a["progress"]["stages"][5]["status"], "running");
  EXPECT_NEAR(a["progress"]["stages"][5]["percent"].get<double>(), 10, 1e-9);

  a = wait_for(first, "done");
  ASSERT_EQ(a["state"], "done") << a.dump(1);
  EXPECT_EQ(a["viewer"], "/avatars/" + first + "/web/");
  std::vector<std::string> names;
  for (const auto& d : a["downloads"]) names.push_back(d["name"]);
  EXPECT_EQ(names,
            (std::vector<std::string>{"avatar.ksavatar", "avatar.ply", "avatar.glb", "web.zip"}));
  ASSERT_EQ(a["videos"].size(), 2u);
  EXPECT_EQ(a["videos"][0]["name"], "turntable");
  EXPECT_EQ(a["videos"][1]["name"], "dance");
  // The downloads are the files on disk, byte for byte; the viewer site is served.
  const Reply ks = call("GET", a["downloads"][0]["url"].get<std::string>());
  EXPECT_EQ(ks.status, 200);
  EXPECT_EQ(ks.body,
            read_file_text((ws / "avatars" / first / "create" / "avatar.ksavatar").string()));
  EXPECT_EQ(call("GET", "/api/avatars/" + first + "/files/dance.mp4").header("Content-Type"),
            "video/mp4");
  EXPECT_NE(call("GET", "/avatars/" + first + "/web/").body.find("viewer"), std::string::npos);
  EXPECT_EQ(call("GET", "/avatars/" + first + "/web").status, 301);
  // The GLB export got create's motions as animations (the fake's command line, in the log).
  const std::string log = call("GET", "/api/avatars/" + first + "/files/job.log").body;
  EXPECT_NE(log.find("--gltf " + (ws / "avatars" / first / "exports" / "avatar.glb").string() +
                     " --motion dance"),
            std::string::npos)
      << log;
  // The second runs only after the first: one create at a time.
  EXPECT_EQ(wait_for(second, "done")["state"], "done");
  // Deleting a made avatar removes its folder.
  EXPECT_EQ(call("DELETE", "/api/avatars/" + first).status, 200);
  EXPECT_FALSE(fs::exists(ws / "avatars" / first));
  EXPECT_EQ(call("GET", "/api/avatars/" + first).status, 404);
  EXPECT_EQ(state()["avatars"].size(), 1u);
}

TEST_F(StudioServer, CancelFailResume) {
  start(30);
  const std::string id = new_avatar();
  const std::string queued = new_avatar();
  wait_for(id, "running");
  // Not while it runs.
  EXPECT_EQ(call("DELETE", "/api/avatars/" + id).status, 409);
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/resume").status, 409);
  // A queued one leaves the queue; the running one is stopped, its processes too.
  EXPECT_EQ(call("POST", "/api/avatars/" + queued + "/cancel").status, 200);
  EXPECT_EQ(avatar(queued)["state"], "cancelled");
  for (int i = 0; i < 100 && !fs::exists(pid_file); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/cancel").status, 200);
  json a = wait_for(id, "cancelled", 10);
  EXPECT_EQ(a["state"], "cancelled");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  EXPECT_EQ(a["error_stage"], "reconstruct");
  {
    std::istringstream pids(read_file_text(pid_file));
    pid_t shell = 0, sleeper = 0;
    pids >> shell >> sleeper;
    ASSERT_GT(sleeper, 0);
    EXPECT_FALSE(running(sleeper)) << "create's own child outlived the cancel";
  }
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/cancel").status, 409);  // nothing to cancel

  // Failing in fit: the error line and the stage; resumed once the cause is gone.
  stop();
  std::ofstream(fail_file) << "x";
  start(0.1);
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/resume").status, 200);
  a = wait_for(id, "failed");
  ASSERT_EQ(a["state"], "failed") << a.dump(1);
  EXPECT_EQ(a["error"], "fit: no person found in the photo");
  EXPECT_EQ(a["error_stage"], "fit");
  fs::remove(fail_file);
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/resume").status, 200);
  EXPECT_EQ(wait_for(id, "done")["state"], "done");
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/resume").status, 409);  // already made
}

TEST_F(StudioServer, AStudioStoppedMidCreateShowsItInterrupted) {
  start(30);
  const std::string id = new_avatar();
  const std::string waiting = new_avatar();
  wait_for(id, "running");
  for (int i = 0; i < 100 && !fs::exists(pid_file); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const auto t0 = std::chrono::steady_clock::now();
  stop();  // as on SIGINT / SIGTERM
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 6.0);
  pid_t shell = 0, sleeper = 0;
  std::istringstream(read_file_text(pid_file)) >> shell >> sleeper;
  EXPECT_FALSE(running(sleeper)) << "create outlived the studio";
  start(0.1);
  json a = avatar(id);
  EXPECT_EQ(a["state"], "interrupted");
  EXPECT_EQ(avatar(waiting)["state"], "interrupted");
  EXPECT_EQ(call("POST", "/api/avatars/" + id + "/resume").status, 200);
  EXPECT_EQ(wait_for(id, "done")["state"], "done");
  EXPECT_EQ(avatar(waiting)["state"], "interrupted");  // each is resumed by hand
}

TEST_F(StudioServer, EventStream) {
  start(0.3);
  Connection c(port);
  ASSERT_TRUE(c.send("GET /api/events HTTP/1.1\r\n" + host() + "\r\n"));
  std::string got = c.read_some(2);
  EXPECT_NE(got.find("text/event-stream"), std::string::npos) << got;
  for (int i = 0; i < 20 && got.find("event: state") == std::string::npos; ++i)
    got += c.read_some(0.2);
  EXPECT_NE(got.find("\"avatars\":[]"), std::string::npos) << got;
  const std::string id = new_avatar();
  std::string more;
  for (int i = 0; i < 40 && more.find(id) == std::string::npos; ++i) more += c.read_some(0.2);
  EXPECT_NE(more.find("event: state"), std::string::npos);
  EXPECT_NE(more.find(id), std::string::npos) << "no event after an upload";
  // At most two streams here; a third is refused; a stream whose client went away is freed.
  Connection c2(port);
  ASSERT_TRUE(c2.send("GET /api/events HTTP/1.1\r\n" + host() + "\r\n"));
  c2.read_some(0.5);
  EXPECT_EQ(call("GET", "/api/events").status, 503);
  c2.close();
  c.close();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // a ping finds them gone
  Connection c3(port);
  ASSERT_TRUE(c3.send("GET /api/events HTTP/1.1\r\n" + host() + "\r\n"));
  EXPECT_NE(c3.read_some(1).find("200 OK"), std::string::npos);
  // A stream ends by itself after a while (3 s here): the page reconnects.
  const auto t0 = std::chrono::steady_clock::now();
  std::string tail;
  while (tail.find("\r\n0\r\n\r\n") == std::string::npos &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(6))
    tail += c3.read_some(0.2);
  EXPECT_NE(tail.find("\r\n0\r\n\r\n"), std::string::npos) << "the stream did not end";
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 4.5);
}

TEST_F(StudioServer, UnknownRoutesWrongMethodsAndTraversal) {
  start();
  const std::string id = new_avatar();
  wait_for(id, "done");
  std::ofstream(dir.path() / "secret.txt") << "top secret";
  fs::create_symlink(dir.path() / "secret.txt", ws / "avatars" / id / "web" / "link.txt");
  for (const char* t : {"/nope", "/api", "/api/nope",
                        "/api/avatars/"
                        "x/nope",
                        "/index.html", "/avatars/", "/static"})
    EXPECT_EQ(call("GET", t).status, t == std::string("/static") ? 301 : 404) << t;
  EXPECT_EQ(call("PUT", "/api/state").status, 405);
  EXPECT_EQ(call("POST", "/api/state").header("Allow"), "GET, HEAD");
  EXPECT_EQ(call("GET", "/api/avatars").status, 405);
  EXPECT_EQ(call("GET", "/api/avatars").header("Allow"), "POST");
  EXPECT_EQ(call("POST", "/api/avatars/" + id).status, 405);
  EXPECT_EQ(call("GET", "/api/avatars/" + id + "/resume").status, 405);
  EXPECT_EQ(call("DELETE", "/api/avatars/" + id + "/files/photo").status, 405);
  // Every route that takes a path or a name, with the usual ways out of the workspace.
  const std::string a = "/api/avatars/" + id;
  const std::vector<std::string> attacks = {
      "/static/../../../../etc/passwd",
      "/static/%2e%2e/%2e%2e/secret.txt",
      "/static/..%2f..%2fsecret.txt",
      "/api/avatars/..",
      "/api/avatars/%2e%2e",
      "/api/avatars/..%2F..%2F..%2Fsecret.txt",
      "/api/avatars/../../secret.txt/files/photo",
      a + "/files/..%2f..%2f..%2fsecret.txt",
      a + "/files/..",
      a + "/files/studio.json",
      a + "/files/create%2fcreate.json",
      a + "/files/%2e%2e%2fstudio.json",
      "/avatars/" + id + "/web/../../../secret.txt",
      "/avatars/" + id + "/web/%2e%2e/studio.json",
      "/avatars/" + id + "/web/..%2f..%2f..%2f..%2fsecret.txt",
      "/avatars/" + id + "/web/link.txt",
      "/avatars/" + id + "/web/%5c..%5cstudio.json",
      "/avatars/..%2f" + id + "/web/index.html",
      "/avatars/" + id + "/w%65b/index.html"};
  for (const auto& t : attacks) {
    const Reply r = call("GET", t);
    EXPECT_TRUE(r.status == 403 || r.status == 404) << t << " -> " << r.status;
    EXPECT_EQ(r.body.find("top secret"), std::string::npos) << t;
    EXPECT_EQ(r.body.find("kinesplat-studio-avatar"), std::string::npos) << t;  // studio.json
  }
  for (const char* m : {"DELETE", "POST"})
    for (const std::string& t : std::vector<std::string>{
             "/api/avatars/..", "/api/avatars/..%2f..%2fws", "/api/avatars/" + id + "%2f..%2f.."}) {
      const std::string target = std::string(m) == "POST" ? t + "/resume" : t;
      EXPECT_EQ(call(m, target).status, 404) << m << " " << target;
    }
  EXPECT_TRUE(fs::exists(ws / "avatars" / id / "studio.json"));
  EXPECT_TRUE(fs::exists(dir.path() / "secret.txt"));
  // From another site's page: refused.
  EXPECT_EQ(call("DELETE", "/api/avatars/" + id, "", "Origin: http://evil.example\r\n").status,
            403);
  EXPECT_TRUE(fs::exists(ws / "avatars" / id));
}

}  // namespace
}  // namespace ks

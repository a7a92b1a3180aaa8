// The studio answers while a create runs: bounded loads on loopback while `kinesplat create` (the
// real one, small settings) is in reconstruct, which keeps both cores busy: 4 keep-alive clients
// asking for the page, its script, the state and the avatar every 5 ms each for 4 s, then 8 as
// fast as they can for 1 s, then a burst of 64 new connections at once.
// Needs the perceive helper and ffmpeg (create's); skipped, saying which, without.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>

#include "core/fileio.hpp"
#include "http_client.hpp"
#include "io/video.hpp"
#include "perceive/helper.hpp"
#include "studio/studio.hpp"
#include "studio/studio_routes.hpp"
#include "temp_dir.hpp"
#include "web/web_server.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {
namespace {

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

TEST(StudioLoad, PageAnswersWhileACreateRuns) {
  if (find_ffmpeg().empty()) GTEST_SKIP() << "no ffmpeg: create writes videos";
  try {
    (void)find_perceive_helper();
  } catch (const std::exception& e) {
    GTEST_SKIP() << "the perceive helper is not installed (create's detector): " << e.what();
  }
  test::TempDir tmp("studio_load");
  const fs::path dir = tmp.path();
  const std::string synth = std::string(KS_CLI_PATH) + " synth --seed 1 --frames 1 --out '" +
                            (dir / "s1").string() + "' >/dev/null 2>&1";
  ASSERT_EQ(std::system(synth.c_str()), 0);

  StudioOptions o;
  o.workspace = (dir / "ws").string();
  o.program = KS_CLI_PATH;
  o.page_dir = std::string(KS_SOURCE_DIR) + "/studio";
  // Enough steps that the create outlasts the load.
  o.create_args = {"--iters", "100",    "--frames", "8",           "--motions",
                   "none",    "--size", "128x192",  "--subdivide", "0"};
  Studio studio(o);
  WebServerOptions so;
  so.port = 0;
  WebServer server(so);
  add_studio_routes(server, studio);
  server.start();
  const int port = server.port();
  const std::string host = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";

  const std::string photo = read_file_text((dir / "s1" / "photo.png").string());
  const test::Reply up = test::request(port, "POST /api/avatars HTTP/1.1\r\n" + host +
                                                 "Content-Length: " + std::to_string(photo.size()) +
                                                 "\r\nConnection: close\r\n\r\n" + photo);
  ASSERT_EQ(up.status, 201) << up.body;
  const std::string id = json::parse(up.body)["id"];
  for (int i = 0; i < 200 && studio.avatar_json(id)["state"] != "running"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(studio.avatar_json(id)["state"], "running");
  // An event stream open all the while, as a page has.
  test::Connection events(port);
  ASSERT_TRUE(events.send("GET /api/events HTTP/1.1\r\n" + host + "\r\n"));

  // The load begins once create is in reconstruct, its longest and busiest stage (both cores).
  for (int i = 0; i < 1500 && studio.avatar_json(id)["progress"]["stage"] != "reconstruct"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const json before = studio.avatar_json(id)["progress"];
  ASSERT_EQ(before["stage"], "reconstruct") << before;

  // Clients on one keep-alive connection each (a new one when the server closes it): `paced`, a
  // request every 5 ms each (what pages do, and more), or as fast as they can.
  const char* targets[] = {"/", "/static/app.js", "/api/state", "/api/avatars/"};
  struct Run {
    std::vector<double> lat;
    int bad = 0;
    double seconds = 0;
  };
  auto load = [&](int clients, double ms, bool paced) {
    std::vector<std::vector<double>> lat(static_cast<size_t>(clients));
    std::atomic<int> bad{0};
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<std::thread> threads;
    for (int c = 0; c < clients; ++c)
      threads.emplace_back([&, c] {
        auto conn = std::make_unique<test::Connection>(port);
        for (int k = 0; k < 100000 && ms_since(t0) < ms; ++k) {
          std::string t = targets[(c + k) % 4];
          if (t.back() == '/' && t.size() > 1) t += id;
          const auto t1 = std::chrono::steady_clock::now();
          test::Reply r;
          if (conn->send("GET " + t + " HTTP/1.1\r\n" + host + "\r\n")) r = conn->read_reply(10);
          if (r.status == 0) {  // the server closed the connection: a new one
            conn = std::make_unique<test::Connection>(port);
            if (conn->send("GET " + t + " HTTP/1.1\r\n" + host + "\r\n")) r = conn->read_reply(10);
          }
          lat[size_t(c)].push_back(ms_since(t1));
          if (r.status != 200) bad++;
          if (paced) std::this_thread::sleep_until(t1 + std::chrono::milliseconds(5));
        }
      });
    for (auto& t : threads) t.join();
    Run run;
    run.seconds = ms_since(t0) / 1000;
    run.bad = bad;
    for (const auto& l : lat) run.lat.insert(run.lat.end(), l.begin(), l.end());
    return run;
  };
  const Run paced = load(4, 4000, true);
  const Run flat = load(8, 1000, false);
  const json mid = studio.avatar_json(id)["progress"];

  // A burst: 64 connections at once, one request each.
  std::vector<double> burst(64);
  std::atomic<int> burst_bad{0};
  const auto tb = std::chrono::steady_clock::now();
  std::vector<std::thread> bt;
  for (int i = 0; i < 64; ++i)
    bt.emplace_back([&, i] {
      const auto t1 = std::chrono::steady_clock::now();
      const test::Reply r = test::get(port, "/api/state");
      burst[size_t(i)] = ms_since(t1);
      if (r.status != 200) burst_bad++;
    });
  for (auto& t : bt) t.join();
  const double burst_s = ms_since(tb) / 1000;
  const json after = studio.avatar_json(id);
  const bool still_running = after["state"] == "running";
  auto show = [](const char* what, const Run& r) {
    std::printf(
        "%s: %zu requests in %.2f s = %.0f requests/s; latency p50 %.2f ms, p90 %.2f ms, "
        "p99 %.2f ms, max %.1f ms\n",
        what, r.lat.size(), r.seconds, double(r.lat.size()) / r.seconds, quantile(r.lat, 0.5),
        quantile(r.lat, 0.9), quantile(r.lat, 0.99), quantile(r.lat, 1.0));
  };
  show("paced load (4 clients, a request every 5 ms each) during reconstruct", paced);
  show("flat-out load (8 clients)", flat);
  std::printf(
      "burst of 64 new connections: %.3f s, max %.1f ms; reconstruct went from %.0f%% to "
      "%.0f%% meanwhile\n",
      burst_s, quantile(burst, 1.0), before["stages"][5]["percent"].get<double>(),
      mid["stages"][5]["percent"].get<double>());
  EXPECT_EQ(paced.bad + flat.bad + burst_bad.load(), 0);
  EXPECT_GT(paced.lat.size(), 1000u);
  EXPECT_LT(quantile(paced.lat, 0.99), 250.0);
  EXPECT_LT(quantile(flat.lat, 0.99), 1000.0);
  EXPECT_LT(quantile(burst, 1.0), 3000.0);
  EXPECT_TRUE(mid["stages"][5]["percent"].get<double>() >
                  before["stages"][5]["percent"].get<double>() ||
              mid["stage"] != "reconstruct" || !still_running)
      << "reconstruct made no progress under the load";
  EXPECT_TRUE(events.read_some(0.5).find("event: state") != std::string::npos);
  events.close();
  studio.shutdown();
  server.stop();
}

}  // namespace
}  // namespace ks

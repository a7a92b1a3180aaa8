// `kinesplat view` end to end in headless Chromium (software WebGL): the page loads a small
// avatar, plays it (screenshots at two times differ), and at a fixed frame seen through a kinesplat
// camera matches `kinesplat animate`'s render of the same frame and camera.
//
// Needs Debian's chromium, node and the viewer's npm packages (viewer/node_modules, with
// playwright-core) and the built viewer (viewer/dist): `make deps` installs and builds them. The
// test is skipped, saying which is missing, where one is not there.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "cli_process.hpp"
#include "core/camera.hpp"
#include "core/fileio.hpp"
#include "evaluate/metrics.hpp"
#include "io/image_io.hpp"
#include "motion/motion.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

// The page must agree with kinesplat's render of the same frame and camera to this PSNR (dB, full
// frame). Measured here (docs/viewer.md): 46.5 dB, while the page at frame 45 against kinesplat's
// renders of frames 44 and 46 (1/30 s away) scores 34.8 and 33.2 dB, and against frame 0 22.7 dB.
// What is left between the two renderers: Spark quantises the skin weights to 1/255, keeps splats
// in its own encoding, draws them in one global depth order with the GPU's blending (no 0.99
// opacity clamp), all in SwiftShader's float precision, and the screenshot is 8-bit.
// 40 dB leaves 6.5 dB for that to vary (another Chromium or SwiftShader) and still fails a page
// that is one frame off.
constexpr double kPsnrFloor = 40.0;

// A small test avatar (about 5,200 splats: software WebGL draws a few frames per second): every
// second vertex of the default body model, elongated, turned, and coloured by body part with
// height stripes so that a misplaced limb shows. No pose correctives (the page has none).
Avatar small_avatar() {
  const BodyModel& model = default_body_model();
  PlainAvatarOptions opt;
  opt.scale_factor = 0.9f;
  opt.opacity = 0.9f;
  opt.posedirs = false;
  const Avatar full = avatar_from_body(model, Eigen::VectorXd::Zero(model.num_betas), opt);
  Avatar a = full;
  const int N = full.num_gaussians();
  std::vector<int> keep;
  for (int i = 0; i < N; i += 2) keep.push_back(i);
  const int M = int(keep.size());
  a.gaussians.resize(M);
  a.anchors.resize(3 * size_t(M));
  a.skin_joints.resize(4 * size_t(M));
  a.skin_weights.resize(4 * size_t(M));
  a.part_labels.resize(M);
  a.template_vertices.resize(0, 3);
  a.template_faces.resize(0, 3);
  static const float palette[8][3] = {
      {0.85f, 0.35f, 0.3f},  {0.3f, 0.6f, 0.85f},  {0.9f, 0.75f, 0.3f}, {0.4f, 0.8f, 0.45f},
      {0.75f, 0.45f, 0.85f}, {0.95f, 0.55f, 0.2f}, {0.35f, 0.8f, 0.8f}, {0.85f, 0.85f, 0.85f}};
  constexpr float kC0 = 0.28209479177387814f;
  for (int m = 0; m < M; ++m) {
    const int i = keep[m];
    for (int k = 0; k < 3; ++k) {
      a.gaussians.means[3 * m + k] = full.gaussians.means[3 * i + k];
      a.anchors[3 * m + k] = full.anchors[3 * i + k];
      a.gaussians.log_scales[3 * m + k] =
          full.gaussians.log_scales[3 * i + k] + (k == 0 ? 0.35f : -0.15f);
    }
    const float ang = 0.7f * float(m % 9);
    a.gaussians.quats[4 * m] = std::cos(ang / 2);
    a.gaussians.quats[4 * m + 1] = 0.f;
    a.gaussians.quats[4 * m + 2] = 0.6f * std::sin(ang / 2);
    a.gaussians.quats[4 * m + 3] = 0.8f * std::sin(ang / 2);
    a.gaussians.opacity_logits[m] = full.gaussians.opacity_logits[i];
    for (int k = 0; k < 4; ++k) {
      a.skin_joints[4 * m + k] = full.skin_joints[4 * i + k];
      a.skin_weights[4 * m + k] = full.skin_weights[4 * i + k];
    }
    const int part = full.part_labels.empty() ? 0 : full.part_labels[i];
    a.part_labels[m] = part;
    const float y = a.gaussians.means[3 * m + 1];
    const float stripe = std::sin(30.f * y) > 0.f ? 1.f : 0.6f;
    for (int c = 0; c < 3; ++c)
      a.gaussians.sh[3 * m + c] = (palette[part % 8][c] * stripe - 0.5f) / kC0;
  }
  a.metadata = {{"source", "viewer_browser_test"}};
  return a;
}

// `kinesplat view` as a child process, its output on a pipe.
using ViewProcess = test::CliProcess;

std::string quote(const std::string& s) {
  return "'" + s + "'";
}

// The value after `key` on the line that holds it ("view: serving at http://... (Ctrl-C").
std::string after(const std::string& text, const std::string& key) {
  const size_t p = text.find(key);
  if (p == std::string::npos) return "";
  const size_t s = p + key.size();
  return text.substr(s, text.find_first_of(" \n", s) - s);
}

// Share of pixels whose largest channel difference exceeds `thr`.
double changed_share(const Image& a, const Image& b, float thr) {
  size_t n = 0;
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    float d = 0.f;
    for (int c = 0; c < 3; ++c)
      d = std::max(d, std::abs(a.data[p * a.channels + c] - b.data[p * b.channels + c]));
    n += d > thr;
  }
  return double(n) / double(a.pixel_count());
}

TEST(ViewerBrowser, PlaysTheAvatarAndMatchesTheCppRender) {
  const std::string chromium = "/usr/bin/chromium";
  const fs::path viewer = fs::path(KS_SOURCE_DIR) / "viewer";
  if (::access(chromium.c_str(), X_OK) != 0)
    GTEST_SKIP() << "Chromium is not installed (" << chromium
                 << "): `make deps` installs Debian's chromium";
  if (std::system("command -v node >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "node is not installed: `make deps` installs it";
  if (!fs::exists(viewer / "node_modules" / "playwright-core" / "package.json"))
    GTEST_SKIP() << "the viewer's npm packages are not installed (" << viewer / "node_modules"
                 << "): run `make deps`";
  if (!fs::exists(viewer / "dist" / "kinesplat-viewer.js"))
    GTEST_SKIP() << "the viewer is not built (" << viewer / "dist"
                 << "): run `make deps`";

  test::TempDir dir("viewer_browser");
  const Avatar avatar = small_avatar();
  ASSERT_GT(avatar.num_gaussians(), 3000);
  ASSERT_LT(avatar.num_gaussians(), 6000);
  const std::string avatar_path = dir / "small.ksavatar";
  save_avatar(avatar_path, avatar);

  // A kinesplat camera in front of the avatar at the compared frame (wave, right arm raised).
  const int W = 240, H = 360, frame = 45;
  const Motion wave = builtin_motion("wave");
  const Gaussians posed = pose_avatar(avatar, wave.frames[frame]);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (size_t i = 0; i < posed.size(); ++i) {
    const Eigen::Vector3d p(posed.means[3 * i], posed.means[3 * i + 1], posed.means[3 * i + 2]);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const Camera cam =
      Camera::look_at_fov(centre + Eigen::Vector3d(0.6, 0.3, 4.2), centre, W, H, 30.0);
  const std::string cam_path = dir / "camera.json";
  cam.save(cam_path);
  const std::string bg = "0.1,0.12,0.15";

  // kinesplat's own render of every frame of the motion through that camera.
  const std::string frames = dir / "frames";
  char size[32];
  std::snprintf(size, sizeof size, "%dx%d", W, H);
  const std::string animate = std::string(KS_CLI_PATH) + " animate " + quote(avatar_path) +
                              " --motion wave --camera " + quote(cam_path) + " --size " + size +
                              " --background " + bg + " --out " + quote(frames) + " >" +
                              quote(dir / "animate.log") + " 2>&1";
  ASSERT_EQ(std::system(animate.c_str()), 0) << read_file_text(dir / "animate.log");

  // The page, served by `kinesplat view`.
  ViewProcess view;
  ASSERT_TRUE(view.start({"view", avatar_path, "--motion", "wave", "--port", "0"}));
  ASSERT_TRUE(view.wait_for("(Ctrl-C to stop)", 60)) << view.text;
  const std::string url = after(view.text, "serving at ");
  const fs::path site = after(view.text, "site in ");
  ASSERT_EQ(url.rfind("http://127.0.0.1:", 0), 0u) << view.text;
  ASSERT_TRUE(fs::exists(site / "avatar.ply")) << view.text;

  const std::string shots = dir / "shots";
  const std::string node = "node " + quote((viewer / "test" / "capture.mjs").string()) + " --url " +
                           quote(url) + " --out " + quote(shots) + " --camera " + quote(cam_path) +
                           " --frame " + std::to_string(frame) + " --motion wave --bg " + bg +
                           " --play-shots --no-ui --width " + std::to_string(W) + " --height " +
                           std::to_string(H) + " >" + quote(dir / "capture.log") + " 2>&1";
  // Screenshots at two times differ: the avatar moves. Software WebGL draws a frame or two a
  // second, slower still when other tests share the cores, and the wave motion moves only the
  // arm, which it holds down at both ends of its loop; in one loaded CI run the two shots
  // (frames 79 and 63 by the page's count) showed no movement. So up to three captures.
  int rc = 0;
  nlohmann::json result;
  Image play1, play2;
  double moved = 0;
  for (int attempt = 0; attempt < 3 && moved <= 0.002; ++attempt) {
    rc = std::system(node.c_str());
    if (rc != 0) break;
    result = read_json(shots + "/result.json");
    play1 = read_image(shots + "/play1.png", 3);
    play2 = read_image(shots + "/play2.png", 3);
    moved = changed_share(play1, play2, 8.f / 255.f);
  }
  const int view_status = view.stop(SIGINT);
  ASSERT_EQ(rc, 0) << read_file_text(dir / "capture.log");
  EXPECT_EQ(view_status, 0) << view.text;
  EXPECT_NE(view.text.find("view: stopped"), std::string::npos) << view.text;
  EXPECT_FALSE(fs::exists(site.parent_path())) << "the temporary site was not removed";
  EXPECT_EQ(result["fixed"]["numSplats"], avatar.num_gaussians());
  EXPECT_EQ(result["fixed"]["frame"], frame);
  EXPECT_NE(result["play1"]["frame"], result["play2"]["frame"]);
  EXPECT_GT(moved, 0.002) << "frames " << result["play1"]["frame"] << " and "
                          << result["play2"]["frame"];

  // The page at the fixed frame and camera matches kinesplat's render of them.
  const Image page = read_image(shots + "/fixed.png", 3);
  char name[32];
  std::snprintf(name, sizeof name, "/%04d.png", frame);
  const Image cpp = read_image(frames + name, 3);
  ASSERT_EQ(page.width, W);
  ASSERT_EQ(page.height, H);
  const double match = psnr(page, cpp);
  std::printf("viewer vs kinesplat render: PSNR %.2f dB at frame %d\n", match, frame);
  EXPECT_GE(match, kPsnrFloor);
  // The floor tells poses apart: the renders of the neighbouring frames (1/30 s away) score
  // below it.
  for (int f : {0, frame - 1, frame + 1}) {
    std::snprintf(name, sizeof name, "/%04d.png", f);
    const double wrong = psnr(page, read_image(frames + name, 3));
    std::printf("viewer at frame %d vs kinesplat render of frame %d: PSNR %.2f dB\n", frame, f,
                wrong);
    EXPECT_LT(wrong, kPsnrFloor) << "frame " << f;
  }
  if (const char* keep = std::getenv("KS_VIEWER_TEST_KEEP")) {
    fs::create_directories(keep);
    fs::copy(shots, keep, fs::copy_options::overwrite_existing | fs::copy_options::recursive);
    fs::copy_file(frames + "/0045.png", fs::path(keep) / "cpp.png",
                  fs::copy_options::overwrite_existing);
  }
}

}  // namespace
}  // namespace ks

// kinesplat's glTF export in headless Chromium (software WebGL), tests/gltf/browser/render.mjs:
// three.js draws the skinned mesh posed by AnimationMixer at a walk frame and it covers what
// kinesplat's own render of that frame and camera covers (silhouette IoU) in about its colours
// (PSNR over the overlap), with the baked texture and with COLOR_0; Babylon.js's glTF loader reads
// the splat primitive through its KHR_gaussian_splatting extension as a GaussianSplattingMesh of
// every Gaussian, and its render of the splats at rest covers what kinesplat's render of the
// canonical Gaussians covers.
//
// Needs node, Debian's chromium and tests/gltf/browser/node_modules (`make deps`, target
// gltf-browser); skipped, saying which is missing, where one is not there.
// KS_GLTF_BROWSER_KEEP=DIR keeps the images (render.mjs's, kinesplat's, the silhouettes'
// disagreement) there. GltfBrowser.DemoAvatarFigures makes docs/export.md's figures when
// KS_GLTF_BROWSER_DEMO names an avatar (skipped otherwise).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "../temp_dir.hpp"
#include "animate/framing.hpp"
#include "animate/posed_render.hpp"
#include "avatar/avatar.hpp"
#include "avatar/from_body.hpp"
#include "avatar/pose.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/fileio.hpp"
#include "evaluate/metrics.hpp"
#include "gltf/gltf_export.hpp"
#include "io/image_io.hpp"
#include "motion/motion.hpp"
#include "raster/rasterizer.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

// three.js's mesh against kinesplat's splats at the same walk frame: the bar. Measured
// here (2026-12-03, Chromium 156, SwiftShader): 0.957, texture and COLOR_0 alike. What is left is a
// rim of about a pixel where the splats reach past the surface (KS_GLTF_BROWSER_KEEP's
// *_vs_kinesplat.png); how wide it is depends on the Gaussians' extent across the silhouette: the
// plain avatar's round Gaussians (0.6 of an edge) gave 0.81, discs 0.6 across and 0.1 thick 0.93,
// the discs below 0.957. The neighbouring frames (1/15 s away) score 0.62-0.64, 2/15 s 0.48-0.49.
constexpr double kMeshIouFloor = 0.95;
// Colour PSNR (dB) over the pixels both silhouettes cover. Measured: 29.17 (texture), 29.08
// (COLOR_0). The mesh shows each vertex's band-0 colour interpolated over its triangles, where the
// splats blend neighbouring discs (their dotted texture, the stripes' soft edges) and the
// background at the rim; 3 dB below those.
constexpr double kMeshPsnrFloor = 26.0;
// Babylon's splats at rest against kinesplat's render of the canonical Gaussians. Measured: 0.989
// (Babylon stores colours, opacities and rotations in 8 bits and uses its own splat kernel).
constexpr double kBabylonIouFloor = 0.97;

// animate's default frame size; the rest pose (arms out) in a square.
constexpr int kW = 512, kH = 768, kRestW = 512, kRestH = 512;
constexpr int kFrames = 32, kFrame = 8;
const float kBackground[3] = {0.1f, 0.12f, 0.15f};

// The default body's plain avatar (10,338 vertices, one Gaussian on each; no pose correctives,
// which the GLB does not carry) with its Gaussians made discs tangent to the surface, as a trained
// avatar's are (0.4 of the mean edge across, 0.05 along the normal), coloured by body part with
// height stripes so that a limb in the wrong place shows in the colours too.
Avatar test_avatar() {
  PlainAvatarOptions opt;
  opt.posedirs = false;
  opt.opacity = 0.95f;
  const double across = 0.4, along = 0.05;
  opt.scale_factor = float(across);
  Avatar a = avatar_from_body(default_body_model(), Eigen::VectorXd::Zero(2), opt);
  const std::vector<float> normals = avatar_anchor_normals(a);
  EXPECT_EQ(normals.size(), 3 * a.gaussians.size());
  const float flat = float(std::log(along / across));
  static const float palette[8][3] = {
      {0.85f, 0.35f, 0.3f},  {0.3f, 0.6f, 0.85f},  {0.9f, 0.75f, 0.3f}, {0.4f, 0.8f, 0.45f},
      {0.75f, 0.45f, 0.85f}, {0.95f, 0.55f, 0.2f}, {0.35f, 0.8f, 0.8f}, {0.85f, 0.85f, 0.85f}};
  constexpr float kC0 = 0.28209479177387814f;
  const int K = a.gaussians.coeffs();
  for (size_t i = 0; i < a.gaussians.size() && normals.size() == 3 * a.gaussians.size(); ++i) {
    // The rotation taking the disc's thin axis (z) onto the normal (w, x, y, z).
    const Eigen::Vector3d n(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
    const Eigen::Quaterniond q =
        Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n.normalized());
    a.gaussians.quats[4 * i] = float(q.w());
    a.gaussians.quats[4 * i + 1] = float(q.x());
    a.gaussians.quats[4 * i + 2] = float(q.y());
    a.gaussians.quats[4 * i + 3] = float(q.z());
    a.gaussians.log_scales[3 * i + 2] += flat;
    const int part = a.part_labels.empty() ? 0 : a.part_labels[i];
    const float stripe = std::sin(20.f * a.gaussians.means[3 * i + 1]) > 0.f ? 1.f : 0.7f;
    for (int c = 0; c < 3; ++c)
      a.gaussians.sh[(i * size_t(K)) * 3 + size_t(c)] =
          (palette[part % 8][c] * stripe - 0.5f) / kC0;
  }
  return a;
}

// Pixels whose largest channel differs from the background by more than 6/255.
Image differs_from(const Image& img, const float bg[3]) {
  Image m(img.width, img.height, 1);
  for (size_t p = 0; p < img.pixel_count(); ++p) {
    float d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(img.data[3 * p + size_t(c)] - bg[c]));
    m.data[p] = d > 6.f / 255.f ? 1.f : 0.f;
  }
  return m;
}

Image above_half(const Image& alpha) {
  Image m(alpha.width, alpha.height, 1);
  for (size_t p = 0; p < alpha.pixel_count(); ++p) m.data[p] = alpha.data[p] > 0.5f ? 1.f : 0.f;
  return m;
}

double iou(const Image& a, const Image& b) {
  size_t both = 0, either = 0;
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    both += a.data[p] > 0.5f && b.data[p] > 0.5f;
    either += a.data[p] > 0.5f || b.data[p] > 0.5f;
  }
  return either ? double(both) / double(either) : 0.0;
}

Image overlap(const Image& a, const Image& b) {
  Image m(a.width, a.height, 1);
  for (size_t p = 0; p < a.pixel_count(); ++p)
    m.data[p] = a.data[p] > 0.5f && b.data[p] > 0.5f ? 1.f : 0.f;
  return m;
}

// Where two silhouettes disagree: white both, red `a` only, green `b` only.
Image disagreement(const Image& a, const Image& b) {
  Image d(a.width, a.height, 3);
  for (size_t p = 0; p < a.pixel_count(); ++p) {
    const bool x = a.data[p] > 0.5f, y = b.data[p] > 0.5f;
    d.data[3 * p] = x ? 1.f : 0.f;
    d.data[3 * p + 1] = y ? 1.f : 0.f;
    d.data[3 * p + 2] = x && y ? 1.f : 0.f;
  }
  return d;
}

// Images side by side, each resized to w x h, with a 4-pixel gap.
Image side_by_side(const std::vector<Image>& images, int w, int h) {
  const int gap = 4;
  Image out(int(images.size()) * (w + gap) - gap, h, 3, 1.f);
  for (size_t k = 0; k < images.size(); ++k) {
    const Image r = resize_area(images[k], w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) out.at(int(k) * (w + gap) + x, y, c) = r.at(x, y, c);
  }
  return out;
}

std::string quote(const std::string& s) {
  return "'" + s + "'";
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// node render.mjs ARGS; its JSON line, or a description of what went wrong in `error`.
struct RenderRun {
  int rc = -1;
  nlohmann::json result;
  std::string error;
  double seconds = 0;
};

RenderRun run_render(const fs::path& dir, const std::string& name, const std::string& args) {
  const fs::path pkg = fs::path(KS_SOURCE_DIR) / "tests/gltf/browser";
  const std::string out = (dir / (name + ".txt")).string(), log = (dir / (name + ".log")).string();
  const std::string cmd = "timeout 300 node " + quote((pkg / "render.mjs").string()) + " " + args +
                          " >" + quote(out) + " 2>" + quote(log);
  RenderRun r;
  const auto t0 = std::chrono::steady_clock::now();
  r.rc = std::system(cmd.c_str());
  r.seconds = seconds_since(t0);
  try {
    const std::string text = read_file_text(out);
    r.result = nlohmann::json::parse(text.substr(0, text.find('\n')));
  } catch (const std::exception& e) {
    r.error = std::string("no JSON line from render.mjs (") + e.what() + ")\n";
  }
  if (r.rc != 0 || !r.result.value("ok", false))
    r.error += "render.mjs " + args + " failed (exit " + std::to_string(r.rc) + "):\n" +
               read_file_text(log);
  return r;
}

// `animate`'s framing (animate/framing.hpp) of one pose, from the front turned `degrees` about
// the vertical through its centre.
Camera framing(const Avatar& a, const BodyParams& pose, int w, int h, double degrees) {
  Motion one;
  one.frames.assign(1, pose);
  Eigen::Vector3d lo, hi;
  motion_bounds(a, one, lo, hi);
  const Camera front = playback_cameras("front", lo, hi, w, h, 1)[0];
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const Eigen::Vector3d eye =
      centre + Eigen::AngleAxisd(degrees * M_PI / 180.0, Eigen::Vector3d::UnitY()) *
                   (front.centre() - centre);
  return Camera::look_at_fov(eye, centre, w, h, 30.0);
}

std::string bg_arg() {
  char bg[64];
  std::snprintf(bg, sizeof bg, "%g,%g,%g", kBackground[0], kBackground[1], kBackground[2]);
  return bg;
}

struct Shared {
  test::TempDir dir{"gltf_browser"};
  Avatar avatar;
  Camera cam, rest_cam;
  // kinesplat's renders through `cam`: walk frame F at posed[F] (kFrame and its neighbours);
  // through `rest_cam`: the rest pose and walk frame kFrame.
  std::vector<RasterResult> posed;
  RasterResult rest, posed_rest_cam;
  RenderRun texture, colors;  // render.mjs on the default GLB (both engines), on --vertex-colors
};

class GltfBrowser : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const fs::path pkg = fs::path(KS_SOURCE_DIR) / "tests/gltf/browser";
    if (std::system("command -v node >/dev/null 2>&1") != 0) {
      skip_ = "node is not installed: `make deps` installs it";
      return;
    }
    if (::access("/usr/bin/chromium", X_OK) != 0) {
      skip_ =
          "Chromium is not installed (/usr/bin/chromium): `make deps` installs Debian's chromium";
      return;
    }
    for (const char* p : {"three", "playwright-core", "babylonjs", "babylonjs-loaders"})
      if (!fs::exists(pkg / "node_modules" / p / "package.json")) {
        skip_ = "the browser check's npm packages are not installed (" +
                (pkg / "node_modules" / p).string() + "): run `make gltf-browser` or `make deps`";
        return;
      }
    s_ = std::make_unique<Shared>();
    Shared& s = *s_;
    s.avatar = test_avatar();
    const Motion walk = builtin_motion("walk", kFrames);
    const std::string glb = s.dir / "avatar.glb", glb_colors = s.dir / "avatar_colors.glb";
    export_gltf(glb, s.avatar, {walk});
    GltfExportOptions vc;
    vc.vertex_colors = true;
    vc.splats = false;
    export_gltf(glb_colors, s.avatar, {walk}, vc);

    s.cam = framing(s.avatar, walk.frames[kFrame], kW, kH, 30.0);
    s.rest_cam = framing(s.avatar, BodyParams{}, kRestW, kRestH, 0.0);
    const std::string cam_path = s.dir / "camera.json", rest_cam_path = s.dir / "rest_camera.json";
    s.cam.save(cam_path);
    s.rest_cam.save(rest_cam_path);

    RasterSettings rs;
    std::copy(kBackground, kBackground + 3, rs.background);
    rs.image_only = true;
    PosedRenderer renderer(s.avatar);
    s.posed.resize(kFrames);
    for (int f = kFrame - 2; f <= kFrame + 2; ++f)
      renderer.render(walk.frames[size_t(f)], s.cam, rs, s.posed[size_t(f)]);
    rasterize_forward(s.avatar.gaussians, s.rest_cam, rs, s.rest);
    renderer.render(walk.frames[kFrame], s.rest_cam, rs, s.posed_rest_cam);

    const std::string common = " --camera " + quote(cam_path) + " --bg " + bg_arg() +
                               " --clip walk --frame " + std::to_string(kFrame);
    s.texture = run_render(s.dir.path(), "texture",
                           "--glb " + quote(glb) + " --out " + quote(s.dir / "texture") + common +
                               " --babylon-camera " + quote(rest_cam_path) + " --babylon-pose");
    s.colors = run_render(
        s.dir.path(), "colors",
        "--glb " + quote(glb_colors) + " --out " + quote(s.dir / "colors") + common + " --three");
    if (const char* keep = std::getenv("KS_GLTF_BROWSER_KEEP")) {
      const fs::path k = keep;
      fs::create_directories(k);
      for (const char* d : {"texture", "colors"})
        if (fs::exists(s.dir / d))
          fs::copy(s.dir / d, k / d,
                   fs::copy_options::overwrite_existing | fs::copy_options::recursive);
      for (const std::string& f : {glb, glb_colors, cam_path, rest_cam_path})
        fs::copy_file(f, k / fs::path(f).filename(), fs::copy_options::overwrite_existing);
      write_png((k / "kinesplat_posed.png").string(), s.posed[kFrame].color);
      write_png((k / "kinesplat_rest.png").string(), s.rest.color);
      write_png((k / "kinesplat_posed_rest_camera.png").string(), s.posed_rest_cam.color);
    }
  }
  static void TearDownTestSuite() { s_.reset(); }

  void SetUp() override {
    if (!skip_.empty()) GTEST_SKIP() << skip_;
    ASSERT_TRUE(s_);
  }

  static std::string skip_;
  static std::unique_ptr<Shared> s_;
};

std::string GltfBrowser::skip_;
std::unique_ptr<Shared> GltfBrowser::s_;

// The three.js render of `run` against kinesplat's render of walk frame kFrame: the IoU, the
// PSNR over the overlap, and the IoUs with the neighbouring frames' renders.
void check_three(const Shared& s, const RenderRun& run, const char* what) {
  ASSERT_TRUE(run.error.empty()) << run.error;
  const nlohmann::json& t = run.result["three"];
  EXPECT_EQ(t["mesh"]["name"], "avatar_mesh");
  EXPECT_EQ(t["mesh"]["bones"], s.avatar.num_joints());
  EXPECT_GE(t["mesh"]["vertices"].get<long>(), s.avatar.template_vertices.rows());  // UV seams
  EXPECT_EQ(t["mesh"]["triangles"], s.avatar.template_faces.rows());
  ASSERT_EQ(t["clips"].size(), 1u);
  EXPECT_EQ(t["clips"][0]["name"], "walk");
  EXPECT_EQ(t["clips"][0]["extras"]["frames"], kFrames);

  const Image three = read_image(t["png"].get<std::string>(), 3);
  ASSERT_EQ(three.width, kW);
  ASSERT_EQ(three.height, kH);
  const Image mesh = differs_from(three, kBackground);
  const Image splats = above_half(s.posed[kFrame].alpha);
  const double match = iou(mesh, splats);
  const double colour = psnr_masked(three, s.posed[kFrame].color, overlap(mesh, splats));
  std::printf(
      "three.js r%s, %s (%s): walk frame %d, silhouette IoU %.4f with kinesplat's render of that "
      "frame, colour PSNR %.2f dB over the overlap; GLTFLoader %.0f ms, first render %.0f ms, page "
      "%.0f ms\n",
      t["version"].get<std::string>().c_str(), what, t["renderer"].get<std::string>().c_str(),
      kFrame, match, colour, t["timings"]["load_ms"].get<double>(),
      t["timings"]["first_render_ms"].get<double>(), t["timings"]["wall_ms"].get<double>());
  EXPECT_GE(match, kMeshIouFloor);
  EXPECT_GE(colour, kMeshPsnrFloor);
  // The bar tells the frame from its neighbours (1/15 s and 2/15 s away).
  for (int f : {kFrame - 2, kFrame - 1, kFrame + 1, kFrame + 2}) {
    const double other = iou(mesh, above_half(s.posed[size_t(f)].alpha));
    std::printf("  IoU with kinesplat's frame %d: %.4f\n", f, other);
    EXPECT_LT(other, kMeshIouFloor) << "frame " << f;
  }
  if (const char* keep = std::getenv("KS_GLTF_BROWSER_KEEP"))
    write_png((fs::path(keep) / (std::string(what) + "_vs_kinesplat.png")).string(),
              disagreement(splats, mesh));
}

TEST_F(GltfBrowser, ThreejsTexturedMeshMatchesKinesplatAtAWalkFrame) {
  check_three(*s_, s_->texture, "texture");
  if (HasFatalFailure()) return;
  const nlohmann::json& t = s_->texture.result["three"];
  EXPECT_FALSE(t["mesh"]["base_color_texture"].is_null());
  // The splats load as THREE.Points (three.js knows no KHR_gaussian_splatting); hidden here.
  ASSERT_EQ(t["points"].size(), 1u);
  EXPECT_EQ(t["points"][0][1], s_->avatar.num_gaussians());
}

TEST_F(GltfBrowser, ThreejsVertexColouredMeshMatchesKinesplatAtAWalkFrame) {
  check_three(*s_, s_->colors, "COLOR_0");
  if (HasFatalFailure()) return;
  const nlohmann::json& t = s_->colors.result["three"];
  EXPECT_EQ(t["mesh"]["color_0"], 3);
  EXPECT_TRUE(t["mesh"]["base_color_texture"].is_null());
  EXPECT_EQ(t["mesh"]["vertices"], s_->avatar.template_vertices.rows());
}

TEST_F(GltfBrowser, BabylonLoadsTheSplatsAsAGaussianSplattingMesh) {
  const Shared& s = *s_;
  ASSERT_TRUE(s.texture.error.empty()) << s.texture.error;
  const nlohmann::json& b = s.texture.result["babylon"];
  EXPECT_EQ(b["splat_count"], s.avatar.num_gaussians());
  int gs = 0;
  for (const auto& m : b["meshes"])
    if (m["class"] == "GaussianSplattingMesh") {
      ++gs;
      EXPECT_EQ(m["name"], "avatar_splats");
      EXPECT_EQ(m["splat_count"], s.avatar.num_gaussians());
    }
  EXPECT_EQ(gs, 1);
  EXPECT_TRUE(b["skinned_mesh"].get<bool>());
  ASSERT_EQ(b["animation_groups"].size(), 1u);
  EXPECT_EQ(b["animation_groups"][0]["name"], "walk");
  std::printf("Babylon.js %s (%s), root node %s\n", b["version"].get<std::string>().c_str(),
              b["renderer"].get<std::string>().c_str(), b["root"].dump().c_str());
  for (const auto& m : b["meshes"]) std::printf("  mesh %s\n", m.dump().c_str());
  std::printf("  skeletons %s, animation groups %s\n", b["skeletons"].dump().c_str(),
              b["animation_groups"].dump().c_str());

  const Image rest = read_image(b["png"].get<std::string>(), 3);
  ASSERT_EQ(rest.width, kRestW);
  ASSERT_EQ(rest.height, kRestH);
  const Image babylon_rest = differs_from(rest, kBackground);
  const double match = iou(babylon_rest, above_half(s.rest.alpha));
  std::printf(
      "Babylon splats at rest: silhouette IoU %.4f with kinesplat's rest render, PSNR %.2f dB; "
      "load %.0f ms, settled render %.0f ms (%d frames)\n",
      match, psnr(rest, s.rest.color), b["timings"]["load_ms"].get<double>(),
      b["timings"]["rest_render_ms"].get<double>(), b["frames_to_settle"].get<int>());
  EXPECT_GE(match, kBabylonIouFloor);

  // The walk group at frame kFrame: does Babylon skin the splats? (Measured, not assumed.)
  const Image posed = read_image(b["posed_png"].get<std::string>(), 3);
  const Image posed_mesh = read_image(b["posed_mesh_png"].get<std::string>(), 3);
  const Image splats_posed = differs_from(posed, kBackground);
  const double posed_vs_rest = iou(splats_posed, above_half(s.rest.alpha));
  const double posed_vs_frame = iou(splats_posed, above_half(s.posed_rest_cam.alpha));
  const double mesh_vs_frame =
      iou(differs_from(posed_mesh, kBackground), above_half(s.posed_rest_cam.alpha));
  std::printf(
      "Babylon after the walk group went to frame %d: splats IoU %.4f with kinesplat's rest "
      "render, %.4f with its frame %d (%.4f of the pixels changed); the skinned mesh alone IoU "
      "%.4f with frame %d\n",
      kFrame, posed_vs_rest, posed_vs_frame, kFrame, b["posed"]["changed_share"].get<double>(),
      mesh_vs_frame, kFrame);
  if (const char* keep = std::getenv("KS_GLTF_BROWSER_KEEP"))
    write_png((fs::path(keep) / "babylon_vs_kinesplat_rest.png").string(),
              disagreement(above_half(s.rest.alpha), babylon_rest));
}

// docs/export.md's figures: KS_GLTF_BROWSER_DEMO=AVATAR.ksavatar (make demo's
// demo-out/create/avatar.ksavatar) exported with `--motion walk --motion dance` (and once more
// with --mesh --vertex-colors); three.js's mesh at walk frame kDemoFrame beside `kinesplat
// animate`'s render of that frame and camera; Babylon's load of the splats and its render of them
// at rest. KS_GLTF_BROWSER_FIGURES=DIR writes the side-by-side PNGs there. Prints the figures;
// skipped without KS_GLTF_BROWSER_DEMO.
TEST_F(GltfBrowser, DemoAvatarFigures) {
  const char* avatar_path = std::getenv("KS_GLTF_BROWSER_DEMO");
  if (!avatar_path)
    GTEST_SKIP() << "set KS_GLTF_BROWSER_DEMO=AVATAR.ksavatar (e.g. make demo's "
                    "demo-out/create/avatar.ksavatar) to make docs/export.md's figures";
  constexpr int kDemoFrame = 16;
  test::TempDir dir("gltf_browser_demo");
  const Avatar avatar = load_avatar(avatar_path);
  const Motion walk = builtin_motion("walk");
  ASSERT_GT(int(walk.frames.size()), kDemoFrame);

  const auto cli = [&](const std::string& args, const std::string& log) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::string cmd = std::string(KS_CLI_PATH) + " " + args + " >" + quote(log) + " 2>&1";
    const int rc = std::system(cmd.c_str());
    EXPECT_EQ(rc, 0) << cmd << "\n" << read_file_text(log);
    return seconds_since(t0);
  };
  const std::string glb = dir / "demo.glb", glb_colors = dir / "demo_colors.glb";
  const double export_s = cli(
      "export " + quote(avatar_path) + " --gltf " + quote(glb) + " --motion walk --motion dance",
      dir / "export.log");
  const double export_colors_s =
      cli("export " + quote(avatar_path) + " --gltf " + quote(glb_colors) +
              " --mesh --vertex-colors --motion walk --motion dance",
          dir / "export_colors.log");

  const Camera cam = framing(avatar, walk.frames[kDemoFrame], kW, kH, 30.0);
  const Camera rest_cam = framing(avatar, BodyParams{}, kRestW, kRestH, 0.0);
  const std::string cam_path = dir / "camera.json", rest_cam_path = dir / "rest_camera.json";
  cam.save(cam_path);
  rest_cam.save(rest_cam_path);
  char size[32];
  std::snprintf(size, sizeof size, "%dx%d", kW, kH);
  const double animate_s =
      cli("animate " + quote(avatar_path) + " --motion walk --camera " + quote(cam_path) +
              " --size " + size + " --background " + bg_arg() + " --out " + quote(dir / "frames"),
          dir / "animate.log");
  char name[32];
  std::snprintf(name, sizeof name, "frames/%04d.png", kDemoFrame);
  const Image animate = read_image(dir / name, 3);

  // kinesplat's alpha at that frame (PosedRenderer, what animate renders with), and at rest.
  RasterSettings rs;
  std::copy(kBackground, kBackground + 3, rs.background);
  rs.image_only = true;
  RasterResult posed, rest;
  PosedRenderer(avatar).render(walk.frames[kDemoFrame], cam, rs, posed);
  rasterize_forward(avatar.gaussians, rest_cam, rs, rest);
  std::printf("animate's PNG vs the in-process render: PSNR %.1f dB\n", psnr(animate, posed.color));

  const std::string common = " --camera " + quote(cam_path) + " --bg " + bg_arg() +
                             " --clip walk --frame " + std::to_string(kDemoFrame);
  const RenderRun both = run_render(dir.path(), "both",
                                    "--glb " + quote(glb) + " --out " + quote(dir / "both") +
                                        common + " --babylon-camera " + quote(rest_cam_path) +
                                        " --babylon-pose --timeout-ms 240000");
  ASSERT_TRUE(both.error.empty()) << both.error;
  const RenderRun colors = run_render(
      dir.path(), "colors",
      "--glb " + quote(glb_colors) + " --out " + quote(dir / "colors") + common + " --three");
  ASSERT_TRUE(colors.error.empty()) << colors.error;

  const Image splats = above_half(posed.alpha);
  std::printf(
      "demo avatar %s: %d Gaussians, template %ld vertices / %ld triangles; export %.2f s "
      "(%s), --mesh --vertex-colors %.2f s; animate (%zu frames) %.1f s\n",
      avatar_path, avatar.num_gaussians(), long(avatar.template_vertices.rows()),
      long(avatar.template_faces.rows()), export_s,
      fs::exists(glb) ? (std::to_string(fs::file_size(glb) / 1000) + " kB").c_str() : "-",
      export_colors_s, walk.frames.size(), animate_s);
  Image three_texture;
  for (const RenderRun* r : {&both, &colors}) {
    const nlohmann::json& t = r->result["three"];
    const Image three = read_image(t["png"].get<std::string>(), 3);
    const Image mesh = differs_from(three, kBackground);
    std::printf(
        "three.js %s: walk frame %d, IoU %.4f, PSNR %.2f dB over the overlap (%.2f dB full "
        "frame); GLTFLoader %.0f ms, first render %.0f ms, next %.0f ms, page %.0f ms, render.mjs "
        "%.1f s (%s)\n",
        r == &both ? "texture" : "COLOR_0", kDemoFrame, iou(mesh, splats),
        psnr_masked(three, posed.color, overlap(mesh, splats)), psnr(three, posed.color),
        t["timings"]["load_ms"].get<double>(), t["timings"]["first_render_ms"].get<double>(),
        t["timings"]["render_ms"].get<double>(), t["timings"]["wall_ms"].get<double>(), r->seconds,
        t["mesh"].dump().c_str());
    if (r == &both) three_texture = three;
  }
  const nlohmann::json& b = both.result["babylon"];
  const Image babylon = read_image(b["png"].get<std::string>(), 3);
  const Image babylon_posed = read_image(b["posed_png"].get<std::string>(), 3);
  std::printf(
      "Babylon.js %s: %d splats (of %d Gaussians) in a GaussianSplattingMesh, skinned mesh %s; "
      "load %.0f ms, settled rest render %.0f ms (%d frames), next %.0f ms, page %.0f ms; IoU "
      "%.4f with kinesplat's rest render, PSNR %.2f dB; after the walk group went to frame %d "
      "%.4f of the pixels changed; groups %s\n",
      b["version"].get<std::string>().c_str(), b["splat_count"].get<int>(), avatar.num_gaussians(),
      b["skinned_mesh"].get<bool>() ? "loaded" : "missing", b["timings"]["load_ms"].get<double>(),
      b["timings"]["rest_render_ms"].get<double>(), b["frames_to_settle"].get<int>(),
      b["timings"]["render_ms"].get<double>(), b["timings"]["wall_ms"].get<double>(),
      iou(differs_from(babylon, kBackground), above_half(rest.alpha)), psnr(babylon, rest.color),
      kDemoFrame, b["posed"]["changed_share"].get<double>(), b["animation_groups"].dump().c_str());
  EXPECT_EQ(b["splat_count"], avatar.num_gaussians());

  if (const char* figures = std::getenv("KS_GLTF_BROWSER_FIGURES")) {
    fs::create_directories(figures);
    write_png((fs::path(figures) / "export_threejs_walk.png").string(),
              side_by_side({animate, three_texture,
                            disagreement(splats, differs_from(three_texture, kBackground))},
                           256, 384));
    write_png((fs::path(figures) / "export_babylon_splats.png").string(),
              side_by_side({rest.color, babylon, babylon_posed}, 256, 256));
  }
}

}  // namespace
}  // namespace ks

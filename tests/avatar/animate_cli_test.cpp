// CLI tests for `kinesplat animate` and `kinesplat export`, run through the
// built binary.
#include <gtest/gtest.h>

#include "temp_dir.hpp"

#include "cli_run.hpp"

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "avatar/tiny_avatar.hpp"
#include "core/fileio.hpp"
#include "gaussians/ply.hpp"
#include "io/image_io.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

using test::CliRun;
using test::run_cli;

struct TmpDir : test::TempDir {
  explicit TmpDir(const std::string& name) : test::TempDir("ks_cli_" + name) {}
  fs::path dir = path();
};

TEST(AnimateCli, WritesPngAndPlyFrames) {
  TmpDir t("animate_png");
  save_avatar(t / "a.ksavatar", test::tiny_avatar());
  const CliRun r = run_cli("animate " + t / "a.ksavatar" +
                           " --motion wave --frames 3 --size 24x32 --ply --out " + t / "frames" +
                           " --camera orbit --background 0,0,0");
  ASSERT_EQ(r.status, 0) << r.output;
  for (int f = 0; f < 3; ++f) {
    char name[16];
    std::snprintf(name, sizeof name, "%04d", f);
    const Image img = read_image(t / ("frames/" + std::string(name) + ".png"), 3);
    EXPECT_EQ(img.width, 24);
    EXPECT_EQ(img.height, 32);
    float sum = 0;
    for (float v : img.data) sum += v;
    EXPECT_GT(sum, 0.f) << "frame " << f << " is empty: the camera does not see the avatar";
    const Gaussians g = read_ply(t / ("frames/" + std::string(name) + ".ply"));
    EXPECT_EQ(g.size(), 6u);
  }
  EXPECT_FALSE(fs::exists(t / "frames/0003.png"));
  EXPECT_NE(r.output.find("wrote 3 frames"), std::string::npos) << r.output;
}

TEST(AnimateCli, ReportsMeanMedianAndSlowestFrame) {
  TmpDir t("animate_times");
  save_avatar(t / "a.ksavatar", test::tiny_avatar());
  const CliRun r = run_cli("animate " + t / "a.ksavatar" +
                           " --motion wave --frames 5 --size 24x32 --out " + t / "frames");
  ASSERT_EQ(r.status, 0) << r.output;
  const size_t at = r.output.find("pose + render ");
  ASSERT_NE(at, std::string::npos) << r.output;
  double mean = -1, fps = -1, median = -1, slowest = -1;
  ASSERT_EQ(std::sscanf(r.output.c_str() + at,
                        "pose + render %lf ms per frame (%lf fps; median %lf ms, slowest %lf ms)",
                        &mean, &fps, &median, &slowest),
            4)
      << r.output;
  // Printed to 0.1 ms: the mean and the median lie within the frames' range.
  EXPECT_GE(mean, 0);
  EXPECT_GE(median, 0);
  EXPECT_LE(mean, slowest + 0.05);
  EXPECT_LE(median, slowest + 0.05);
}

TEST(AnimateCli, WritesMp4WhenFfmpegIsPresent) {
  if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) GTEST_SKIP() << "no ffmpeg";
  TmpDir t("animate_mp4");
  save_avatar(t / "a.ksavatar", test::tiny_avatar());
  const CliRun r = run_cli("animate " + t / "a.ksavatar" +
                           " --motion walk --frames 4 --size 32x32 --out " + t / "clip.mp4");
  ASSERT_EQ(r.status, 0) << r.output;
  ASSERT_TRUE(fs::exists(t / "clip.mp4"));
  EXPECT_GT(fs::file_size(t / "clip.mp4"), 100u);
  EXPECT_FALSE(fs::exists(t / "clip_frames"));  // temporary frames removed
}

TEST(AnimateCli, ClearErrors) {
  TmpDir t("animate_err");
  CliRun r = run_cli("animate " + t / "missing.ksavatar" + " --out " + t / "x");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("error:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("missing.ksavatar"), std::string::npos) << r.output;
  save_avatar(t / "a.ksavatar", test::tiny_avatar());
  r = run_cli("animate " + t / "a.ksavatar" + " --size 10 --out " + t / "x");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--size"), std::string::npos) << r.output;
  r = run_cli("animate " + t / "a.ksavatar" + " --backface-cull 1.5 --out " + t / "x");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--backface-cull"), std::string::npos) << r.output;
  r = run_cli("animate " + t / "a.ksavatar" + " --motion no-such-motion --out " + t / "x");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("no-such-motion"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(t / "x"));
}

TEST(ExportCli, RestAndPosedPly) {
  TmpDir t("export");
  const Avatar a = test::tiny_avatar();
  save_avatar(t / "a.ksavatar", a);
  CliRun r = run_cli("export " + t / "a.ksavatar" + " --out " + t / "rest.ply");
  ASSERT_EQ(r.status, 0) << r.output;
  const Gaussians rest = read_ply(t / "rest.ply");
  ASSERT_EQ(rest.size(), 6u);
  EXPECT_EQ(rest.means, a.gaussians.means);
  EXPECT_EQ(rest.opacity_logits, a.gaussians.opacity_logits);
  // A pose file: global rotation of 90 degrees about Y plus a translation.
  std::vector<double> body(69, 0.0);
  nlohmann::json j = {
      {"global_orient", {0.0, M_PI / 2, 0.0}}, {"body_pose", body}, {"transl", {0.0, 0.0, 1.0}}};
  write_json_atomic(t / "pose.json", j);
  r = run_cli("export " + t / "a.ksavatar" + " --pose " + t / "pose.json" + " --out " +
              t / "posed.ply");
  ASSERT_EQ(r.status, 0) << r.output;
  const Gaussians posed = read_ply(t / "posed.ply");
  ASSERT_EQ(posed.size(), 6u);
  // x' = z, z' = -x + 1.
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(posed.means[3 * i], a.gaussians.means[3 * i + 2], 1e-5);
    EXPECT_NEAR(posed.means[3 * i + 2], -a.gaussians.means[3 * i] + 1.0, 1e-5);
  }
  write_text_atomic(t / "bad.json", "{\"body_pose\": [1, 2]}");
  r = run_cli("export " + t / "a.ksavatar" + " --pose " + t / "bad.json" + " --out " +
              t / "bad.ply");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("body_pose"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(t / "bad.ply"));
  // Betas: the avatar's own are accepted (a dataset's PARAMS.json carries them), others refused
  // (an avatar's shape is fixed when it is trained); so is a non-zero expression.
  nlohmann::json own = j;
  own["betas"] = {0.0, 0.0};
  write_json_atomic(t / "own.json", own);
  r = run_cli("export " + t / "a.ksavatar" + " --pose " + t / "own.json" + " --out " +
              t / "own.ply");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(read_ply(t / "own.ply").means, posed.means);
  nlohmann::json other = j;
  other["betas"] = {1.5};
  write_json_atomic(t / "other.json", other);
  r = run_cli("export " + t / "a.ksavatar" + " --pose " + t / "other.json" + " --out " +
              t / "other.ply");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("betas"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(t / "other.ply"));
}

}  // namespace
}  // namespace ks

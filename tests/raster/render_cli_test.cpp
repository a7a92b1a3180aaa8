// Runs the built `kinesplat` binary (KS_CLI_PATH): render and bench raster.
#include <gtest/gtest.h>

#include "temp_dir.hpp"

#include <sys/wait.h>
#include <unistd.h>
#include "cli_run.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "gaussians/ply.hpp"
#include "io/image_io.hpp"
#include "raster/raster_scene.hpp"
#include "raster/rasterizer.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::run_cli;

struct TmpDir : test::TempDir {
  TmpDir() : test::TempDir("ks_render_cli") {}
  fs::path p = path();
};

TEST(RenderCli, RendersPlyWithCamera) {
  TmpDir d;
  test::SceneOptions o;
  o.n = 30;
  o.sh_degree = 3;
  write_ply((d.p / "s.ply").string(), test::random_scene(o, 3));
  test::test_camera(40, 30).save((d.p / "cam.json").string());
  const auto out = (d.p / "img.png").string();
  const CliRun r =
      run_cli("render " + (d.p / "s.ply").string() + " --camera " + (d.p / "cam.json").string() +
              " --out " + out + " --background 0,0.5,1 --bits 16");
  ASSERT_EQ(r.status, 0) << r.err;
  const Image img = read_image(out);
  ASSERT_EQ(img.width, 40);
  ASSERT_EQ(img.height, 30);
  // The library's render of the same scene: the PNG holds it to 16-bit rounding, and it is not
  // an empty frame (a good part of the image is covered, away from the background colour).
  RasterSettings s;
  s.background[1] = 0.5f, s.background[2] = 1.f;
  RasterResult ref;
  rasterize_forward(read_ply((d.p / "s.ply").string()), test::test_camera(40, 30), s, ref);
  double covered = 0, far_from_bg = 0;
  for (float a : ref.alpha.data) covered += a;
  for (size_t p = 0; p < img.pixel_count(); ++p) {
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(img.data[3 * p + c], std::clamp(ref.color.data[3 * p + c], 0.f, 1.f),
                  1.0f / 65535)
          << "pixel " << p;
    far_from_bg += std::abs(img.data[3 * p] - 0.f) + std::abs(img.data[3 * p + 2] - 1.f) > 0.1;
  }
  EXPECT_GT(covered / double(img.pixel_count()), 0.05);
  EXPECT_GT(far_from_bg / double(img.pixel_count()), 0.02);
}

TEST(RenderCli, BadCameraGivesClearErrorAndNoOutput) {
  TmpDir d;
  test::SceneOptions o;
  o.n = 5;
  write_ply((d.p / "s.ply").string(), test::random_scene(o, 4));
  {
    std::ofstream f(d.p / "cam.json");
    f << "{\"width\": 32, \"height\": 32, \"fx\": 30}";  // missing keys
  }
  const auto out = (d.p / "img.png").string();
  const CliRun r = run_cli("render " + (d.p / "s.ply").string() + " --camera " +
                           (d.p / "cam.json").string() + " --out " + out);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("error:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("camera"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  for (const auto& e : fs::directory_iterator(d.p))
    EXPECT_EQ(e.path().extension() == ".png", false) << e.path();
  // A malformed background is also a clear error.
  test::test_camera(32, 32).save((d.p / "good.json").string());
  const CliRun r3 = run_cli("render " + (d.p / "s.ply").string() + " --camera " +
                            (d.p / "good.json").string() + " --out " + out + " --background 2,0");
  EXPECT_EQ(r3.status, 1);
  EXPECT_NE(r3.err.find("--background"), std::string::npos) << r3.err;
  EXPECT_FALSE(fs::exists(out));
}

TEST(RenderCli, BenchRasterPrintsSummary) {
  const CliRun r =
      run_cli("bench raster --gaussians 2000 --width 64 --height 96 --frames 2 --backward");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("FPS"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("forward+backward"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(std::string("kernel ") + raster_kernel_name({})), std::string::npos)
      << r.out;
  // The machine's state beside the figures (bench/speed_rounds.sh reads this line), unless
  // --no-probe.
  EXPECT_NE(r.out.find("machine speed probe: "), std::string::npos) << r.out;
  const CliRun q =
      run_cli("bench raster --gaussians 500 --width 32 --height 48 --frames 1 --no-probe");
  ASSERT_EQ(q.status, 0) << q.err;
  EXPECT_EQ(q.out.find("machine speed probe"), std::string::npos) << q.out;
}

// --kernel picks the tile kernel (named in the summary); an unknown one, or one the CPU lacks, is
// a clear error.
TEST(RenderCli, BenchRasterKernelOption) {
  const std::string args = "bench raster --gaussians 500 --width 32 --height 48 --frames 1";
  const CliRun r = run_cli(args + " --kernel baseline");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("kernel baseline"), std::string::npos) << r.out;
  const CliRun bad = run_cli(args + " --kernel sse9");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.err.find("--kernel"), std::string::npos) << bad.err;
  if (!raster_avx512_available()) {
    const CliRun none = run_cli(args + " --kernel avx512");
    EXPECT_EQ(none.status, 1);
    EXPECT_NE(none.err.find("AVX-512"), std::string::npos) << none.err;
  }
}

TEST(RenderCli, BenchRasterTimesGivenScene) {
  TmpDir d;
  test::SceneOptions o;
  o.n = 30;
  write_ply((d.p / "s.ply").string(), test::random_scene(o, 5));
  test::test_camera(40, 30).save((d.p / "cam.json").string());
  const std::string args = " --camera " + (d.p / "cam.json").string() + " --frames 1 --backward";
  const CliRun r = run_cli("bench raster --ply " + (d.p / "s.ply").string() + args);
  ASSERT_EQ(r.status, 0) << r.err;
  // The scene's size and the camera's image size, not the defaults (110000, 512x768).
  EXPECT_NE(r.out.find("gaussians 30 "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("40x30"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("forward+backward"), std::string::npos) << r.out;
  // A missing .ply is a clear error naming the file.
  const CliRun bad = run_cli("bench raster --ply " + (d.p / "none.ply").string() + args);
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("none.ply"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace ks

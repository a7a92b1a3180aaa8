// Runs the built `kinesplat` binary (KS_CLI_PATH): render and bench raster.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include "cli_run.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "gaussians/ply.hpp"
#include "io/image_io.hpp"
#include "raster/raster_scene.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::run_cli;

struct TmpDir {
  fs::path p;
  TmpDir() : p(fs::temp_directory_path() / ("ks_render_cli_" + std::to_string(::getpid()))) {
    fs::create_directories(p);
  }
  ~TmpDir() { fs::remove_all(p); }
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
  EXPECT_EQ(img.width, 40);
  EXPECT_EQ(img.height, 30);
  // Corners are background (0, 0.5, 1) unless a Gaussian covers them; most pixels are not black.
  EXPECT_GT(img.at(0, 0, 2) + img.at(39, 29, 2), 0.5f);
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
}

}  // namespace
}  // namespace ks

// `--device cuda` where there is no GPU to use (a build without KS_CUDA, or no device): each
// command that takes it fails at once with a line that says why, and writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "cli_run.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"
#include "temp_dir.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

TEST(RasterCudaCli, DeviceCudaWithoutAGpuFailsClearly) {
  if (cuda::raster_cuda_devices() > 0) GTEST_SKIP() << "a CUDA device is present";
  test::TempDir t("ks_cuda_cli");
  const std::string commands[] = {
      "bench raster --device cuda --gaussians 100 --frames 1",
      "animate " + (t / "a.ksavatar") + " --device cuda --frames 2 --size 16x16 --out " +
          (t / "frames"),
      "reconstruct " + (t / "ds") + " --device cuda --iters 1 -q -o " + (t / "out.ksavatar"),
  };
  for (const std::string& c : commands) {
    SCOPED_TRACE(c);
    const test::CliRun r = test::run_cli(c);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.err.find("--device cuda: "), std::string::npos) << r.err;
    // Why: no backend in this build, or no device.
    EXPECT_TRUE(r.err.find("KS_CUDA") != std::string::npos ||
                r.err.find("no CUDA device") != std::string::npos)
        << r.err;
  }
  EXPECT_TRUE(fs::is_empty(t.path()));
}

TEST(RasterCudaCli, InfoSaysWhatThereIs) {
  const test::CliRun r = test::run_cli("info");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.out.find("rasterizer tile kernel on this CPU: "), std::string::npos) << r.out;
  const std::string want = cuda::raster_cuda_compiled()
                               ? "CUDA rasterizer: " + cuda::raster_cuda_describe()
                               : "CUDA rasterizer: not in this build";
  EXPECT_NE(r.out.find(want), std::string::npos) << r.out;
}

}  // namespace
}  // namespace ks

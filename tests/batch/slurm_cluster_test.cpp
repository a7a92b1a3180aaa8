// The Slurm end-to-end test (scripts/test_slurm.sh, `make test-slurm`) inside the suite: it runs
// where Slurm is installed and the suite runs as root, and is skipped with the reason otherwise
// (the script exits 77 then). KS_SKIP_SLURM=1 skips it.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "temp_dir.hpp"

namespace {

TEST(BatchSlurmCluster, ThreeItemsOneBrokenOnALoopbackCluster) {
  if (std::getenv("KS_SKIP_SLURM")) GTEST_SKIP() << "KS_SKIP_SLURM is set";
  ks::test::TempDir dir("ks_slurm_test");
  const std::string log = dir / "test_slurm.log";
  // No apt-get from the suite; a batch must finish well inside ctest's 600 s limit (a
  // sanitizer build, whose items run several times slower, sets KS_SLURM_TIMEOUT and a longer
  // ctest limit: `make test-sanitize`).
  const char* env_timeout = std::getenv("KS_SLURM_TIMEOUT");
  std::string timeout = env_timeout && *env_timeout ? env_timeout : "420";
  if (timeout.find_first_not_of("0123456789") != std::string::npos) timeout = "420";
  const std::string cmd = "KS_SLURM_NO_INSTALL=1 KS_SLURM_TIMEOUT=" + timeout + " " +
                          std::string(KS_SOURCE_DIR) + "/scripts/test_slurm.sh " + KS_CLI_PATH +
                          " >" + log + " 2>&1";
  const int rc = std::system(cmd.c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  const int status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  if (status == 77) GTEST_SKIP() << ss.str();
  EXPECT_EQ(status, 0) << ss.str();
  EXPECT_NE(ss.str().find("test-slurm: PASSED"), std::string::npos) << ss.str();
}

}  // namespace

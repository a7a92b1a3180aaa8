// `kinesplat batch` and `kinesplat batch status` through the built program: the manifest's options
// checked against `create`'s own, options refused where the scheduler would ignore them, the
// scheduler files, and a local batch of a fake, fast item program.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_run.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

void write(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path) << text;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string q(const std::string& s) {
  return "'" + s + "'";
}

// Two photos and a manifest with an option `create` takes (--iters).
void two_items(const ks::test::TempDir& dir) {
  write(dir / "a.png", "a");
  write(dir / "b.png", "broken");
  write(dir / "m.csv", "id,photo,iters\na,a.png,5\nb,b.png,\n");
}

TEST(BatchCli, ManifestOptionsAreCreatesAndProblemsComeAtOnce) {
  ks::test::TempDir dir("ks_batch_cli");
  write(dir / "a.png", "a");
  write(dir / "m.csv", "id,photo,stepz,out\na,a.png,1,x\na,none.png,,\n");
  const auto r = ks::test::run_cli("batch " + q(dir / "m.csv") + " --out " + q(dir / "out"));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("error: " + (dir / "m.csv") + ": 4 problems, nothing was run"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("unknown option 'stepz'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("'out' is set by batch"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("duplicate id 'a'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("none.png does not exist"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST(BatchCli, RefusesOptionsTheSchedulerIgnores) {
  ks::test::TempDir dir("ks_batch_cli");
  two_items(dir);
  const std::string base = "batch " + q(dir / "m.csv") + " --out " + q(dir / "out");
  for (const auto& [args, msg] : std::vector<std::pair<std::string, std::string>>{
           {" --jobs 2 --scheduler slurm", "--jobs has no effect with --scheduler slurm"},
           {" --partition cpu", "--partition has no effect with --scheduler local"},
           {" --image x --scheduler slurm", "--image has no effect with --scheduler slurm"},
           {" --scheduler pbs", "--scheduler pbs: expected local, slurm or k8s"},
           {" --scheduler slurm --mem 4X", "--mem 4X: expected a memory size"},
           {" --scheduler k8s", "--scheduler k8s needs --image"}}) {
    const auto r = ks::test::run_cli(base + args);
    EXPECT_EQ(r.status, 1) << args;
    EXPECT_NE(r.err.find(msg), std::string::npos) << args << ": " << r.err;
  }
  const auto none = ks::test::run_cli("batch --out " + q(dir / "out"));
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.err.find("batch needs a MANIFEST"), std::string::npos) << none.err;
}

TEST(BatchCli, SlurmDryRunAndKubernetesFiles) {
  ks::test::TempDir dir("ks_batch_cli");
  two_items(dir);
  const std::string base = "batch " + q(dir / "m.csv") + " --out " + q(dir / "out");
  const auto s = ks::test::run_cli(base +
                                   " --scheduler slurm --dry-run --cpus 3 --mem 5G "
                                   "--partition cpu --time 1:00:00 --sbatch-arg=--qos=low");
  ASSERT_EQ(s.status, 0) << s.output;
  const std::string sb = slurp(dir / "out/batch.sbatch");
  EXPECT_NE(sb.find("#SBATCH --cpus-per-task=3\n#SBATCH --mem=5120M\n"), std::string::npos) << sb;
  EXPECT_NE(sb.find("#SBATCH --qos=low\n"), std::string::npos) << sb;
  EXPECT_NE(sb.find("KINESPLAT='" + fs::canonical(KS_CLI_PATH).string() + "'"), std::string::npos)
      << sb;
  EXPECT_NE(sb.find("'--iters' '5'"), std::string::npos) << sb;
  const auto k = ks::test::run_cli(base + " --scheduler k8s --image reg/ks:1 --volume " +
                                   q("data:" + dir.str()) + " --parallelism 2 --cpus 4");
  ASSERT_EQ(k.status, 0) << k.output;
  EXPECT_NE(k.out.find("kubectl apply -f"), std::string::npos) << k.out;
  const auto job = nlohmann::json::parse(slurp(dir / "out/batch.k8s.json"));
  EXPECT_EQ(job["spec"]["completionMode"], "Indexed");
  EXPECT_EQ(job["spec"]["completions"], 2);
  EXPECT_EQ(job["spec"]["template"]["spec"]["containers"][0]["resources"]["requests"]["cpu"], "4");
  // The pods must see the paths: a volume elsewhere is refused.
  const auto bad =
      ks::test::run_cli(base + " --scheduler k8s --image reg/ks:1 --volume data:/elsewhere");
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("the pods would not see"), std::string::npos) << bad.err;
}

TEST(BatchCli, LocalBatchAndStatus) {
  ks::test::TempDir dir("ks_batch_cli");
  two_items(dir);
  const std::string fake = dir / "fake-kinesplat";
  write(
      fake,
      "#!/bin/sh\n"
      "out=$4; mkdir -p \"$out\"\n"
      "if grep -q broken \"$2\"; then\n"
      "  echo '{\"status\": \"failed\", \"error\": \"no person in the photo\"}' > "
      "\"$out/create.json\"\n"
      "  echo 'error: no person in the photo' >&2; exit 1\n"
      "fi\n"
      "echo x > \"$out/avatar.ksavatar\"; echo '{\"status\": \"done\"}' > \"$out/create.json\"\n");
  ::chmod(fake.c_str(), 0755);
  const auto r = ks::test::run_cli("batch " + q(dir / "m.csv") + " --out " + q(dir / "out") +
                                   " --kinesplat " + q(fake));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.out.find("b FAILED: no person in the photo"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("error: 1 item failed"), std::string::npos) << r.err;
  const auto st = ks::test::run_cli("batch status " + q(dir / "out"));
  EXPECT_EQ(st.status, 0) << st.output;
  EXPECT_NE(st.out.find("a   done"), std::string::npos) << st.out;
  EXPECT_NE(st.out.find("b   failed   no person in the photo"), std::string::npos) << st.out;
  EXPECT_NE(st.out.find("2 items: 1 done, 1 failed, 0 pending"), std::string::npos) << st.out;
  const auto js = ks::test::run_cli("batch status --json " + q(dir / "out"));
  ASSERT_EQ(js.status, 0) << js.output;
  const auto j = nlohmann::json::parse(js.out);
  EXPECT_EQ(j["items"][1]["state"], "failed");
  EXPECT_EQ(j["items"][1]["error"], "no person in the photo");
  const auto none = ks::test::run_cli("batch status " + q(dir / "nothing"));
  EXPECT_EQ(none.status, 1);
  EXPECT_NE(none.err.find("holds no batch"), std::string::npos) << none.err;
}

}  // namespace

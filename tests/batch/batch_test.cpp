// The batch's schedulers: the sbatch script, the Kubernetes Indexed Job, item status from the
// items' own outputs, and the local scheduler running a fake, fast item command through the same
// task script every scheduler uses.
#include "batch/batch.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

const ks::ItemOptionSpec kSpec = {{"steps", true}, {"force", false}};

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

// Three photos (b is "broken": the fake item command fails on it) and their manifest.
ks::Manifest three_items(const ks::test::TempDir& dir) {
  write(dir / "photos/a.png", "a");
  write(dir / "photos/b.png", "broken");
  write(dir / "photos/c.png", "c");
  write(dir / "m.csv",
        "id,photo,steps,force\na,photos/a.png,20,\nb,photos/b.png,,\nc,photos/c.png,,1\n");
  return ks::parse_manifest(dir / "m.csv", kSpec);
}

// A stand-in for `kinesplat`: `create PHOTO --out DIR ...` that honours create's contract
// (create.json done / failed, avatar.ksavatar, `error: ...` on stderr) in a few milliseconds, and
// counts its calls per item.
std::string fake_kinesplat(const ks::test::TempDir& dir) {
  const std::string path = dir / "fake-kinesplat";
  write(path,
        "#!/bin/sh\n"
        "[ \"$1\" = create ] || { echo \"error: expected create, got $1\" >&2; exit 2; }\n"
        "photo=$2; out=$4\n"
        "mkdir -p \"$out\" && echo \"$*\" >> \"$out/calls\"\n"
        "if grep -q broken \"$photo\"; then\n"
        "  printf '{\"status\": \"failed\", \"error\": \"%s: no person found\"}' \"$photo\" > "
        "\"$out/create.json\"\n"
        "  echo \"error: $photo: no person found\" >&2; exit 1\n"
        "fi\n"
        "echo avatar > \"$out/avatar.ksavatar\"\n"
        "echo '{\"status\": \"done\"}' > \"$out/create.json\"\n");
  ::chmod(path.c_str(), 0755);
  return path;
}

int count_lines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) ++n;
  return n;
}

TEST(BatchSlurm, ScriptHasTheArrayResourcesAndItemTable) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  ks::BatchOptions o;
  o.scheduler = ks::Scheduler::kSlurm;
  o.out_dir = dir / "out";
  o.kinesplat = "/opt/ks/bin/kinesplat";
  o.resources.cpus = 4;
  o.resources.memory_mb = 6000;
  o.slurm.partition = "cpu";
  o.slurm.time_limit = "2:00:00";
  o.slurm.max_running = 2;
  o.slurm.extra_args = {"--account=lab"};
  const std::string s = ks::slurm_script(m, {0, 2}, o);
  EXPECT_EQ(s.rfind("#!/bin/sh\n", 0), 0u);
  for (const char* line :
       {"#SBATCH --array=0,2%2\n", "#SBATCH --cpus-per-task=4\n", "#SBATCH --mem=6000M\n",
        "#SBATCH --partition=cpu\n", "#SBATCH --time=2:00:00\n", "#SBATCH --account=lab\n",
        "#SBATCH --job-name=kinesplat-batch\n", "IDX=\"$SLURM_ARRAY_TASK_ID\"\n",
        "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-4}\"\n",
        "KINESPLAT='/opt/ks/bin/kinesplat'\n"})
    EXPECT_NE(s.find(line), std::string::npos) << line << "\n" << s;
  EXPECT_NE(s.find("#SBATCH --output=" + (dir / "out/slurm/%A_%a.out") + "\n"), std::string::npos);
  // Rows 0 and 2 in the table under their manifest rows; row 1 not there.
  EXPECT_NE(s.find("  0) ID='a'; DIR='" + (dir / "out/items/a") + "'\n     set -- 'create' '" +
                   (dir / "photos/a.png") + "' '--out' '" + (dir / "out/items/a") +
                   "' '--steps' '20' ;;\n"),
            std::string::npos)
      << s;
  EXPECT_NE(
      s.find("  2) ID='c'; DIR='" + (dir / "out/items/c") + "'\n     set -- 'create' '" +
             (dir / "photos/c.png") + "' '--out' '" + (dir / "out/items/c") + "' '--force' ;;\n"),
      std::string::npos)
      << s;
  EXPECT_EQ(s.find("ID='b'"), std::string::npos);
  // The #SBATCH lines come before the first command (sbatch stops reading them there).
  EXPECT_LT(s.find("#SBATCH --account=lab"), s.find("IDX="));
  // Without the optional ones, no such lines.
  ks::BatchOptions plain;
  plain.scheduler = ks::Scheduler::kSlurm;
  plain.out_dir = dir / "out";
  const std::string p = ks::slurm_script(m, {0, 1, 2}, plain);
  EXPECT_NE(p.find("#SBATCH --array=0,1,2\n"), std::string::npos);
  EXPECT_EQ(p.find("--partition"), std::string::npos);
  EXPECT_EQ(p.find("--time"), std::string::npos);
}

TEST(BatchSlurm, DryRunWritesTheScriptAndSubmitsNothing) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  ks::BatchOptions o;
  o.scheduler = ks::Scheduler::kSlurm;
  o.out_dir = dir / "out";
  o.slurm.dry_run = true;
  o.slurm.sbatch = dir / "no-such-sbatch";
  std::ostringstream log;
  EXPECT_EQ(ks::run_batch(m, o, log), 0);
  EXPECT_TRUE(fs::exists(dir / "out/batch.sbatch"));
  EXPECT_NE(log.str().find("not submitted: --dry-run"), std::string::npos);
  const auto r = ks::batch_status(dir / "out");
  ASSERT_EQ(r.items.size(), 3u);
  EXPECT_EQ(r.count(ks::ItemState::kPending), 3);
}

TEST(BatchSlurm, SubmitsWithSbatchAndRecordsTheJob) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  // A stand-in sbatch that answers as `sbatch --parsable` does and keeps the script it got.
  const std::string sbatch = dir / "fake-sbatch";
  write(sbatch, "#!/bin/sh\ncp \"$2\" \"" + (dir / "submitted.sh") + "\"\necho 4242\n");
  ::chmod(sbatch.c_str(), 0755);
  ks::BatchOptions o;
  o.scheduler = ks::Scheduler::kSlurm;
  o.out_dir = dir / "out";
  o.slurm.sbatch = sbatch;
  std::ostringstream log;
  ks::run_batch(m, o, log);
  EXPECT_NE(log.str().find("as Slurm job 4242"), std::string::npos) << log.str();
  EXPECT_NE(slurp(dir / "submitted.sh").find("#SBATCH --array=0,1,2\n"), std::string::npos);
  const auto r = ks::batch_status(dir / "out");
  EXPECT_EQ(r.count(ks::ItemState::kQueued), 3);
  EXPECT_EQ(r.items[0].status.job, "4242");
  EXPECT_EQ(r.items[0].status.submitted_by, "slurm");
  // Submitted and not finished: a second batch hands nothing over again, --resubmit does.
  std::ostringstream again;
  ks::run_batch(m, o, again);
  EXPECT_NE(again.str().find("3 submitted before and not finished"), std::string::npos)
      << again.str();
  EXPECT_NE(again.str().find("0 to submit"), std::string::npos) << again.str();
  // A failing sbatch is an error with its message.
  write(sbatch, "#!/bin/sh\necho 'sbatch: error: invalid partition' >&2\nexit 1\n");
  o.resubmit = true;
  try {
    ks::run_batch(m, o, again);
    FAIL() << "expected an error";
  } catch (const ks::Error& e) {
    EXPECT_NE(std::string(e.what()).find("invalid partition"), std::string::npos) << e.what();
  }
}

TEST(BatchK8s, IndexedJobStructure) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  ks::BatchOptions o;
  o.scheduler = ks::Scheduler::kK8s;
  o.out_dir = dir / "out";
  o.k8s.image = "registry.example/kinesplat:0.1";
  o.k8s.volumes = {{"avatars", dir.str()}};
  o.k8s.k8s_namespace = "studio";
  o.k8s.parallelism = 8;
  o.resources.cpus = 3;
  o.resources.memory_mb = 5000;
  const nlohmann::json j = ks::k8s_job(m, {1, 2}, o);
  EXPECT_EQ(j["apiVersion"], "batch/v1");
  EXPECT_EQ(j["kind"], "Job");
  EXPECT_EQ(j["metadata"]["name"], "kinesplat-batch");
  EXPECT_EQ(j["metadata"]["namespace"], "studio");
  const auto& spec = j["spec"];
  EXPECT_EQ(spec["completionMode"], "Indexed");
  EXPECT_EQ(spec["completions"], 2);
  EXPECT_EQ(spec["parallelism"], 2);  // never more than the items
  EXPECT_EQ(spec["backoffLimitPerIndex"], 0);
  const auto& pod = spec["template"]["spec"];
  EXPECT_EQ(pod["restartPolicy"], "Never");
  ASSERT_EQ(pod["containers"].size(), 1u);
  const auto& c = pod["containers"][0];
  EXPECT_EQ(c["image"], "registry.example/kinesplat:0.1");
  EXPECT_EQ(c["resources"]["requests"]["cpu"], "3");
  EXPECT_EQ(c["resources"]["requests"]["memory"], "5000Mi");
  EXPECT_EQ(c["resources"]["limits"]["memory"], "5000Mi");
  EXPECT_EQ(c["env"][0]["name"], "OMP_NUM_THREADS");
  EXPECT_EQ(c["env"][0]["value"], "3");
  ASSERT_EQ(pod["volumes"].size(), 1u);
  EXPECT_EQ(pod["volumes"][0]["persistentVolumeClaim"]["claimName"], "avatars");
  EXPECT_EQ(c["volumeMounts"][0]["name"], pod["volumes"][0]["name"]);
  EXPECT_EQ(c["volumeMounts"][0]["mountPath"], dir.str());
  // The completion index picks the row: index 0 -> item b (row 1), index 1 -> item c (row 2).
  ASSERT_EQ(c["command"].size(), 3u);
  EXPECT_EQ(c["command"][0], "/bin/sh");
  const std::string script = c["command"][2];
  EXPECT_EQ(script.rfind("IDX=\"$JOB_COMPLETION_INDEX\"\n", 0), 0u);
  EXPECT_NE(script.find("KINESPLAT='kinesplat'\n"), std::string::npos);
  EXPECT_NE(script.find("  0) ID='b';"), std::string::npos) << script;
  EXPECT_NE(script.find("  1) ID='c';"), std::string::npos) << script;
  EXPECT_EQ(script.find("ID='a'"), std::string::npos);
}

TEST(BatchK8s, RefusesPathsThePodsCannotSeeAndMissingImage) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  ks::BatchOptions o;
  o.scheduler = ks::Scheduler::kK8s;
  o.out_dir = dir / "out";
  EXPECT_THROW(ks::k8s_job(m, {0}, o), ks::Error);  // no image
  o.k8s.image = "img";
  o.k8s.volumes = {{"out", dir / "out"}};
  try {
    ks::k8s_job(m, {0, 1}, o);
    FAIL() << "expected an error";
  } catch (const ks::Error& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("item a's photo " + (dir / "photos/a.png")), std::string::npos) << w;
    EXPECT_NE(w.find("item b's photo"), std::string::npos) << w;
    EXPECT_EQ(w.find("output directory"), std::string::npos) << w;
  }
  EXPECT_EQ(ks::parse_k8s_volume("pvc-1:/data").claim, "pvc-1");
  EXPECT_EQ(ks::parse_k8s_volume("pvc-1:/data").mount, "/data");
  EXPECT_THROW(ks::parse_k8s_volume("pvc-1"), ks::Error);
  EXPECT_THROW(ks::parse_k8s_volume("pvc-1:data"), ks::Error);
  EXPECT_THROW(ks::parse_k8s_volume(":/data"), ks::Error);
}

TEST(BatchStatus, FromTheItemsOwnOutputs) {
  ks::test::TempDir dir("ks_batch");
  auto state = [&](const std::string& id) { return ks::read_item_status(dir / ("items/" + id)); };
  // Nothing there: pending.
  EXPECT_EQ(state("none").state, ks::ItemState::kPending);
  // Done: create.json done and the avatar, with the task's figures.
  write(dir / "items/done/create.json", "{\"status\": \"done\"}");
  write(dir / "items/done/avatar.ksavatar", "x");
  write(dir / "items/done/exit_status", "0\n");
  write(dir / "items/done/resources", "83.52 1843200\n");
  EXPECT_EQ(state("done").state, ks::ItemState::kDone);
  EXPECT_DOUBLE_EQ(state("done").seconds, 83.52);
  EXPECT_EQ(state("done").peak_kb, 1843200);
  // create.json says done but the avatar is gone: not done.
  write(dir / "items/noavatar/create.json", "{\"status\": \"done\"}");
  write(dir / "items/noavatar/exit_status", "0\n");
  EXPECT_EQ(state("noavatar").state, ks::ItemState::kFailed);
  EXPECT_NE(state("noavatar").error.find("no finished avatar"), std::string::npos);
  // Failed with create's own error.
  write(dir / "items/failed/create.json",
        "{\"status\": \"failed\", \"error\": \"x.png: no person\"}");
  write(dir / "items/failed/exit_status", "1\n");
  EXPECT_EQ(state("failed").state, ks::ItemState::kFailed);
  EXPECT_EQ(state("failed").error, "x.png: no person");
  // Failed before create.json existed: the log's last error line.
  write(dir / "items/log/create.log", "error: first\nsome output\nerror: cannot read x.png\n");
  write(dir / "items/log/exit_status", "1\n");
  EXPECT_EQ(state("log").error, "cannot read x.png");
  // Killed (time limit): exit status 137 / 143, GNU time's note before its figures.
  write(dir / "items/killed/exit_status", "137\n");
  write(dir / "items/killed/resources", "Command terminated by signal 9\n12.5 204800\n");
  EXPECT_EQ(state("killed").state, ks::ItemState::kFailed);
  EXPECT_NE(state("killed").error.find("killed by signal 9"), std::string::npos);
  EXPECT_DOUBLE_EQ(state("killed").seconds, 12.5);
  // Submitted, started: queued, running; a previous attempt's create.json failed is not the state.
  write(dir / "items/queued/submitted", "slurm 77 2026-01-01T00:00:00Z\n");
  write(dir / "items/queued/create.json", "{\"status\": \"failed\", \"error\": \"old\"}");
  EXPECT_EQ(state("queued").state, ks::ItemState::kQueued);
  EXPECT_EQ(state("queued").job, "77");
  write(dir / "items/queued/started", "node1\n");
  EXPECT_EQ(state("queued").state, ks::ItemState::kRunning);
  // A create run by hand that failed, never through batch: failed.
  write(dir / "items/byhand/create.json", "{\"status\": \"failed\", \"error\": \"bad\\nmore\"}");
  EXPECT_EQ(state("byhand").state, ks::ItemState::kFailed);
  EXPECT_EQ(state("byhand").error, "bad");
  // Unreadable create.json with an exit status 0: failed, saying so.
  write(dir / "items/garbled/create.json", "{not json");
  write(dir / "items/garbled/exit_status", "0\n");
  EXPECT_EQ(state("garbled").state, ks::ItemState::kFailed);
}

TEST(BatchStatus, MalformedBatchDirectory) {
  ks::test::TempDir dir("ks_batch");
  EXPECT_THROW(ks::batch_status(dir.str()), ks::Error);  // no batch.json
  write(dir / "batch.json", "{\"items\": 3}");
  EXPECT_THROW(ks::batch_status(dir.str()), ks::Error);
  write(dir / "batch.json", "{\"items\": [{\"id\": \"../x\"}]}");
  EXPECT_THROW(ks::batch_status(dir.str()), ks::Error);
  write(dir / "batch.json", "{\"items\": [");
  EXPECT_THROW(ks::batch_status(dir.str()), ks::Error);
}

TEST(BatchLocal, RunsItemsReportsTheFailureAndRerunsOnlyIt) {
  ks::test::TempDir dir("ks_batch");
  const ks::Manifest m = three_items(dir);
  ks::BatchOptions o;
  o.out_dir = dir / "out";
  o.kinesplat = fake_kinesplat(dir);
  o.jobs = 2;
  std::ostringstream log;
  EXPECT_EQ(ks::run_batch(m, o, log), 1);
  const std::string l = log.str();
  EXPECT_NE(l.find("3 items, 0 done; 3 to run here"), std::string::npos) << l;
  EXPECT_NE(l.find("] b FAILED: " + (dir / "photos/b.png") + ": no person found"),
            std::string::npos)
      << l;
  EXPECT_NE(l.find("2 of 3 done here, 1 failed"), std::string::npos) << l;
  auto r = ks::batch_status(dir / "out");
  EXPECT_EQ(r.count(ks::ItemState::kDone), 2);
  EXPECT_EQ(r.count(ks::ItemState::kFailed), 1);
  EXPECT_EQ(r.items[1].status.error, dir / "photos/b.png" + std::string(": no person found"));
  // The item command's arguments and its log.
  EXPECT_EQ(slurp(dir / "out/items/a/calls"), "create " + (dir / "photos/a.png") + " --out " +
                                                  (dir / "out/items/a") + " --steps 20\n");
  EXPECT_NE(slurp(dir / "out/items/c/calls").find(" --force"), std::string::npos);
  EXPECT_NE(slurp(dir / "out/items/b/create.log").find("error: "), std::string::npos);
  std::ostringstream table;
  ks::print_status(r, table);
  EXPECT_NE(table.str().find("3 items: 2 done, 1 failed, 0 pending"), std::string::npos)
      << table.str();
  // Again: only the failed item runs (the others are done).
  std::ostringstream again;
  EXPECT_EQ(ks::run_batch(m, o, again), 1);
  EXPECT_NE(again.str().find("3 items, 2 done; 1 to run here"), std::string::npos) << again.str();
  EXPECT_EQ(count_lines(dir / "out/items/a/calls"), 1);
  EXPECT_EQ(count_lines(dir / "out/items/b/calls"), 2);
  // The photo fixed, the next batch finishes it.
  write(dir / "photos/b.png", "b");
  std::ostringstream fixed;
  EXPECT_EQ(ks::run_batch(m, o, fixed), 0);
  r = ks::batch_status(dir / "out");
  EXPECT_EQ(r.count(ks::ItemState::kDone), 3);
  const nlohmann::json rec = ks::read_json(dir / "out/batch.json");
  EXPECT_EQ(rec["runs"].size(), 3u);
  EXPECT_EQ(rec["runs"][1]["items"], nlohmann::json::array({"b"}));
  std::ostringstream nothing;
  EXPECT_EQ(ks::run_batch(m, o, nothing), 0);
  EXPECT_NE(nothing.str().find("3 items, 3 done; 0 to run here"), std::string::npos);
}

TEST(BatchOptions, MemorySizesAndSchedulers) {
  EXPECT_EQ(ks::parse_memory_mb("4G", "--mem"), 4096);
  EXPECT_EQ(ks::parse_memory_mb("4Gi", "--mem"), 4096);
  EXPECT_EQ(ks::parse_memory_mb("3500M", "--mem"), 3500);
  EXPECT_EQ(ks::parse_memory_mb("3500", "--mem"), 3500);
  EXPECT_EQ(ks::parse_memory_mb("1.5G", "--mem"), 1536);
  EXPECT_EQ(ks::parse_memory_mb("1536K", "--mem"), 2);
  for (const char* bad : {"", "G", "-1G", "4X", "0", "nan"})
    EXPECT_THROW(ks::parse_memory_mb(bad, "--mem"), ks::Error) << bad;
  EXPECT_EQ(ks::parse_scheduler("slurm"), ks::Scheduler::kSlurm);
  EXPECT_THROW(ks::parse_scheduler("pbs"), ks::Error);
}

}  // namespace

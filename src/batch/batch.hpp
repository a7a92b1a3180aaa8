#pragma once
// `kinesplat batch` (docs/batch.md): one avatar per manifest row, each an independent run of the
// item command (`kinesplat create PHOTO --out DIR/items/ID ...`), handed to a scheduler:
//   local  runs the items here, N at a time;
//   slurm  writes DIR/batch.sbatch (a job array, one task per item) and submits it with sbatch;
//   k8s    writes DIR/batch.k8s.json, an Indexed Job (the completion index picks the item).
// Every scheduler runs the same per-item task script (task_script_body), which records the item's
// start, exit status and resources beside create's own outputs; `batch status` reads those.
// Re-running batch on the same DIR hands over only the items that are not done.
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "batch/manifest.hpp"
#include "batch/status.hpp"

namespace ks {

enum class Scheduler { kLocal, kSlurm, kK8s };
Scheduler parse_scheduler(const std::string& name);  // local|slurm|k8s, else ks::Error
const char* scheduler_name(Scheduler s);

// What one item needs, from the figures measured for `kinesplat create` at its defaults
// (docs/batch.md, "Planning a cluster run"). Used by slurm (--cpus-per-task, --mem) and k8s
// (requests and limits).
struct ItemResources {
  int cpus = 2;
  int memory_mb = 3072;
};

// "4G", "4096M", "4096" (MiB), "512K": MiB, rounded up; ks::Error naming `flag` otherwise.
int parse_memory_mb(const std::string& text, const std::string& flag);

struct SlurmOptions {
  std::string partition;                // empty: the cluster's default partition
  std::string time_limit;               // sbatch --time (empty: the partition's default)
  int max_running = 0;                  // at most this many tasks at once (--array=...%N), 0: any
  std::vector<std::string> extra_args;  // each becomes an "#SBATCH ARG" line
  std::string job_name = "kinesplat-batch";
  std::string sbatch = "sbatch";  // the program that submits
  bool dry_run = false;           // write DIR/batch.sbatch only
};

struct K8sVolume {
  std::string claim;  // a PersistentVolumeClaim's name
  std::string mount;  // where the pods see it (absolute)
};
// "CLAIM:/MOUNT/PATH"; ks::Error otherwise.
K8sVolume parse_k8s_volume(const std::string& text);

struct K8sOptions {
  std::string image;  // the container image with kinesplat (required)
  std::string job_name = "kinesplat-batch";
  std::string k8s_namespace;  // empty: the namespace kubectl uses
  int parallelism = 4;        // pods at once
  std::vector<K8sVolume> volumes;
};

struct BatchOptions {
  Scheduler scheduler = Scheduler::kLocal;
  std::string out_dir;
  // The kinesplat program the tasks run: empty = this program (local, slurm: its absolute path,
  // which the cluster's nodes must see) or "kinesplat" on the image's PATH (k8s).
  std::string kinesplat;
  std::string item_command = "create";
  int jobs = 1;           // local: items at once
  bool resubmit = false;  // slurm: hand over again items submitted before and not finished
  ItemResources resources;
  SlurmOptions slurm;
  K8sOptions k8s;
};

// The task script shared by every scheduler, from the item table on: expects $IDX to hold the
// task's index, runs `kinesplat ITEM_COMMAND ...` for the item that index names (rows[i] is the
// manifest row of index keys[i]) with its output in DIR/items/ID/create.log, and records
// started / exit_status / resources in DIR/items/ID/. Exits with the item command's status.
std::string task_script_body(const Manifest& m, const std::vector<int>& keys,
                             const std::vector<int>& rows, const std::string& out_dir,
                             const std::string& kinesplat, const std::string& item_command);

// The argument list of one item's command (without the program): ITEM_COMMAND PHOTO --out
// DIR/items/ID [--option value | --flag]...
std::vector<std::string> item_arguments(const BatchItem& item, const std::string& out_dir,
                                        const std::string& item_command);

// DIR/batch.sbatch's text: a job array over `rows` (manifest rows) with the resources above.
std::string slurm_script(const Manifest& m, const std::vector<int>& rows, const BatchOptions& o);

// The Indexed Job for `rows`: completions = rows.size(), completion index i runs rows[i].
nlohmann::json k8s_job(const Manifest& m, const std::vector<int>& rows, const BatchOptions& o);

// Runs the batch: writes DIR/batch.json, picks the items that are not done, and runs / submits /
// writes them for o.scheduler. Progress and a summary go to `out`. Returns the number of items
// that failed (local only; 0 for a submission).
int run_batch(const Manifest& m, const BatchOptions& o, std::ostream& out);

struct BatchItemReport {
  std::string id;
  ItemStatus status;
};
struct BatchStatusReport {
  std::string dir;
  std::vector<BatchItemReport> items;
  int count(ItemState s) const;
};

// The state of every item of the batch in `dir` (from DIR/batch.json and the items' outputs);
// ks::Error if `dir` holds no batch.
BatchStatusReport batch_status(const std::string& dir);

// The report as a table with a summary line and each failure's error.
void print_status(const BatchStatusReport& r, std::ostream& out);

}  // namespace ks

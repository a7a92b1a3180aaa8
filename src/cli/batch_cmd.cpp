// `kinesplat batch MANIFEST --out DIR`: an avatar per manifest row, run here or handed to Slurm /
// Kubernetes; `kinesplat batch status DIR` (docs/batch.md).
#include <algorithm>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "batch/batch.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"

namespace {

// The command each item runs; its own options are what a manifest may set.
const char* const kItemCommand = "create";

ks::ItemOptionSpec item_option_spec(CLI::App* root) {
  CLI::App* cmd = nullptr;
  for (CLI::App* s : root->get_subcommands([](CLI::App*) { return true; }))
    if (s->get_name() == kItemCommand) cmd = s;
  if (!cmd)
    throw ks::Error(std::string("this kinesplat has no `") + kItemCommand +
                    "` command for the items to run");
  ks::ItemOptionSpec spec;
  for (const CLI::Option* o : cmd->get_options())
    for (const std::string& name : o->get_lnames()) spec[name] = o->get_type_size() != 0;
  return spec;
}

struct Args {
  ks::BatchOptions opt;
  std::string manifest, scheduler = ks::scheduler_name(opt.scheduler), mem;
  std::vector<std::string> volumes;
  std::string status_dir;
  bool status_json = false;
};

ks::cli::CommandGroup group(35, [](CLI::App& app) {
  auto a = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "batch",
      std::string("An avatar for every row of a manifest (`") + kItemCommand +
          "` per item), run here or handed to Slurm or Kubernetes; `batch status DIR` follows it");
  sub->add_option("manifest", a->manifest,
                  "CSV or JSON lines: id, photo and per-item options of `create`");
  sub->add_option("--out,-o", a->opt.out_dir, "Batch directory (items in DIR/items/ID/)");
  sub->add_option("--scheduler", a->scheduler, "local|slurm|k8s")->capture_default_str();
  sub->add_option(
      "--kinesplat", a->opt.kinesplat,
      "The kinesplat program the tasks run (default: this one; `kinesplat` on the image's PATH "
      "with k8s)");
  auto* jobs = sub->add_option("--jobs,-j", a->opt.jobs, "local: items at once")
                   ->check(CLI::Range(1, 256))
                   ->capture_default_str();
  auto* cpus = sub->add_option("--cpus", a->opt.resources.cpus,
                               "slurm/k8s: CPUs per item (docs/batch.md has the measured figures)")
                   ->check(CLI::Range(1, 1024))
                   ->capture_default_str();
  auto* mem = sub->add_option("--mem", a->mem,
                              "slurm/k8s: memory per item, e.g. 4G or 3500M (default " +
                                  std::to_string(a->opt.resources.memory_mb) + "M)");
  auto* partition = sub->add_option("--partition", a->opt.slurm.partition, "slurm: partition");
  auto* time = sub->add_option("--time", a->opt.slurm.time_limit,
                               "slurm: time limit per item (sbatch --time, e.g. 1:00:00)");
  auto* max_running = sub->add_option("--max-running", a->opt.slurm.max_running,
                                      "slurm: at most this many items at once (0: no limit)")
                          ->check(CLI::NonNegativeNumber);
  auto* sbatch_arg =
      sub->add_option("--sbatch-arg", a->opt.slurm.extra_args,
                      "slurm: an extra sbatch argument, e.g. --sbatch-arg=--account=lab (repeat)");
  auto* sbatch = sub->add_option("--sbatch", a->opt.slurm.sbatch, "slurm: the sbatch program")
                     ->capture_default_str();
  auto* dry_run = sub->add_flag("--dry-run", a->opt.slurm.dry_run,
                                "slurm: write DIR/batch.sbatch without submitting it");
  auto* resubmit = sub->add_flag(
      "--resubmit", a->opt.resubmit,
      "slurm: also hand over items submitted before that have not finished (a lost job)");
  auto* job_name = sub->add_option("--job-name", a->opt.slurm.job_name, "slurm/k8s: job name")
                       ->capture_default_str();
  auto* image = sub->add_option("--image", a->opt.k8s.image, "k8s: container image with kinesplat");
  auto* ns = sub->add_option("--namespace", a->opt.k8s.k8s_namespace, "k8s: namespace");
  auto* parallelism = sub->add_option("--parallelism", a->opt.k8s.parallelism, "k8s: pods at once")
                          ->check(CLI::Range(1, 100000))
                          ->capture_default_str();
  auto* volume = sub->add_option(
      "--volume", a->volumes,
      "k8s: CLAIM:/PATH, a PersistentVolumeClaim the pods mount at PATH (repeat); the photos and "
      "DIR must lie under one, at the same paths as here");

  auto* status = sub->add_subcommand("status", "done / failed / pending per item of a batch");
  status->add_option("dir", a->status_dir, "Batch directory")->required();
  status->add_flag("--json", a->status_json, "Print the report as JSON");
  status->callback([a] {
    const ks::BatchStatusReport r = ks::batch_status(a->status_dir);
    if (!a->status_json) {
      ks::print_status(r, std::cout);
      return;
    }
    nlohmann::json items = nlohmann::json::array();
    for (const auto& it : r.items) {
      nlohmann::json j = {{"id", it.id}, {"state", ks::item_state_name(it.status.state)}};
      if (!it.status.error.empty()) j["error"] = it.status.error;
      if (!it.status.job.empty()) j["job"] = it.status.job;
      if (it.status.seconds >= 0) j["seconds"] = it.status.seconds;
      if (it.status.peak_kb >= 0) j["peak_kb"] = it.status.peak_kb;
      items.push_back(j);
    }
    std::cout << nlohmann::json{{"dir", r.dir}, {"items", items}}.dump(2) << "\n";
  });

  sub->callback([a, sub, status, jobs, cpus, mem, partition, time, max_running, sbatch_arg, sbatch,
                 dry_run, resubmit, job_name, image, ns, parallelism, volume] {
    if (status->parsed()) return;
    Args& x = *a;
    if (x.manifest.empty()) throw ks::Error("batch needs a MANIFEST (or: batch status DIR)");
    if (x.opt.out_dir.empty()) throw ks::Error("batch needs --out DIR");
    x.opt.scheduler = ks::parse_scheduler(x.scheduler);
    x.opt.item_command = kItemCommand;
    // Options that would be ignored with this scheduler.
    using S = ks::Scheduler;
    const std::vector<std::pair<CLI::Option*, std::vector<S>>> only = {
        {jobs, {S::kLocal}},
        {cpus, {S::kSlurm, S::kK8s}},
        {mem, {S::kSlurm, S::kK8s}},
        {partition, {S::kSlurm}},
        {time, {S::kSlurm}},
        {max_running, {S::kSlurm}},
        {sbatch_arg, {S::kSlurm}},
        {sbatch, {S::kSlurm}},
        {dry_run, {S::kSlurm}},
        {resubmit, {S::kSlurm}},
        {job_name, {S::kSlurm, S::kK8s}},
        {image, {S::kK8s}},
        {ns, {S::kK8s}},
        {parallelism, {S::kK8s}},
        {volume, {S::kK8s}}};
    for (const auto& [o, ok] : only)
      if (o->count() > 0 && std::find(ok.begin(), ok.end(), x.opt.scheduler) == ok.end())
        throw ks::Error(o->get_name() + " has no effect with --scheduler " + x.scheduler);
    if (!x.mem.empty()) x.opt.resources.memory_mb = ks::parse_memory_mb(x.mem, "--mem");
    for (const std::string& v : x.volumes) x.opt.k8s.volumes.push_back(ks::parse_k8s_volume(v));
    const ks::Manifest m = ks::parse_manifest(x.manifest, item_option_spec(sub->get_parent()));
    const int failed = ks::run_batch(m, x.opt, std::cout);
    if (failed > 0)
      throw ks::Error(std::to_string(failed) + (failed == 1 ? " item" : " items") +
                      " failed (`kinesplat batch status " + x.opt.out_dir + "` lists the errors)");
  });
});

}  // namespace

#include "batch/batch.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <ostream>
#include <sstream>
#include <thread>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/process.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string this_program() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("cannot find this program's path (/proc/self/exe): " + ec.message());
  return p.string();
}

std::string kinesplat_program(const BatchOptions& o) {
  if (!o.kinesplat.empty()) return o.kinesplat;
  return o.scheduler == Scheduler::kK8s ? "kinesplat" : this_program();
}

std::string absolute_dir(const std::string& d) {
  if (d.empty()) throw Error("batch needs an output directory (--out)");
  std::error_code ec;
  return fs::absolute(d, ec).lexically_normal().string();
}

nlohmann::json items_json(const Manifest& m) {
  nlohmann::json items = nlohmann::json::array();
  for (const BatchItem& it : m.items) {
    nlohmann::json opts = nlohmann::json::array();
    for (const ItemOption& o : it.options)
      opts.push_back(o.flag ? nlohmann::json{o.name} : nlohmann::json{o.name, o.value});
    items.push_back({{"id", it.id}, {"photo", it.photo}, {"options", opts}, {"line", it.line}});
  }
  return items;
}

std::string fmt(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

std::string figures(const ItemStatus& st) {
  std::string s;
  if (st.seconds >= 0) s += fmt(st.seconds, 1) + " s";
  if (st.peak_kb >= 0) s += (s.empty() ? "" : ", ") + fmt(st.peak_kb / 1024.0, 0) + " MB peak";
  return s;
}

// Marks `ids` as handed to `scheduler` (job id or "-"), clearing the last attempt's markers.
void mark_submitted(const std::string& out_dir, const Manifest& m, const std::vector<int>& rows,
                    const std::string& scheduler, const std::string& job) {
  for (int r : rows) {
    const fs::path d = item_dir(out_dir, m.items[size_t(r)].id);
    std::error_code ec;
    fs::create_directories(d, ec);
    fs::remove(d / "started", ec);
    fs::remove(d / "exit_status", ec);
    fs::remove(d / "resources", ec);
    write_text_atomic((d / "submitted").string(),
                      scheduler + " " + (job.empty() ? "-" : job) + " " + utc_now() + "\n");
  }
}

void record_run(const std::string& out_dir, const Manifest& m, const std::vector<int>& rows,
                const std::string& scheduler, const std::string& job) {
  const std::string path = (fs::path(out_dir) / "batch.json").string();
  nlohmann::json j = read_json(path);
  nlohmann::json ids = nlohmann::json::array();
  for (int r : rows) ids.push_back(m.items[size_t(r)].id);
  nlohmann::json run = {{"time", utc_now()}, {"scheduler", scheduler}, {"items", ids}};
  if (!job.empty()) run["job"] = job;
  j["runs"].push_back(run);
  write_json_atomic(path, j);
}

int run_local(const Manifest& m, const std::vector<int>& rows, const BatchOptions& o,
              const std::string& out_dir, const std::string& kinesplat, std::ostream& out) {
  std::vector<int> keys = rows;  // locally the task index is the manifest row
  const std::string script = (fs::path(out_dir) / "batch.local.sh").string();
  write_text_atomic(script,
                    "#!/bin/sh\n# kinesplat batch: the local scheduler's task script; "
                    "IDX = the manifest row.\n" +
                        task_script_body(m, keys, rows, out_dir, kinesplat, o.item_command));
  mark_submitted(out_dir, m, rows, "local", "");
  record_run(out_dir, m, rows, "local", "");
  const int jobs = std::max(1, std::min<int>(o.jobs, int(rows.size())));
  // Several items at once share the cores: each gets its part, unless the caller chose.
  std::string omp;
  if (jobs > 1 && !std::getenv("OMP_NUM_THREADS")) {
    const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
    omp = "OMP_NUM_THREADS=" + std::to_string(std::max(1u, hw / unsigned(jobs))) + " ";
  }
  std::mutex mu;
  std::atomic<size_t> next{0};
  int finished = 0, failed = 0;
  const auto t0 = std::chrono::steady_clock::now();
  auto worker = [&] {
    while (true) {
      const size_t k = next++;
      if (k >= rows.size()) return;
      const BatchItem& item = m.items[size_t(rows[k])];
      const std::string dir = item_dir(out_dir, item.id);
      {
        std::lock_guard<std::mutex> lock(mu);
        out << "batch: " << item.id << " started\n" << std::flush;
      }
      const std::string cmd =
          "IDX=" + std::to_string(rows[k]) + " " + omp + "/bin/sh " + shell_quote(script);
      const std::string task_log = (fs::path(dir) / "task.out").string();
      std::error_code ec;
      fs::remove(task_log, ec);
      const int rc = run_shell(cmd, task_log);
      // A task script that ended before recording its exit (it could not make the item's folder):
      // record it here, so that the item reads as failed.
      if (!fs::exists(fs::path(dir) / "exit_status", ec))
        write_text_atomic((fs::path(dir) / "exit_status").string(),
                          std::to_string(rc == 0 ? 1 : rc) + "\n");
      const ItemStatus st = read_item_status(dir);
      std::lock_guard<std::mutex> lock(mu);
      ++finished;
      const double el =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      out << "batch: [" << finished << "/" << rows.size() << ", " << fmt(el, 0) << " s] " << item.id
          << " ";
      if (st.state == ItemState::kDone) {
        const std::string f = figures(st);
        out << "done" << (f.empty() ? "" : " (" + f + ")") << "\n";
      } else {
        ++failed;
        out << "FAILED: " << (st.error.empty() ? item_state_name(st.state) : st.error) << "\n";
      }
      out << std::flush;
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < jobs; ++i) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  return failed;
}

std::string join(const std::vector<std::string>& v, const std::string& sep) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? sep : "") + v[i];
  return s;
}

bool path_under(const fs::path& p, const fs::path& dir) {
  const fs::path rel = p.lexically_normal().lexically_relative(dir.lexically_normal());
  return !rel.empty() && *rel.begin() != "..";
}

}  // namespace

Scheduler parse_scheduler(const std::string& name) {
  if (name == "local") return Scheduler::kLocal;
  if (name == "slurm") return Scheduler::kSlurm;
  if (name == "k8s") return Scheduler::kK8s;
  throw Error("--scheduler " + name + ": expected local, slurm or k8s");
}

const char* scheduler_name(Scheduler s) {
  return s == Scheduler::kLocal ? "local" : s == Scheduler::kSlurm ? "slurm" : "k8s";
}

int parse_memory_mb(const std::string& text, const std::string& flag) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  std::string unit = text.substr(used);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() == 2 && unit[1] == 'I') unit = unit.substr(0, 1);  // Gi, Mi, Ki
  if (unit.size() == 2 && unit[1] == 'B') unit = unit.substr(0, 1);  // GB, MB, KB
  double mb = -1;
  if (used > 0 && std::isfinite(v) && v > 0) {
    if (unit.empty() || unit == "M")
      mb = v;
    else if (unit == "G")
      mb = v * 1024;
    else if (unit == "T")
      mb = v * 1024 * 1024;
    else if (unit == "K")
      mb = v / 1024;
  }
  if (!(mb > 0) || mb > 1e9)
    throw Error(flag + " " + text + ": expected a memory size such as 4G, 3500M or 3500 (MiB)");
  return int(std::ceil(mb));
}

K8sVolume parse_k8s_volume(const std::string& text) {
  const size_t c = text.find(':');
  K8sVolume v;
  if (c != std::string::npos) {
    v.claim = text.substr(0, c);
    v.mount = text.substr(c + 1);
  }
  if (v.claim.empty() || v.mount.empty() || v.mount[0] != '/')
    throw Error("--volume " + text +
                ": expected CLAIM:/MOUNT/PATH (a PersistentVolumeClaim and "
                "where the pods see it)");
  return v;
}

std::vector<std::string> item_arguments(const BatchItem& item, const std::string& out_dir,
                                        const std::string& item_command) {
  std::vector<std::string> a = {item_command, item.photo, "--out", item_dir(out_dir, item.id)};
  for (const ItemOption& o : item.options) {
    a.push_back("--" + o.name);
    if (!o.flag) a.push_back(o.value);
  }
  return a;
}

std::string task_script_body(const Manifest& m, const std::vector<int>& keys,
                             const std::vector<int>& rows, const std::string& out_dir,
                             const std::string& kinesplat, const std::string& item_command) {
  std::ostringstream s;
  s << "KINESPLAT=" << shell_quote(kinesplat) << "\n";
  s << "# The item table: task index -> item id and its command's arguments.\n";
  s << "case \"${IDX:-}\" in\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const BatchItem& item = m.items[size_t(rows[i])];
    std::vector<std::string> q;
    for (const std::string& a : item_arguments(item, out_dir, item_command))
      q.push_back(shell_quote(a));
    s << "  " << keys[i] << ") ID=" << shell_quote(item.id)
      << "; DIR=" << shell_quote(item_dir(out_dir, item.id)) << "\n     set -- " << join(q, " ")
      << " ;;\n";
  }
  s << "  *) echo \"error: task index '${IDX:-}' names no item of this batch\" >&2; exit 2 ;;\n";
  s << "esac\n";
  // clang-format off
  s << R"SH(mkdir -p "$DIR" || exit 1
rm -f "$DIR/exit_status" "$DIR/resources"
echo "$(hostname) $(date -u +%Y-%m-%dT%H:%M:%SZ)" > "$DIR/started"
echo "== kinesplat batch: item $ID on $(hostname) at $(date -u +%Y-%m-%dT%H:%M:%SZ)" >> "$DIR/create.log"
# A task stopped by its scheduler (time limit, cancel) still records how it ended.
trap 'echo 143 > "$DIR/exit_status"; exit 143' TERM
if [ -x /usr/bin/time ]; then
  /usr/bin/time -f '%e %M' -o "$DIR/resources" "$KINESPLAT" "$@" >> "$DIR/create.log" 2>&1
else
  "$KINESPLAT" "$@" >> "$DIR/create.log" 2>&1
fi
rc=$?
echo "$rc" > "$DIR/exit_status.tmp" && mv -f "$DIR/exit_status.tmp" "$DIR/exit_status"
if [ "$rc" -ne 0 ]; then
  echo "kinesplat batch: item $ID failed (exit status $rc), log $DIR/create.log" >&2
  grep '^error:' "$DIR/create.log" | tail -n 1 >&2
fi
exit "$rc"
)SH";
  // clang-format on
  return s.str();
}

std::string slurm_script(const Manifest& m, const std::vector<int>& rows, const BatchOptions& o) {
  const std::string out_dir = absolute_dir(o.out_dir);
  std::vector<std::string> idx;
  for (int r : rows) idx.push_back(std::to_string(r));
  std::ostringstream s;
  s << "#!/bin/sh\n";
  s << "# kinesplat batch: " << rows.size() << " of the " << m.items.size() << " items of "
    << m.path << ", one array task each (task id = manifest row).\n";
  s << "#SBATCH --job-name=" << o.slurm.job_name << "\n";
  s << "#SBATCH --array=" << join(idx, ",")
    << (o.slurm.max_running > 0 ? "%" + std::to_string(o.slurm.max_running) : "") << "\n";
  s << "#SBATCH --ntasks=1\n";
  s << "#SBATCH --cpus-per-task=" << o.resources.cpus << "\n";
  s << "#SBATCH --mem=" << o.resources.memory_mb << "M\n";
  s << "#SBATCH --output=" << (fs::path(out_dir) / "slurm" / "%A_%a.out").string() << "\n";
  if (!o.slurm.partition.empty()) s << "#SBATCH --partition=" << o.slurm.partition << "\n";
  if (!o.slurm.time_limit.empty()) s << "#SBATCH --time=" << o.slurm.time_limit << "\n";
  for (const std::string& a : o.slurm.extra_args) s << "#SBATCH " << a << "\n";
  s << "IDX=\"$SLURM_ARRAY_TASK_ID\"\n";
  s << "export OMP_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-" << o.resources.cpus << "}\"\n";
  s << task_script_body(m, rows, rows, out_dir, kinesplat_program(o), o.item_command);
  return s.str();
}

nlohmann::json k8s_job(const Manifest& m, const std::vector<int>& rows, const BatchOptions& o) {
  const std::string out_dir = absolute_dir(o.out_dir);
  if (o.k8s.image.empty())
    throw Error("--scheduler k8s needs --image (a container image with kinesplat)");
  // The pods see the photos and DIR through the volumes, at the same paths as here.
  std::vector<std::string> problems;
  auto check = [&](const std::string& what, const std::string& p) {
    for (const K8sVolume& v : o.k8s.volumes)
      if (path_under(p, v.mount) || fs::path(p).lexically_normal() == fs::path(v.mount)) return;
    problems.push_back(what + " " + p);
  };
  check("the output directory", out_dir);
  for (int r : rows) check("item " + m.items[size_t(r)].id + "'s photo", m.items[size_t(r)].photo);
  if (!problems.empty())
    throw Error("--scheduler k8s: the pods would not see " + join(problems, ", ") +
                ": mount a volume there with --volume CLAIM:/PATH (pods see the same paths as "
                "this machine)");
  std::vector<int> keys(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) keys[i] = int(i);
  const std::string script =
      "IDX=\"$JOB_COMPLETION_INDEX\"\n" +
      task_script_body(m, keys, rows, out_dir, kinesplat_program(o), o.item_command);
  nlohmann::json mounts = nlohmann::json::array(), volumes = nlohmann::json::array();
  for (size_t i = 0; i < o.k8s.volumes.size(); ++i) {
    const std::string name = "data-" + std::to_string(i);
    mounts.push_back({{"name", name}, {"mountPath", o.k8s.volumes[i].mount}});
    volumes.push_back(
        {{"name", name}, {"persistentVolumeClaim", {{"claimName", o.k8s.volumes[i].claim}}}});
  }
  const std::string mem = std::to_string(o.resources.memory_mb) + "Mi";
  const std::string cpu = std::to_string(o.resources.cpus);
  nlohmann::json container = {
      {"name", "kinesplat"},
      {"image", o.k8s.image},
      {"command", {"/bin/sh", "-c", script}},
      {"env", {{{"name", "OMP_NUM_THREADS"}, {"value", cpu}}}},
      {"resources", {{"requests", {{"cpu", cpu}, {"memory", mem}}}, {"limits", {{"memory", mem}}}}},
      {"volumeMounts", mounts}};
  nlohmann::json metadata = {{"name", o.k8s.job_name},
                             {"labels", {{"app.kubernetes.io/name", "kinesplat-batch"}}}};
  if (!o.k8s.k8s_namespace.empty()) metadata["namespace"] = o.k8s.k8s_namespace;
  const int n = int(rows.size());
  return {{"apiVersion", "batch/v1"},
          {"kind", "Job"},
          {"metadata", metadata},
          {"spec",
           {{"completionMode", "Indexed"},
            {"completions", n},
            {"parallelism", std::max(1, std::min(o.k8s.parallelism, n))},
            // A failed item fails its own index only; the others go on (Kubernetes >= 1.29).
            {"backoffLimitPerIndex", 0},
            {"template",
             {{"metadata", {{"labels", {{"app.kubernetes.io/name", "kinesplat-batch"}}}}},
              {"spec",
               {{"restartPolicy", "Never"},
                {"containers", nlohmann::json::array({container})},
                {"volumes", volumes}}}}}}}};
}

int run_batch(const Manifest& m, const BatchOptions& o, std::ostream& out) {
  const std::string out_dir = absolute_dir(o.out_dir);
  const std::string kinesplat = kinesplat_program(o);
  std::error_code ec;
  fs::create_directories(fs::path(out_dir) / "items", ec);
  if (ec) throw Error("cannot create " + out_dir + "/items: " + ec.message());
  // The batch's record: the items as parsed (status reads them), and each hand-over.
  const std::string record = (fs::path(out_dir) / "batch.json").string();
  nlohmann::json j;
  if (fs::exists(record)) {
    j = read_json(record);
    if (!j.is_object() || !j.contains("runs") || !j["runs"].is_array())
      throw Error(record + ": not a batch record (no \"runs\" list)");
  } else {
    j = {{"runs", nlohmann::json::array()}};
  }
  std::error_code aec;
  j["manifest"] = fs::absolute(m.path, aec).lexically_normal().string();
  j["item_command"] = o.item_command;
  j["items"] = items_json(m);
  write_json_atomic(record, j);

  // What to hand over: every item that is not done (create resumes the rest of its work).
  std::vector<int> rows;
  int done = 0, in_flight = 0;
  std::vector<std::string> in_flight_ids;
  for (size_t r = 0; r < m.items.size(); ++r) {
    const ItemStatus st = read_item_status(item_dir(out_dir, m.items[r].id));
    if (st.state == ItemState::kDone) {
      ++done;
      continue;
    }
    const bool elsewhere = (st.state == ItemState::kQueued || st.state == ItemState::kRunning) &&
                           st.submitted_by != "local";
    if (elsewhere && !o.resubmit && o.scheduler != Scheduler::kK8s) {
      ++in_flight;
      in_flight_ids.push_back(m.items[r].id + (st.job.empty() ? "" : " (job " + st.job + ")"));
      continue;
    }
    rows.push_back(int(r));
  }
  out << "batch: " << m.items.size() << " items, " << done << " done";
  if (in_flight)
    out << ", " << in_flight << " submitted before and not finished (" << join(in_flight_ids, ", ")
        << "; --resubmit hands them over again)";
  out << "; " << rows.size() << " to " << (o.scheduler == Scheduler::kLocal ? "run here" : "submit")
      << "\n";
  if (rows.empty()) return 0;

  if (o.scheduler == Scheduler::kLocal) {
    const int failed = run_local(m, rows, o, out_dir, kinesplat, out);
    out << "batch: " << rows.size() - size_t(failed) << " of " << rows.size() << " done here, "
        << failed << " failed; `kinesplat batch status " << out_dir << "` for every item\n";
    return failed;
  }
  if (o.scheduler == Scheduler::kK8s) {
    const std::string path = (fs::path(out_dir) / "batch.k8s.json").string();
    write_json_atomic(path, k8s_job(m, rows, o));
    out << "batch: wrote " << path << " (an Indexed Job of " << rows.size()
        << " pods); submit it with `kubectl apply -f " << path << "`\n";
    return 0;
  }
  // slurm
  const std::string path = (fs::path(out_dir) / "batch.sbatch").string();
  write_text_atomic(path, slurm_script(m, rows, o));
  fs::create_directories(fs::path(out_dir) / "slurm", ec);
  if (o.slurm.dry_run) {
    out << "batch: wrote " << path << " (not submitted: --dry-run); submit it with `sbatch " << path
        << "`\n";
    return 0;
  }
  // Submitted items lose the last attempt's markers before the job can start.
  mark_submitted(out_dir, m, rows, "slurm", "");
  const std::string log = (fs::path(out_dir) / "slurm" / "sbatch.out").string();
  fs::remove(log, ec);
  const int rc = run_shell(shell_quote(o.slurm.sbatch) + " --parsable " + shell_quote(path), log);
  const std::string answer = log_tail(log);
  if (rc != 0)
    throw Error("sbatch " + path + " failed (exit status " + std::to_string(rc) +
                "): " + (answer.empty() ? "no output" : answer));
  std::string job = answer.substr(
      answer.find_last_of('\n') == std::string::npos ? 0 : answer.find_last_of('\n') + 1);
  job = job.substr(0, job.find(';'));
  mark_submitted(out_dir, m, rows, "slurm", job);
  record_run(out_dir, m, rows, "slurm", job);
  out << "batch: submitted " << path << " as Slurm job " << job << " (" << rows.size()
      << (rows.size() == 1 ? " array task" : " array tasks") << "); `kinesplat batch status "
      << out_dir << "` to follow it\n";
  return 0;
}

int BatchStatusReport::count(ItemState s) const {
  return int(std::count_if(items.begin(), items.end(),
                           [s](const BatchItemReport& r) { return r.status.state == s; }));
}

BatchStatusReport batch_status(const std::string& dir) {
  const std::string record = (fs::path(dir) / "batch.json").string();
  if (!fs::exists(record))
    throw Error(dir + " holds no batch (no batch.json; `kinesplat batch MANIFEST --out " + dir +
                "` makes one)");
  const nlohmann::json j = read_json(record);
  if (!j.is_object() || !j.contains("items") || !j["items"].is_array())
    throw Error(record + ": not a batch record (no \"items\" list)");
  BatchStatusReport r;
  r.dir = dir;
  for (const auto& it : j["items"]) {
    if (!it.is_object() || !it.contains("id") || !it["id"].is_string() ||
        !valid_item_id(it["id"].get<std::string>()))
      throw Error(record + ": an item without a valid \"id\"");
    BatchItemReport ir;
    ir.id = it["id"];
    ir.status = read_item_status(item_dir(dir, ir.id));
    r.items.push_back(std::move(ir));
  }
  return r;
}

void print_status(const BatchStatusReport& r, std::ostream& out) {
  size_t w = 2;
  for (const auto& it : r.items) w = std::max(w, it.id.size());
  for (const auto& it : r.items) {
    std::string line = it.id + std::string(w + 2 - it.id.size(), ' ');
    std::string state = item_state_name(it.status.state);
    line += state + std::string(9 - state.size(), ' ');
    std::string detail;
    if (it.status.state == ItemState::kFailed) {
      detail = it.status.error;
    } else if (it.status.state == ItemState::kDone) {
      detail = figures(it.status);
    } else if (it.status.state == ItemState::kQueued || it.status.state == ItemState::kRunning) {
      detail = it.status.submitted_by + (it.status.job.empty() ? "" : " job " + it.status.job);
    }
    out << line << detail << "\n";
  }
  const int done = r.count(ItemState::kDone), failed = r.count(ItemState::kFailed);
  const int running = r.count(ItemState::kRunning), queued = r.count(ItemState::kQueued);
  const int pending = int(r.items.size()) - done - failed;
  out << r.items.size() << " items: " << done << " done, " << failed << " failed, " << pending
      << " pending";
  if (running || queued) out << " (" << running << " running, " << queued << " queued)";
  out << "\n";
}

}  // namespace ks

#pragma once
// The studio's worker: one job at a time, the others queued in order. A job is `kinesplat create`
// on an avatar's photo (a child process, studio/child_process), then the exports the page offers
// (`export --web`, `--out avatar.ply`, `--gltf avatar.glb`, and the site as web.zip). Its progress
// is read from create's output (studio/create_progress); every change calls `on_change`.
// Cancelling stops the child's whole process group: create is resumable (stages whose outputs
// are up to date are skipped), so a cancelled, failed or interrupted job can run again.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "studio/child_process.hpp"
#include "studio/create_progress.hpp"
#include "studio/workspace.hpp"

namespace ks {

struct JobSettings {
  std::string program;                   // the kinesplat executable run for create and export
  std::vector<std::string> create_args;  // more options for every create
  int cancel_grace_ms = 3000;            // SIGTERM, then SIGKILL this much later
};

class CreateQueue {
 public:
  CreateQueue(Workspace& ws, JobSettings settings, std::function<void()> on_change);
  ~CreateQueue();  // shutdown()
  CreateQueue(const CreateQueue&) = delete;
  CreateQueue& operator=(const CreateQueue&) = delete;

  // Queues the avatar's job (its record becomes "queued"); false if it is queued or running.
  bool enqueue(const std::string& id);
  enum class Cancel { kNotActive, kDequeued, kStopping };
  Cancel cancel(const std::string& id);
  bool active(const std::string& id) const;  // queued or running
  // {"state": "queued", "position": n} or {"state": "running", "progress": {...}}; nothing when
  // the avatar has no job here.
  std::optional<nlohmann::json> live(const std::string& id) const;
  // Stops the worker: the running job's processes are stopped and its record left "running"
  // (read as interrupted next time); queued jobs stay "queued" (the same). Idempotent.
  void shutdown();
  // The running job's id, "" when idle.
  std::string running() const;

 private:
  void work();
  void run_job(const std::string& id);
  // Runs one child, feeding its lines to the log (and to `progress` when given); its status.
  int run_child(const std::vector<std::string>& argv, std::FILE* log, bool parse);
  void changed();

  Workspace& ws_;
  JobSettings settings_;
  std::function<void()> on_change_;
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::deque<std::string> queue_;
  std::string running_;
  CreateProgress progress_;
  std::chrono::steady_clock::time_point started_;
  std::shared_ptr<ChildProcess> child_;
  bool cancel_requested_ = false, stopping_ = false;
  std::thread worker_;
};

}  // namespace ks

#include "studio/create_queue.hpp"

#include <cstdio>
#include <filesystem>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/zip_write.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {

namespace {

// True when `out` exists and is newer than `in` (an export of this avatar already made).
bool up_to_date(const fs::path& out, const fs::path& in) {
  std::error_code ec;
  const auto to = fs::last_write_time(out, ec);
  if (ec) return false;
  const auto ti = fs::last_write_time(in, ec);
  return !ec && to >= ti;
}

// The message without the avatar folder's path (the page shows "photo.png", not where the
// workspace lies on the server's disk).
std::string without_folder(std::string message, const fs::path& dir) {
  const std::string prefix = dir.string() + "/";
  for (size_t p; (p = message.find(prefix)) != std::string::npos;) message.erase(p, prefix.size());
  return message;
}

}  // namespace

CreateQueue::CreateQueue(Workspace& ws, JobSettings settings, std::function<void()> on_change)
    : ws_(ws), settings_(std::move(settings)), on_change_(std::move(on_change)) {
  worker_ = std::thread([this] { work(); });
}

CreateQueue::~CreateQueue() {
  shutdown();
}

void CreateQueue::changed() {
  if (on_change_) on_change_();
}

bool CreateQueue::enqueue(const std::string& id) {
  {
    std::lock_guard<std::mutex> lock(m_);
    if (stopping_ || running_ == id) return false;
    for (const auto& q : queue_)
      if (q == id) return false;
    std::optional<AvatarRecord> r = ws_.load(id);
    if (!r) return false;
    r->state = "queued";
    r->error.clear();
    r->error_stage.clear();
    ws_.save(*r);
    queue_.push_back(id);
  }
  cv_.notify_all();
  changed();
  return true;
}

CreateQueue::Cancel CreateQueue::cancel(const std::string& id) {
  Cancel result = Cancel::kNotActive;
  {
    std::lock_guard<std::mutex> lock(m_);
    for (auto it = queue_.begin(); it != queue_.end(); ++it)
      if (*it == id) {
        queue_.erase(it);
        if (std::optional<AvatarRecord> r = ws_.load(id)) {
          r->state = "cancelled";
          ws_.save(*r);
        }
        result = Cancel::kDequeued;
        break;
      }
    if (result == Cancel::kNotActive && running_ == id) {
      cancel_requested_ = true;
      if (child_) child_->terminate(settings_.cancel_grace_ms);
      result = Cancel::kStopping;
    }
  }
  if (result != Cancel::kNotActive) changed();
  return result;
}

bool CreateQueue::active(const std::string& id) const {
  std::lock_guard<std::mutex> lock(m_);
  if (running_ == id) return true;
  for (const auto& q : queue_)
    if (q == id) return true;
  return false;
}

std::string CreateQueue::running() const {
  std::lock_guard<std::mutex> lock(m_);
  return running_;
}

std::optional<json> CreateQueue::live(const std::string& id) const {
  std::lock_guard<std::mutex> lock(m_);
  if (running_ == id) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
    json j = {{"state", "running"}, {"progress", progress_.to_json(elapsed)}};
    if (cancel_requested_) j["cancelling"] = true;
    return j;
  }
  int pos = 1;
  for (const auto& q : queue_) {
    if (q == id) return json{{"state", "queued"}, {"position", pos}};
    ++pos;
  }
  return std::nullopt;
}

void CreateQueue::shutdown() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stopping_ = true;
    if (child_) child_->terminate(settings_.cancel_grace_ms);
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void CreateQueue::work() {
  for (;;) {
    std::string id;
    {
      std::unique_lock<std::mutex> lock(m_);
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      id = queue_.front();
      queue_.pop_front();
      running_ = id;
      progress_ = CreateProgress();
      started_ = std::chrono::steady_clock::now();
      cancel_requested_ = false;
    }
    changed();
    try {
      run_job(id);
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(m_);
      if (!stopping_)
        if (std::optional<AvatarRecord> r = ws_.load(id)) {
          r->state = "failed";
          r->error = e.what();
          r->error_stage = progress_.current_name();
          ws_.save(*r);
        }
    }
    {
      std::lock_guard<std::mutex> lock(m_);
      running_.clear();
      child_.reset();
    }
    changed();
  }
}

int CreateQueue::run_child(const std::vector<std::string>& argv, std::FILE* log, bool parse) {
  auto child = std::make_shared<ChildProcess>();
  {
    std::lock_guard<std::mutex> lock(m_);
    if (stopping_ || cancel_requested_) return 130;
    child->start(argv);
    child_ = child;
  }
  std::string cmd;
  for (const auto& a : argv) cmd += (cmd.empty() ? "" : " ") + a;
  std::fprintf(log, "$ %s\n", cmd.c_str());
  std::fflush(log);
  const int status = child->wait([&](const std::string& line) {
    std::fprintf(log, "%s\n", line.c_str());
    std::fflush(log);
    {
      std::lock_guard<std::mutex> lock(m_);
      if (parse) {
        progress_.feed(line);
      } else if (line.rfind("error: ", 0) == 0) {
        progress_.feed(line);  // the error line of an export
      }
    }
    changed();
  });
  std::lock_guard<std::mutex> lock(m_);
  child_.reset();
  return status;
}

void CreateQueue::run_job(const std::string& id) {
  std::optional<AvatarRecord> rec = ws_.load(id);
  if (!rec || rec->photo.empty()) throw Error("studio: avatar " + id + " has no photo record");
  const fs::path dir = ws_.avatar_dir(id);
  rec->state = "running";
  rec->error.clear();
  rec->error_stage.clear();
  ws_.save(*rec);
  std::FILE* log = std::fopen((dir / "job.log").c_str(), "w");
  if (!log) throw Error("studio: cannot write " + (dir / "job.log").string());
  struct Closer {
    std::FILE* f;
    ~Closer() { std::fclose(f); }
  } closer{log};

  auto outcome = [&](int status, const std::string& what) {
    // true: go on. Otherwise the record says why the job ended (or stays "running" when the
    // studio is stopping: interrupted).
    std::lock_guard<std::mutex> lock(m_);
    if (stopping_) return false;
    if (cancel_requested_) {
      rec->state = "cancelled";
      rec->error = "cancelled during " + progress_.current_name();
      rec->error_stage = progress_.current_name();
      ws_.save(*rec);
      return false;
    }
    if (status == 0) return true;
    progress_.finish(false);
    rec->state = "failed";
    rec->error = without_folder(
        !progress_.error().empty()
            ? progress_.error()
            : what + " exited with status " + std::to_string(status) +
                  (progress_.last_line().empty() ? "" : ": " + progress_.last_line()),
        dir);
    rec->error_stage = progress_.current_name();
    ws_.save(*rec);
    return false;
  };

  std::vector<std::string> create = {settings_.program, "create", (dir / rec->photo).string(),
                                     "--out", (dir / "create").string()};
  create.insert(create.end(), settings_.create_args.begin(), settings_.create_args.end());
  if (!outcome(run_child(create, log, true), "create")) return;

  {
    std::lock_guard<std::mutex> lock(m_);
    progress_.begin_export();
  }
  changed();
  const fs::path avatar = dir / "create" / "avatar.ksavatar";
  const fs::path exports = dir / "exports";
  fs::create_directories(exports);
  std::vector<std::string> motions;  // the create's motion videos, also the GLB's animations
  try {
    const json cj = read_json((dir / "create" / "create.json").string());
    for (const auto& v : cj.at("outputs").at("videos")) {
      const std::string stem = fs::path(v.get<std::string>()).stem().string();
      if (stem != "turntable") motions.push_back(stem);
    }
  } catch (const std::exception&) {
  }
  struct Step {
    fs::path out;
    std::vector<std::string> argv;
  };
  std::vector<Step> steps = {
      {dir / "web" / "motions.json",
       {settings_.program, "export", avatar.string(), "--web", (dir / "web").string()}},
      {exports / "avatar.ply",
       {settings_.program, "export", avatar.string(), "--out", (exports / "avatar.ply").string()}},
      {exports / "avatar.glb",
       {settings_.program, "export", avatar.string(), "--gltf",
        (exports / "avatar.glb").string()}}};
  for (const auto& m : motions) {
    steps[0].argv.insert(steps[0].argv.end(), {"--motion", m});
    steps[2].argv.insert(steps[2].argv.end(), {"--motion", m});
  }
  for (size_t i = 0; i < steps.size(); ++i) {
    if (!up_to_date(steps[i].out, avatar) &&
        !outcome(run_child(steps[i].argv, log, false), "export"))
      return;
    {
      std::lock_guard<std::mutex> lock(m_);
      progress_.export_fraction(double(i + 1) / double(steps.size() + 1));
    }
    changed();
  }
  if (!up_to_date(exports / "web.zip", dir / "web" / "motions.json")) {
    std::fprintf(log, "studio: zipping web/ into exports/web.zip\n");
    try {
      write_zip_of_folder((exports / "web.zip").string(), (dir / "web").string(),
                          "kinesplat-" + id + "-web/");
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lock(m_);
      progress_.finish(false);
      rec->state = "failed";
      rec->error = without_folder(e.what(), dir);
      rec->error_stage = "export";
      ws_.save(*rec);
      return;
    }
  }
  std::lock_guard<std::mutex> lock(m_);
  if (stopping_) return;
  progress_.finish(true);
  rec->state = "done";
  rec->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  ws_.save(*rec);
}

}  // namespace ks

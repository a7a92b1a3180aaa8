#include "studio/studio.hpp"

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <regex>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "create/create.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {

namespace {

fs::path executable() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe;
}

bool is_page(const fs::path& d) {
  std::error_code ec;
  return fs::is_regular_file(d / "index.html", ec) && fs::is_regular_file(d / "app.js", ec);
}

// The files a page may ask for by name, and where each lies in the avatar's folder.
struct NamedFile {
  const char* name;
  const char* path;
  const char* label;  // for downloads; nullptr: shown, not offered as a download
};
const NamedFile kFiles[] = {
    {"avatar.ksavatar", "create/avatar.ksavatar", "avatar (.ksavatar, for kinesplat)"},
    {"avatar.ply", "exports/avatar.ply", "3DGS splats (.ply, rest pose)"},
    {"avatar.glb", "exports/avatar.glb", "glTF 2.0 (.glb: skinned mesh, splats, motions)"},
    {"web.zip", "exports/web.zip", "web viewer site (.zip of export --web)"},
    {"perceive_overlay.png", "create/subject/perceive_overlay.png", nullptr},
    {"fit_overlay.png", "create/subject/fit_overlay.png", nullptr},
    {"job.log", "job.log", nullptr},
};

}  // namespace

std::string find_studio_page() {
  if (const char* env = std::getenv("KINESPLAT_STUDIO_DIR"); env && *env) {
    if (is_page(env)) return env;
    throw Error(std::string("KINESPLAT_STUDIO_DIR=") + env +
                " does not hold the studio page (index.html and app.js)");
  }
  std::vector<fs::path> tried;
  const fs::path exe = executable();
  if (!exe.empty()) {
    const fs::path d = exe.parent_path();
    for (const fs::path& p :
         {d / ".." / "studio", d / "studio", d / ".." / "share" / "kinesplat" / "studio"}) {
      const fs::path n = p.lexically_normal();
      if (is_page(n)) return n.string();
      tried.push_back(n);
    }
  }
  std::string where;
  for (const auto& p : tried) where += (where.empty() ? "" : ", ") + p.string();
  throw Error(
      "the studio page is not found (looked for index.html and app.js in " +
      (where.empty() ? std::string("no folder: the program's location is unknown") : where) +
      "); point KINESPLAT_STUDIO_DIR at the source tree's studio/ folder");
}

Studio::Studio(const StudioOptions& opt)
    : opt_(opt),
      page_dir_(opt.page_dir.empty() ? find_studio_page() : opt.page_dir),
      ws_(opt.workspace) {
  if (!is_page(page_dir_))
    throw Error("studio: " + page_dir_ + " does not hold the studio page (index.html and app.js)");
  JobSettings js;
  js.program = opt.program.empty() ? executable().string() : opt.program;
  if (js.program.empty()) throw Error("studio: cannot tell where the kinesplat program is");
  js.create_args = opt.create_args;
  queue_ = std::make_unique<CreateQueue>(ws_, js, [this] { touch(); });
}

Studio::~Studio() {
  shutdown();
}

void Studio::shutdown() {
  {
    std::lock_guard<std::mutex> lock(m_);
    if (stopping_) return;
    stopping_ = true;
  }
  cv_.notify_all();
  queue_->shutdown();
}

bool Studio::stopping() const {
  std::lock_guard<std::mutex> lock(m_);
  return stopping_;
}

uint64_t Studio::version() const {
  std::lock_guard<std::mutex> lock(m_);
  return version_;
}

void Studio::touch() {
  {
    std::lock_guard<std::mutex> lock(m_);
    ++version_;
  }
  cv_.notify_all();
}

uint64_t Studio::wait_change(uint64_t seen, double seconds) const {
  std::unique_lock<std::mutex> lock(m_);
  cv_.wait_for(lock, std::chrono::duration<double>(seconds),
               [&] { return version_ != seen || stopping_; });
  return version_;
}

std::string Studio::file_for(const std::string& id, const std::string& name) const {
  if (!Workspace::valid_id(id)) return "";
  const fs::path dir = ws_.avatar_dir(id);
  std::error_code ec;
  std::string rel;
  if (name == "photo") {
    const std::optional<AvatarRecord> r = ws_.load(id);
    if (r && !r->photo.empty()) rel = r->photo;
  }
  for (const auto& f : kFiles)
    if (name == f.name) rel = f.path;
  if (rel.empty()) {
    // A video create made: one of the .mp4 files in create/, matched by its exact name.
    for (const auto& e : fs::directory_iterator(dir / "create", ec))
      if (e.is_regular_file(ec) && e.path().extension() == ".mp4" &&
          e.path().filename().string() == name)
        rel = "create/" + name;
  }
  if (rel.empty()) return "";
  const fs::path p = dir / rel;
  return fs::is_regular_file(p, ec) ? p.string() : "";
}

json Studio::avatar_json(const std::string& id) const {
  const std::optional<AvatarRecord> rec = ws_.load(id);
  if (!rec) return nullptr;
  const fs::path dir = ws_.avatar_dir(id);
  const std::string base = "/api/avatars/" + id;
  json j = {{"id", id},
            {"label", rec->label},
            {"created", rec->created},
            {"photo", base + "/files/photo"}};
  std::string state = rec->state;
  if (const std::optional<json> live = queue_->live(id)) {
    state = live->at("state");
    for (const auto& [k, v] : live->items())
      if (k != "state") j[k] = v;
  } else if (state == "queued" || state == "running") {
    state = "interrupted";  // a studio stopped while it was waiting or being made
  }
  j["state"] = state;
  if (!rec->error.empty()) j["error"] = rec->error;
  if (!rec->error_stage.empty()) j["error_stage"] = rec->error_stage;
  if (rec->seconds > 0) j["seconds"] = rec->seconds;
  // What create recorded: its stages' status and times.
  std::error_code ec;
  const fs::path cj = dir / "create" / "create.json";
  if (fs::is_regular_file(cj, ec)) {
    try {
      const json c = read_json(cj.string());
      const json recorded = c.value("stages", json::object());
      json stages = json::array();
      for (const auto& name : create_stage_names()) {  // in create's order
        if (!recorded.contains(name) || !recorded[name].is_object()) continue;
        const json& s = recorded[name];
        stages.push_back({{"name", name},
                          {"status", s.value("status", "")},
                          {"skipped", s.value("skipped", false)},
                          {"seconds", s.value("seconds", 0.0)}});
      }
      j["create"] = {{"status", c.value("status", "")}, {"stages", stages}};
      if (state == "interrupted" || state == "failed" || state == "cancelled")
        for (const auto& [name, s] : recorded.items())
          if (s.value("status", "") == "running" && !j.contains("error_stage"))
            j["error_stage"] = name;
      if (state == "failed" && !j.contains("error") && c.contains("error")) j["error"] = c["error"];
    } catch (const std::exception&) {
    }
  }
  json files = json::object();
  json downloads = json::array();
  for (const auto& f : kFiles) {
    const std::string p = file_for(id, f.name);
    if (p.empty()) continue;
    files[f.name] = base + "/files/" + f.name;
    if (f.label)
      downloads.push_back({{"name", f.name},
                           {"label", f.label},
                           {"bytes", fs::file_size(p, ec)},
                           {"url", base + "/files/" + f.name + "?download=1"}});
  }
  json videos = json::array();
  for (const auto& e : fs::directory_iterator(dir / "create", ec))
    if (e.is_regular_file(ec) && e.path().extension() == ".mp4")
      videos.push_back({{"name", e.path().stem().string()},
                        {"url", base + "/files/" + e.path().filename().string()}});
  std::sort(videos.begin(), videos.end(), [](const json& a, const json& b) {
    // The turntable first, then by name.
    const bool ta = a["name"] == "turntable", tb = b["name"] == "turntable";
    return ta != tb ? ta : a["name"].get<std::string>() < b["name"].get<std::string>();
  });
  j["files"] = files;
  j["downloads"] = downloads;
  j["videos"] = videos;
  if (fs::is_regular_file(dir / "web" / "motions.json", ec) &&
      fs::is_regular_file(dir / "web" / "index.html", ec))
    j["viewer"] = "/avatars/" + id + "/web/";
  return j;
}

json Studio::state() const {
  json avatars = json::array();
  for (const auto& id : ws_.ids()) {
    json a = avatar_json(id);
    if (!a.is_null()) avatars.push_back(a);
  }
  return {
      {"version", version()},
      {"workspace", ws_.dir().string()},
      {"running", queue_->running()},
      {"limits", {{"photo_bytes", opt_.max_photo_bytes}, {"types", {"image/png", "image/jpeg"}}}},
      {"avatars", avatars}};
}

std::string Studio::add_photo(TempFile& photo, ImageType type, const std::string& label) {
  std::lock_guard<std::mutex> lock(actions_);
  if (stopping()) throw StudioError(503, "the studio is stopping");
  const AvatarRecord r = ws_.add(photo, type, label);
  queue_->enqueue(r.id);
  touch();
  return r.id;
}

void Studio::resume(const std::string& id) {
  std::lock_guard<std::mutex> lock(actions_);
  const std::optional<AvatarRecord> r = ws_.load(id);
  if (!r) throw StudioError(404, "no avatar " + id);
  if (queue_->active(id))
    throw StudioError(409, "avatar " + id + " is already queued or being made");
  if (r->state == "done") throw StudioError(409, "avatar " + id + " is already made");
  if (!queue_->enqueue(id)) throw StudioError(409, "avatar " + id + " cannot be queued now");
}

void Studio::cancel(const std::string& id) {
  std::lock_guard<std::mutex> lock(actions_);
  if (!ws_.load(id)) throw StudioError(404, "no avatar " + id);
  if (queue_->cancel(id) == CreateQueue::Cancel::kNotActive)
    throw StudioError(409, "avatar " + id + " is not queued or being made");
}

void Studio::remove(const std::string& id) {
  std::lock_guard<std::mutex> lock(actions_);
  if (!ws_.load(id)) throw StudioError(404, "no avatar " + id);
  if (queue_->active(id))
    throw StudioError(409, "avatar " + id + " is queued or being made: cancel it first");
  ws_.remove(id);
  touch();
}

}  // namespace ks

#pragma once
// The studio's workspace folder: one folder per avatar, named by the server, and nothing read or
// written outside it.
//   WORKSPACE/.studio.lock         held (flock) while a studio serves the workspace
//   WORKSPACE/uploads/             uploads in progress (emptied at start)
//   WORKSPACE/avatars/ID/          ID = YYYYMMDD-HHMMSS-xxxx (UTC time, 4 random hex digits)
//     studio.json                  the record below
//     photo.png | photo.jpg        the uploaded photo
//     create/                      `kinesplat create photo --out create/` (create.json, subject/,
//                                  prior/, avatar.ksavatar, turntable.mp4, MOTION.mp4)
//     job.log                      what create and the exports printed, the last run's
//     web/                         `kinesplat export --web` (the viewer site)
//     exports/                     avatar.ply, avatar.glb, web.zip
// An avatar folder appears whole (written as ID.new, then renamed).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "studio/upload.hpp"

namespace ks {

struct AvatarRecord {
  std::string id, label, created;  // created: ISO 8601 UTC
  std::string photo;               // the photo's file name in the avatar folder
  // queued | running | done | failed | cancelled. A record left "queued" or "running" by a studio
  // that stopped reads as interrupted.
  std::string state = "queued";
  std::string error, error_stage;  // of a failed run
  double seconds = 0;              // the last run's time
};

class Workspace {
 public:
  // Creates the folders when missing, takes the lock (ks::Error when another studio holds it) and
  // removes what an earlier studio left half-made (uploads, ID.new folders).
  explicit Workspace(const std::string& dir);
  ~Workspace();
  Workspace(const Workspace&) = delete;
  Workspace& operator=(const Workspace&) = delete;

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path uploads() const { return dir_ / "uploads"; }

  static bool valid_id(const std::string& id);
  // The avatar's folder; ks::Error for an id that is not one of the server's.
  std::filesystem::path avatar_dir(const std::string& id) const;
  bool exists(const std::string& id) const;
  // Avatar ids, newest first.
  std::vector<std::string> ids() const;

  std::optional<AvatarRecord> load(const std::string& id) const;
  void save(const AvatarRecord& r) const;  // atomically

  // A new avatar from a complete upload: its folder with the photo and a "queued" record.
  AvatarRecord add(TempFile& photo, ImageType type, const std::string& label);
  // Removes the avatar's folder (ks::Error when it cannot).
  void remove(const std::string& id);

  // A label for display from a client's file name: its last path component, control
  // characters dropped, at most 80 characters; "photo" when nothing is left.
  static std::string clean_label(const std::string& name);

 private:
  std::filesystem::path dir_;
  int lock_fd_ = -1;
};

}  // namespace ks

#pragma once
// `kinesplat studio`: a local web app that makes avatars from photos and plays them. The app's
// state and actions: the workspace (studio/workspace), the create queue (studio/create_queue), the
// list of avatars with their progress, files and downloads as JSON, and a version number that
// grows with every change (the page's event stream waits on it). Its HTTP routes are in
// studio/studio_routes; docs/studio.md describes both.
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "studio/create_queue.hpp"
#include "studio/workspace.hpp"

namespace ks {

struct StudioOptions {
  int port = 8642;                             // the studio's HTTP port (`kinesplat studio`)
  std::string workspace = "kinesplat-studio";  // the folder everything goes into
  // The kinesplat program run for create and export; empty: this program (/proc/self/exe).
  std::string program;
  std::vector<std::string> create_args;  // more `create` options for every avatar
  size_t max_photo_bytes = size_t(50) << 20;
  std::string page_dir;  // the page's files; empty: find_studio_page()
  int max_event_streams = 8;
  int event_stream_seconds = 60;  // an event stream ends after this (the page reconnects)
  double event_ping_seconds = 5;  // a "ping" event this often when nothing changes
};

// The folder of the studio page (index.html, app.js, style.css): KINESPLAT_STUDIO_DIR, else
// studio/ in the source tree beside the build folder (../studio from the program), studio/ beside
// the program, ../share/kinesplat/studio. ks::Error saying where it looked when none holds it.
std::string find_studio_page();

class Studio {
 public:
  explicit Studio(const StudioOptions& opt);  // opens the workspace (ks::Error when it cannot)
  ~Studio();                                  // shutdown()
  Studio(const Studio&) = delete;
  Studio& operator=(const Studio&) = delete;

  const StudioOptions& options() const { return opt_; }
  Workspace& workspace() { return ws_; }
  const std::string& page_dir() const { return page_dir_; }

  // Everything the page shows: {"version", "limits", "running", "avatars": [...]}.
  nlohmann::json state() const;
  nlohmann::json avatar_json(const std::string& id) const;  // one avatar (null when none)
  uint64_t version() const;
  // Waits until the version differs from `seen` or `seconds` pass; the version then.
  uint64_t wait_change(uint64_t seen, double seconds) const;
  void touch();  // something changed

  // Actions; each throws ks::Error with a message for the page (StudioError gives its status).
  std::string add_photo(TempFile& photo, ImageType type, const std::string& label);
  void resume(const std::string& id);
  void cancel(const std::string& id);
  void remove(const std::string& id);

  // The file a download / view name stands for (a fixed table: never a path from the request);
  // empty when the name is unknown or the file does not exist yet.
  std::string file_for(const std::string& id, const std::string& name) const;

  // Ends the worker (the running create interrupted, left resumable). Idempotent.
  void shutdown();
  bool stopping() const;

 private:
  StudioOptions opt_;
  std::string page_dir_;
  Workspace ws_;
  std::mutex actions_;  // one action at a time (a resume never races a removal)
  mutable std::mutex m_;
  mutable std::condition_variable cv_;
  uint64_t version_ = 1;
  bool stopping_ = false;
  std::unique_ptr<CreateQueue> queue_;
};

// An action's refusal with its HTTP status (404 no such avatar, 409 not now).
struct StudioError : std::runtime_error {
  int status;
  StudioError(int s, const std::string& m) : std::runtime_error(m), status(s) {}
};

}  // namespace ks

// `kinesplat view`: the avatar playing in a browser. Writes the `export --web` site to a temporary
// folder, serves it on 127.0.0.1 until Ctrl-C, then removes the folder.
#include <signal.h>
#include <stdlib.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "avatar/avatar.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "web/static_files.hpp"
#include "web/web_export.hpp"
#include "web/web_server.hpp"

namespace fs = std::filesystem;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

struct ViewArgs {
  std::string avatar;
  std::vector<std::string> motions;
  int port = ks::WebServerOptions{}.port;
};

// Removes a folder when it goes out of scope.
struct TempDir {
  fs::path path;
  void remove() {
    std::error_code ec;
    if (!path.empty()) fs::remove_all(path, ec);
    path.clear();
  }
  ~TempDir() { remove(); }
};

void run_view(const ViewArgs& args) {
  const ks::Avatar avatar = ks::load_avatar(args.avatar);
  std::string default_motion;
  const std::vector<ks::Motion> motions = ks::web_motions(args.motions, &default_motion);
  ks::WebExportOptions opt;
  opt.default_motion = default_motion;
  opt.bundle_dir = ks::find_viewer_bundle();

  TempDir tmp;
  std::string pattern = (fs::temp_directory_path() / "kinesplat-view-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) throw ks::Error("view: cannot create a temporary folder");
  tmp.path = pattern;
  const fs::path site = tmp.path / "site";
  ks::export_web_site(avatar, motions, site.string(), opt);

  ks::WebServerOptions so;
  so.port = args.port;
  ks::WebServer server(so);
  ks::serve_folder(server, "", site);
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  sigaction(SIGINT, &sa, &old_int);
  sigaction(SIGTERM, &sa, &old_term);
  std::printf("view: %d Gaussians, %zu motions (starting with \"%s\"), site in %s\n",
              avatar.num_gaussians(), motions.size(), default_motion.c_str(),
              site.string().c_str());
  std::printf("view: serving at %s (Ctrl-C to stop)\n", server.url().c_str());
  std::fflush(stdout);
  server.run([] { return g_stop != 0; });
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  const std::string where = tmp.path.string();
  tmp.remove();
  std::printf("view: stopped after %zu requests; removed %s\n", server.requests_served(),
              where.c_str());
}

ks::cli::CommandGroup group(75, [](CLI::App& app) {
  auto args = std::make_shared<ViewArgs>();
  auto* sub = app.add_subcommand(
      "view",
      "Play an avatar in a web browser: serves the `export --web` site on 127.0.0.1 until Ctrl-C");
  sub->add_option("avatar", args->avatar, "Avatar file (from `reconstruct`)")->required();
  sub->add_option("--motion", args->motions,
                  "Motion to start with: a built-in name (see `kinesplat motions`) or an AMASS "
                  ".npz file; repeat to add more files (the built-in motions are always offered)");
  sub->add_option("--port", args->port, "TCP port on 127.0.0.1 (0: any free port)")
      ->capture_default_str();
  sub->callback([args] { run_view(*args); });
});

}  // namespace

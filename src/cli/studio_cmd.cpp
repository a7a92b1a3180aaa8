// `kinesplat studio`: the local web app (studio/studio.hpp, docs/studio.md). Opens the workspace,
// serves the page on 127.0.0.1 (or --listen ADDR, with an access token) until Ctrl-C, then stops
// the running create (left resumable) and the server.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <memory>
#include <sstream>
#include <thread>

#include "cli/registry.hpp"
#include "core/error.hpp"
#include "studio/studio.hpp"
#include "studio/studio_routes.hpp"
#include "web/web_server.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

struct StudioArgs {
  ks::StudioOptions opt;
  std::string listen, create_options;
  bool open = false;
};

std::string random_token() {
  unsigned char b[16];
  const int fd = ::open("/dev/urandom", O_RDONLY | O_CLOEXEC);
  if (fd < 0 || ::read(fd, b, sizeof b) != ssize_t(sizeof b))
    throw ks::Error("studio: cannot read /dev/urandom for the access token");
  ::close(fd);
  static const char* hex = "0123456789abcdef";
  std::string t;
  for (unsigned char c : b) t += std::string{hex[c >> 4], hex[c & 15]};
  return t;
}

// Opens `url` in the desktop's browser (xdg-open), without waiting for it.
void open_browser(const std::string& url) {
  if (std::system("command -v xdg-open >/dev/null 2>&1") != 0) {
    std::printf("studio: --open: xdg-open is not installed; open the address yourself\n");
    return;
  }
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setsid();
    const int null = ::open("/dev/null", O_RDWR);
    ::dup2(null, 0);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execlp("xdg-open", "xdg-open", url.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
}

void run_studio(StudioArgs& a) {
  std::istringstream words(a.create_options);
  for (std::string w; words >> w;) a.opt.create_args.push_back(w);
  ks::Studio studio(a.opt);
  ks::WebServerOptions so;
  so.port = a.opt.port;
  if (!a.listen.empty()) {
    so.host = a.listen;
    so.token = random_token();
  }
  ks::WebServer server(so);
  ks::add_studio_routes(server, studio);

  const nlohmann::json st = studio.state();
  int interrupted = 0;
  for (const auto& av : st["avatars"]) interrupted += av["state"] == "interrupted";
  std::printf(
      "studio: workspace %s (%zu avatars%s)\n", studio.workspace().dir().c_str(),
      st["avatars"].size(),
      interrupted
          ? (", " + std::to_string(interrupted) + " interrupted: resume them from the page").c_str()
          : "");
  std::string url = server.url();
  if (!so.token.empty()) url += "?token=" + so.token;
  std::printf("studio: serving at %s (Ctrl-C to stop)\n", url.c_str());
  if (!so.token.empty())
    std::printf("studio: listening on %s: every request needs the token in that address\n",
                a.listen.c_str());
  std::fflush(stdout);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  sigaction(SIGINT, &sa, &old_int);
  sigaction(SIGTERM, &sa, &old_term);
  server.start();
  if (a.open) open_browser(url);
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::string running;
  const nlohmann::json now = studio.state();
  for (const auto& av : now["avatars"])
    if (av["state"] == "running") running = av["id"];
  studio.shutdown();  // the running create is stopped and stays resumable
  server.stop();
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  if (!running.empty())
    std::printf(
        "studio: stopped avatar %s while it was being made: it shows as interrupted, "
        "with a resume button, next time\n",
        running.c_str());
  std::printf("studio: stopped after %zu requests\n", server.requests_served());
}

ks::cli::CommandGroup group(76, [](CLI::App& app) {
  auto a = std::make_shared<StudioArgs>();
  auto* sub = app.add_subcommand(
      "studio",
      "A local web app: drop a photo, watch create make the avatar, play it, download it. "
      "Serves on 127.0.0.1 until Ctrl-C (docs/studio.md)");
  sub->add_option("--port", a->opt.port, "TCP port (0: any free port)")->capture_default_str();
  sub->add_option("--dir", a->opt.workspace,
                  "Workspace folder: the photos, each avatar's create folder and exports")
      ->capture_default_str();
  sub->add_flag("--open", a->open, "Open the page in the desktop's browser (xdg-open)");
  sub->add_option("--listen", a->listen,
                  "Serve on this numeric address instead of 127.0.0.1 (e.g. 0.0.0.0 for every "
                  "interface); a printed access token is then needed on every request");
  sub->add_option("--create-options", a->create_options,
                  "More `kinesplat create` options for every avatar, one string split at spaces "
                  "(e.g. \"--iters 200 --motions dance,wave\")");
  sub->callback([a] { run_studio(*a); });
});

}  // namespace

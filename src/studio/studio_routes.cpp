#include "studio/studio_routes.hpp"

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <thread>

#include "core/error.hpp"
#include "perceive/photo.hpp"
#include "studio/upload.hpp"
#include "web/static_files.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {

namespace {

using Req = WebServer::Request;
using Res = WebServer::Response;

void reply_json(Res& res, const json& j, int status = 200) {
  res.status = status;
  res.set_content(j.dump() + "\n", "application/json");
}

// Runs an action, turning its refusal into the reply.
template <class F>
void act(Res& res, F&& f) {
  try {
    f();
  } catch (const StudioError& e) {
    WebServer::reply_error(res, e.status, e.what());
  } catch (const Error& e) {
    WebServer::reply_error(res, 400, e.what());
  }
}

// The avatar id of a route's first group, or a 404 reply.
bool avatar_id(const Req& req, Res& res, Studio& studio, std::string& id) {
  id = req.matches[1];
  if (!Workspace::valid_id(id) || !studio.workspace().exists(id)) {
    WebServer::reply_error(res, 404, "no avatar \"" + id + "\"");
    return false;
  }
  return true;
}

}  // namespace

void add_studio_routes(WebServer& server, Studio& studio) {
  const fs::path page = studio.page_dir();
  server.get("/",
             [page](const Req&, Res& res) { reply_with_file(page, page / "index.html", res); });
  serve_folder(server, "/static", page);

  server.get("/api/state", [&studio](const Req&, Res& res) { reply_json(res, studio.state()); });

  // Server-Sent Events: the whole state on connecting and after every change (at most 4 a
  // second), a "ping" event every few seconds otherwise; each stream ends after a while (the page's
  // EventSource reconnects) and at most max_event_streams run at once (the rest: 503, the page
  // polls).
  auto streams = std::make_shared<std::atomic<int>>(0);
  server.get("/api/events", [&studio, &server, streams](const Req&, Res& res) {
    const StudioOptions& o = studio.options();
    if (streams->fetch_add(1) >= o.max_event_streams) {
      streams->fetch_sub(1);
      WebServer::reply_error(res, 503, "too many event streams; poll /api/state instead");
      return;
    }
    struct Stream {
      uint64_t seen = 0;
      bool started = false;
      std::chrono::steady_clock::time_point end;
    };
    auto st = std::make_shared<Stream>();
    st->end = std::chrono::steady_clock::now() + std::chrono::seconds(o.event_stream_seconds);
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [&studio, &server, st](size_t, httplib::DataSink& sink) {
          if (!st->started) {
            st->started = true;
            const std::string hello = "retry: 1500\n\n";
            return sink.write(hello.data(), hello.size());
          }
          const uint64_t v = studio.wait_change(st->seen, studio.options().event_ping_seconds);
          if (server.stopping() || studio.stopping() ||
              std::chrono::steady_clock::now() > st->end) {
            sink.done();
            return true;
          }
          std::string msg;
          if (v != st->seen) {
            st->seen = v;
            msg = "event: state\ndata: " + studio.state().dump() + "\n\n";
          } else {
            msg = "event: ping\ndata: {}\n\n";
          }
          if (!sink.write(msg.data(), msg.size())) return false;  // the page went away
          std::this_thread::sleep_for(std::chrono::milliseconds(250));
          return true;
        },
        [streams](bool) { streams->fetch_sub(1); });
  });

  const size_t max_photo = studio.options().max_photo_bytes;
  server.post(
      "/api/avatars",
      [&studio, max_photo](const Req& req, Res& res, const httplib::ContentReader& reader) {
        size_t declared = 0;
        try {
          declared = size_t(std::stoull(req.get_header_value("Content-Length")));
        } catch (const std::exception&) {
        }
        UploadResult up = receive_photo(reader, declared, studio.workspace().uploads(), max_photo);
        if (up.status == 0) return;  // the client went away; nothing was kept
        if (up.status != 200) {
          WebServer::reply_error(res, up.status, up.error);
          WebServer::close_after_reply(res);
          return;
        }
        try {
          (void)load_photo(up.file.path().string(), 256);  // decodes as create will
        } catch (const std::exception& e) {
          std::string why = e.what();
          const std::string at = up.file.path().string() + ": ";
          if (why.rfind(at, 0) == 0) why = why.substr(at.size());
          WebServer::reply_error(res, 415,
                                 std::string("the file begins like a ") +
                                     (up.type == ImageType::kPng ? "PNG" : "JPEG") +
                                     " but cannot be read as one (" + why + ")");
          return;
        }
        std::string name;
        if (!percent_decode(req.get_header_value("X-Filename"), name)) name.clear();
        act(res, [&] {
          const std::string id = studio.add_photo(up.file, up.type, Workspace::clean_label(name));
          reply_json(res, {{"id", id}, {"avatar", studio.avatar_json(id)}}, 201);
        });
      },
      max_photo,
      [](size_t declared, size_t limit) {
        return "the photo is " + megabytes(declared) + ", over the " + megabytes(limit) +
               " the studio takes";
      });

  const std::string id_re = "/api/avatars/([^/]+)";
  server.get(id_re, [&studio](const Req& req, Res& res) {
    std::string id;
    if (avatar_id(req, res, studio, id)) reply_json(res, studio.avatar_json(id));
  });
  server.del(id_re, [&studio](const Req& req, Res& res) {
    std::string id;
    if (!avatar_id(req, res, studio, id)) return;
    act(res, [&] {
      studio.remove(id);
      reply_json(res, {{"removed", id}});
    });
  });
  server.post(id_re + "/resume", [&studio](const Req& req, Res& res) {
    std::string id;
    if (!avatar_id(req, res, studio, id)) return;
    act(res, [&] {
      studio.resume(id);
      reply_json(res, studio.avatar_json(id));
    });
  });
  server.post(id_re + "/cancel", [&studio](const Req& req, Res& res) {
    std::string id;
    if (!avatar_id(req, res, studio, id)) return;
    act(res, [&] {
      studio.cancel(id);
      reply_json(res, studio.avatar_json(id));
    });
  });
  server.get(id_re + "/files/([^/]+)", [&studio](const Req& req, Res& res) {
    std::string id;
    if (!avatar_id(req, res, studio, id)) return;
    const std::string name = req.matches[2];
    const std::string path = studio.file_for(id, name);
    if (path.empty()) {
      WebServer::reply_error(res, 404, "avatar " + id + " has no file \"" + name + "\" (yet)");
      return;
    }
    reply_with_file(fs::path(path).parent_path(), path, res);
    if (req.get_param_value("download") == "1")
      res.set_header("Content-Disposition",
                     "attachment; filename=\"kinesplat-" + id + "-" +
                         (name == "photo" ? fs::path(path).filename().string() : name) + "\"");
  });

  // The viewer site of each avatar, as `kinesplat view` serves it.
  server.get("/avatars/([^/]+)/web", [&studio](const Req& req, Res& res) {
    std::string id;
    if (avatar_id(req, res, studio, id)) res.set_redirect("/avatars/" + id + "/web/", 301);
  });
  server.get("/avatars/([^/]+)/web/.*", [&studio](const Req& req, Res& res) {
    std::string id;
    if (!avatar_id(req, res, studio, id)) return;
    reply_under_prefix("/avatars/" + id + "/web", studio.workspace().avatar_dir(id) / "web", req,
                       res);
  });
}

}  // namespace ks

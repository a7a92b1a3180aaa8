#pragma once
// The studio's HTTP routes (docs/studio.md lists them):
//   GET    /                                  the page (studio/index.html)
//   GET    /static/...                        the page's files
//   GET    /api/state                         every avatar, its state, progress, files (JSON)
//   GET    /api/events                        the same as Server-Sent Events, on every change
//   POST   /api/avatars                       upload a photo (the body: its bytes) -> 201 {"id"}
//   GET    /api/avatars/ID                    one avatar
//   DELETE /api/avatars/ID                    remove it (not while queued or being made)
//   POST   /api/avatars/ID/resume | /cancel   queue again (create resumes) | stop
//   GET    /api/avatars/ID/files/NAME         a file by name from a fixed list (?download=1:
//                                             as an attachment)
//   GET    /avatars/ID/web/...                the avatar's viewer site (export --web)
// Errors are JSON {"error": "..."} with their status.
#include "studio/studio.hpp"
#include "web/web_server.hpp"

namespace ks {

void add_studio_routes(WebServer& server, Studio& studio);

}  // namespace ks

#pragma once
// Files under a folder, served by web/web_server: content types by extension, request targets
// resolved under the folder (nothing outside it is ever named), files streamed from disk (Range
// requests answered, as video players ask). `kinesplat view` serves its site with serve_folder;
// `kinesplat studio` serves its page, the viewer and each avatar's files the same way.
#include <filesystem>
#include <optional>
#include <string>

#include "web/web_server.hpp"

namespace ks {

// Content-Type for a file name, by its (case-insensitive) extension; application/octet-stream
// when unknown.
std::string mime_type_for(const std::string& filename);

// Decodes %XX escapes ('+' stays '+'); false for a malformed escape.
bool percent_decode(const std::string& in, std::string& out);

// True when `p` lies inside `root` (or is the root) once symbolic links are resolved.
bool path_within(const std::filesystem::path& root, const std::filesystem::path& p);

// The file a request target ("/a/b.js?x=1", still percent-encoded) names under `root`, or nothing
// when the target is refused (not absolute, bad percent-encoding, "..", NUL, backslash, or it
// resolves outside the root, through a symbolic link say). The file need not exist; a target
// ending in "/" names that folder's index.html.
std::optional<std::filesystem::path> resolve_request_path(const std::filesystem::path& root,
                                                          const std::string& target);

// Answers with the file at `path` (already resolved and checked): 200 (or 206 for a Range) with
// its content type, streamed; 404 when it is not a regular file; a folder serves its index.html
// when that lies under `root`.
void reply_with_file(const std::filesystem::path& root, const std::filesystem::path& path,
                     WebServer::Response& res);

// GET / HEAD of `prefix` + path serves `root` + path: `prefix` is "" (the whole server) or
// "/a/b" (no trailing slash); "/a/b" alone redirects to "/a/b/". Refused targets are 403.
// Answers a GET for `prefix` + PATH with the file PATH under `root`: the prefix must be as sent
// (not percent-encoded differently), the path go through resolve_request_path; else 403.
void reply_under_prefix(const std::string& prefix, const std::filesystem::path& root,
                        const WebServer::Request& req, WebServer::Response& res);
void serve_folder(WebServer& server, const std::string& prefix, const std::filesystem::path& root);

}  // namespace ks

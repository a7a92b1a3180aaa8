#include "web/static_files.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <memory>
#include <regex>

namespace fs = std::filesystem;

namespace ks {

std::string mime_type_for(const std::string& filename) {
  std::string ext = fs::path(filename).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  static const std::pair<const char*, const char*> table[] = {
      {".html", "text/html; charset=utf-8"},
      {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".txt", "text/plain; charset=utf-8"},
      {".md", "text/plain; charset=utf-8"},
      {".wasm", "application/wasm"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".svg", "image/svg+xml"},
      {".ico", "image/x-icon"},
      {".mp4", "video/mp4"},
      {".zip", "application/zip"},
      {".glb", "model/gltf-binary"},
      {".ply", "application/octet-stream"},
      {".ksavatar", "application/octet-stream"},
      {".spz", "application/octet-stream"},
      {".bin", "application/octet-stream"},
  };
  for (const auto& [e, type] : table)
    if (ext == e) return type;
  return "application/octet-stream";
}

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

bool percent_decode(const std::string& in, std::string& out) {
  out.clear();
  for (size_t i = 0; i < in.size(); ++i) {
    if (in[i] != '%') {
      out += in[i];
      continue;
    }
    if (i + 2 >= in.size()) return false;
    const int hi = hex_value(in[i + 1]), lo = hex_value(in[i + 2]);
    if (hi < 0 || lo < 0) return false;
    out += char(hi * 16 + lo);
    i += 2;
  }
  return true;
}

bool path_within(const fs::path& root, const fs::path& p) {
  std::error_code ec;
  const fs::path croot = fs::weakly_canonical(root, ec);
  if (ec) return false;
  const fs::path cp = fs::weakly_canonical(p, ec);
  if (ec) return false;
  auto r = croot.begin(), q = cp.begin();
  for (; r != croot.end(); ++r, ++q)
    if (q == cp.end() || *r != *q) return false;
  return true;
}

std::optional<fs::path> resolve_request_path(const fs::path& root, const std::string& target) {
  if (target.empty() || target[0] != '/') return std::nullopt;
  const std::string raw = target.substr(0, target.find_first_of("?#"));
  std::string path;
  if (!percent_decode(raw, path)) return std::nullopt;
  if (path.find('\0') != std::string::npos || path.find('\\') != std::string::npos)
    return std::nullopt;
  fs::path out = root;
  size_t start = 1;
  while (start <= path.size()) {
    size_t end = path.find('/', start);
    if (end == std::string::npos) end = path.size();
    const std::string seg = path.substr(start, end - start);
    if (seg == "..") return std::nullopt;
    if (!seg.empty() && seg != ".") out /= seg;
    start = end + 1;
  }
  if (path.back() == '/') out /= "index.html";
  if (!path_within(root, out)) return std::nullopt;  // a symbolic link leads out
  return out;
}

void reply_with_file(const fs::path& root, const fs::path& path, WebServer::Response& res) {
  std::error_code ec;
  fs::path file = path;
  if (fs::is_directory(file, ec)) {
    file /= "index.html";
    if (!path_within(root, file)) {
      WebServer::reply_error(res, 403, "refused");
      return;
    }
  }
  if (!fs::is_regular_file(file, ec)) {
    WebServer::reply_error(res, 404, "not found");
    return;
  }
  auto in = std::make_shared<std::ifstream>(file, std::ios::binary);
  const auto size = fs::file_size(file, ec);
  if (!*in || ec) {
    WebServer::reply_error(res, 404, "not found");
    return;
  }
  // Streamed in pieces: the library asks for [offset, offset + length) of the (range of the) file.
  res.set_content_provider(size_t(size), mime_type_for(file.string()),
                           [in](size_t offset, size_t length, httplib::DataSink& sink) {
                             std::vector<char> chunk(std::min<size_t>(length, 64 * 1024));
                             in->clear();
                             in->seekg(std::streamoff(offset));
                             in->read(chunk.data(), std::streamsize(chunk.size()));
                             const std::streamsize got = in->gcount();
                             if (got <= 0) return false;
                             return sink.write(chunk.data(), size_t(got));
                           });
}

void reply_under_prefix(const std::string& prefix, const fs::path& root,
                        const WebServer::Request& req, WebServer::Response& res) {
  // The prefix as sent, not percent-encoded differently (the route matched the decoded path).
  const bool literal = req.target.compare(0, prefix.size(), prefix) == 0;
  const std::optional<fs::path> p =
      literal ? resolve_request_path(root, req.target.substr(prefix.size())) : std::nullopt;
  if (!p) {
    WebServer::reply_error(res, 403, "refused: " + req.target);
    return;
  }
  reply_with_file(root, *p, res);
}

void serve_folder(WebServer& server, const std::string& prefix, const fs::path& root) {
  const std::string quoted =
      std::regex_replace(prefix, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)");
  if (!prefix.empty())
    server.get(quoted, [prefix](const WebServer::Request&, WebServer::Response& res) {
      res.set_redirect(prefix + "/", 301);
    });
  server.get(quoted + "/.*",
             [root, prefix](const WebServer::Request& req, WebServer::Response& res) {
               reply_under_prefix(prefix, root, req, res);
             });
}

}  // namespace ks

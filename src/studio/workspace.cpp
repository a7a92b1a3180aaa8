#include "studio/workspace.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <ctime>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace ks {

namespace {

std::string utc_now(const char* format) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::gmtime_r(&t, &tm);
  char b[40];
  std::strftime(b, sizeof b, format, &tm);
  return b;
}

const std::regex& id_re() {
  static const std::regex re("^[0-9]{8}-[0-9]{6}-[0-9a-f]{4}$");
  return re;
}

}  // namespace

Workspace::Workspace(const std::string& dir) {
  if (dir.empty()) throw Error("studio: no workspace folder given");
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw Error("studio: " + dir + " exists and is not a folder");
  fs::create_directories(fs::path(dir) / "avatars", ec);
  if (ec) throw Error("studio: cannot create the workspace " + dir + ": " + ec.message());
  dir_ = fs::canonical(dir);
  const fs::path lock = dir_ / ".studio.lock";
  lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0) throw Error("studio: cannot open " + lock.string());
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw Error("studio: another studio is serving the workspace " + dir_.string() +
                " (stop it first, or give another --dir)");
  }
  // Half-made things of an earlier studio.
  fs::remove_all(uploads(), ec);
  fs::create_directories(uploads(), ec);
  for (const auto& e : fs::directory_iterator(dir_ / "avatars", ec))
    if (e.path().extension() == ".new") fs::remove_all(e.path(), ec);
}

Workspace::~Workspace() {
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the lock
}

bool Workspace::valid_id(const std::string& id) {
  return std::regex_match(id, id_re());
}

fs::path Workspace::avatar_dir(const std::string& id) const {
  if (!valid_id(id)) throw Error("studio: \"" + id + "\" is not an avatar id");
  return dir_ / "avatars" / id;
}

bool Workspace::exists(const std::string& id) const {
  std::error_code ec;
  return valid_id(id) && fs::is_regular_file(avatar_dir(id) / "studio.json", ec);
}

std::vector<std::string> Workspace::ids() const {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir_ / "avatars", ec)) {
    const std::string name = e.path().filename().string();
    if (valid_id(name) && fs::is_regular_file(e.path() / "studio.json", ec)) out.push_back(name);
  }
  std::sort(out.rbegin(), out.rend());
  return out;
}

std::optional<AvatarRecord> Workspace::load(const std::string& id) const {
  if (!valid_id(id)) return std::nullopt;
  try {
    const json j = read_json((avatar_dir(id) / "studio.json").string());
    AvatarRecord r;
    r.id = id;
    r.label = j.value("label", "");
    r.created = j.value("created", "");
    r.photo = j.value("photo", "");
    r.state = j.value("state", "queued");
    r.error = j.value("error", "");
    r.error_stage = j.value("error_stage", "");
    r.seconds = j.value("seconds", 0.0);
    // The photo is one of the two names the server gives, whatever the file says.
    if (r.photo != "photo.png" && r.photo != "photo.jpg") r.photo.clear();
    return r;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

void Workspace::save(const AvatarRecord& r) const {
  const json j = {{"format", "kinesplat-studio-avatar"},
                  {"version", 1},
                  {"id", r.id},
                  {"label", r.label},
                  {"created", r.created},
                  {"photo", r.photo},
                  {"state", r.state},
                  {"error", r.error},
                  {"error_stage", r.error_stage},
                  {"seconds", r.seconds}};
  write_json_atomic((avatar_dir(r.id) / "studio.json").string(), j);
}

AvatarRecord Workspace::add(TempFile& photo, ImageType type, const std::string& label) {
  static thread_local std::mt19937 rng(std::random_device{}());
  AvatarRecord r;
  fs::path final_dir;
  for (int attempt = 0; attempt < 16; ++attempt) {
    char hex[8];
    std::snprintf(hex, sizeof hex, "%04x", unsigned(rng() & 0xffff));
    r.id = utc_now("%Y%m%d-%H%M%S") + "-" + hex;
    final_dir = avatar_dir(r.id);
    std::error_code ec;
    if (!fs::exists(final_dir, ec) && !fs::exists(final_dir.string() + ".new", ec)) break;
    r.id.clear();
  }
  if (r.id.empty()) throw Error("studio: cannot find a free avatar id");
  r.label = label;
  r.created = utc_now("%Y-%m-%dT%H:%M:%SZ");
  r.photo = std::string("photo") + image_extension(type);
  r.state = "queued";
  const fs::path staging = final_dir.string() + ".new";
  fs::create_directories(staging);
  try {
    fs::rename(photo.path(), staging / r.photo);
    photo.keep();
    const json j = {{"format", "kinesplat-studio-avatar"},
                    {"version", 1},
                    {"id", r.id},
                    {"label", r.label},
                    {"created", r.created},
                    {"photo", r.photo},
                    {"state", r.state}};
    write_json_atomic((staging / "studio.json").string(), j);
    fs::rename(staging, final_dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(staging, ec);
    throw;
  }
  return r;
}

void Workspace::remove(const std::string& id) {
  const fs::path d = avatar_dir(id);
  // Renamed first, so that a listing never sees it half-removed.
  const fs::path gone = d.string() + ".new";
  std::error_code ec;
  fs::rename(d, gone, ec);
  if (ec) throw Error("studio: cannot remove avatar " + id + ": " + ec.message());
  fs::remove_all(gone, ec);
}

std::string Workspace::clean_label(const std::string& name) {
  std::string base =
      name.substr(name.find_last_of("/\\") == std::string::npos ? 0 : name.find_last_of("/\\") + 1);
  std::string out;
  for (size_t i = 0; i < base.size();) {
    const unsigned char c = static_cast<unsigned char>(base[i]);
    // A whole UTF-8 sequence is kept; a stray byte becomes '?'; control characters go.
    const size_t n = c < 0x80           ? 1
                     : (c >> 5) == 0x6  ? 2
                     : (c >> 4) == 0xe  ? 3
                     : (c >> 3) == 0x1e ? 4
                                        : 0;
    bool ok = n > 0 && i + n <= base.size();
    for (size_t k = 1; ok && k < n; ++k)
      ok = (static_cast<unsigned char>(base[i + k]) & 0xc0) == 0x80;
    if (!ok) {
      out += '?';
      ++i;
      continue;
    }
    if (n > 1 || (c >= 0x20 && c != 0x7f)) out += base.substr(i, n);
    i += n;
  }
  // At most 80 bytes, not cutting a UTF-8 sequence.
  if (out.size() > 80) {
    size_t cut = 80;
    while (cut > 0 && (static_cast<unsigned char>(out[cut]) & 0xc0) == 0x80) --cut;
    out.resize(cut);
  }
  return out.empty() ? "photo" : out;
}

}  // namespace ks

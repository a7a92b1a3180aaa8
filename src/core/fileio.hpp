#pragma once
// File helpers that never leave a half-written file behind: every writer goes to a temporary
// file beside the target and renames it into place only when complete.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace ks {

// Reads a whole file; throws ks::Error("cannot open <path>: ...") if it is missing or unreadable.
std::vector<uint8_t> read_file_bytes(const std::string& path);
std::string read_file_text(const std::string& path);
// Parses JSON; a malformed file gives ks::Error naming the file and the parser's message.
nlohmann::json read_json(const std::string& path);

// Writes bytes/text atomically (temp file + rename). Creates parent directories.
void write_file_atomic(const std::string& path, const void* data, size_t size);
void write_text_atomic(const std::string& path, const std::string& text);
void write_json_atomic(const std::string& path, const nlohmann::json& j);

// Calls `write(tmp_path)` to produce the file, then renames tmp_path -> path. On exception
// the temporary is removed and the exception re-thrown. `tmp_path` keeps the target's extension
// so that writers choosing a format by extension (OpenCV) still work.
void write_via_temp(const std::string& path, const std::function<void(const std::string&)>& write);

// A directory output that appears only when complete: work in `staging()`, then `commit()`
// renames it to `final_dir` (replacing an existing directory there). If never committed, the
// destructor removes the staging directory.
class StagedDir {
 public:
  explicit StagedDir(const std::string& final_dir);
  ~StagedDir();
  StagedDir(const StagedDir&) = delete;
  StagedDir& operator=(const StagedDir&) = delete;
  const std::filesystem::path& staging() const { return staging_; }
  std::string path(const std::string& rel) const { return (staging_ / rel).string(); }
  void commit();

 private:
  std::filesystem::path final_;
  std::filesystem::path staging_;
  bool committed_ = false;
};

}  // namespace ks

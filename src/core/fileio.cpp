#include "core/fileio.hpp"

#include <unistd.h>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {
std::string unique_suffix() {
  static std::atomic<unsigned> counter{0};
  const auto now = std::chrono::steady_clock::now().time_since_epoch().count();
  return ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" +
         std::to_string(now % 1000000);
}

void ensure_parent(const fs::path& p) {
  if (p.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(p.parent_path(), ec);
    if (ec)
      throw Error("cannot create directory " + p.parent_path().string() + ": " + ec.message());
  }
}
}  // namespace

std::vector<uint8_t> read_file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (!fs::exists(path)) throw Error("cannot open " + path + ": no such file");
    throw Error("cannot open " + path + ": " + std::strerror(errno));
  }
  if (fs::is_directory(path)) throw Error("cannot read " + path + ": it is a directory");
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  in.seekg(0, std::ios::beg);
  std::vector<uint8_t> bytes(size > 0 ? size_t(size) : 0);
  if (!bytes.empty() && !in.read(reinterpret_cast<char*>(bytes.data()), bytes.size()))
    throw Error("cannot read " + path);
  return bytes;
}

std::string read_file_text(const std::string& path) {
  auto b = read_file_bytes(path);
  return std::string(b.begin(), b.end());
}

nlohmann::json read_json(const std::string& path) {
  const std::string text = read_file_text(path);
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for 1e999
    throw Error("malformed JSON in " + path + ": " + e.what());
  }
}

void write_via_temp(const std::string& path, const std::function<void(const std::string&)>& write) {
  fs::path target(path);
  ensure_parent(target);
  fs::path tmp = target;
  std::string name(".");
  name += target.stem().string();
  name += unique_suffix();
  name += target.extension().string();
  tmp.replace_filename(name);
  try {
    write(tmp.string());
    fs::rename(tmp, target);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
}

void write_file_atomic(const std::string& path, const void* data, size_t size) {
  write_via_temp(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error("cannot write " + path + ": " + std::strerror(errno));
    out.write(static_cast<const char*>(data), std::streamsize(size));
    out.flush();
    if (!out) throw Error("cannot write " + path + ": write failed");
  });
}

void write_text_atomic(const std::string& path, const std::string& text) {
  write_file_atomic(path, text.data(), text.size());
}

void write_json_atomic(const std::string& path, const nlohmann::json& j) {
  write_text_atomic(path, j.dump(2) + "\n");
}

StagedDir::StagedDir(const std::string& final_dir) : final_(final_dir) {
  if (final_.filename().empty()) final_ = final_.parent_path();
  ensure_parent(fs::absolute(final_));
  staging_ = final_;
  std::string name(".");
  name += final_.filename().string();
  name += unique_suffix();
  staging_.replace_filename(name);
  std::error_code ec;
  fs::create_directories(staging_, ec);
  if (ec) throw Error("cannot create directory " + staging_.string() + ": " + ec.message());
}

StagedDir::~StagedDir() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_, ec);
  }
}

void StagedDir::commit() {
  std::error_code ec;
  if (fs::exists(final_)) {
    fs::remove_all(final_, ec);
    if (ec) throw Error("cannot replace " + final_.string() + ": " + ec.message());
  }
  fs::rename(staging_, final_, ec);
  if (ec) throw Error("cannot move output into " + final_.string() + ": " + ec.message());
  committed_ = true;
}

}  // namespace ks

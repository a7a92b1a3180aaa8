#include "studio/upload.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>

namespace fs = std::filesystem;

namespace ks {

ImageType sniff_image(const char* data, size_t size) {
  static const unsigned char png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const auto* d = reinterpret_cast<const unsigned char*>(data);
  if (size >= 8 && std::memcmp(d, png, 8) == 0) return ImageType::kPng;
  if (size >= 3 && d[0] == 0xff && d[1] == 0xd8 && d[2] == 0xff) return ImageType::kJpeg;
  return ImageType::kUnknown;
}

const char* image_extension(ImageType t) {
  switch (t) {
    case ImageType::kPng:
      return ".png";
    case ImageType::kJpeg:
      return ".jpg";
    default:
      return "";
  }
}

std::string megabytes(size_t bytes) {
  const double mb = double(bytes) / (1024.0 * 1024.0);
  char b[32];
  if (mb < 10 && bytes % (1024 * 1024) != 0)
    std::snprintf(b, sizeof b, "%.1f MB", mb);
  else
    std::snprintf(b, sizeof b, "%.0f MB", mb);
  return b;
}

TempFile::~TempFile() {
  remove();
}

fs::path TempFile::keep() {
  fs::path p = path_;
  path_.clear();
  return p;
}

void TempFile::remove() {
  if (path_.empty()) return;
  std::error_code ec;
  fs::remove(path_, ec);
  path_.clear();
}

namespace {

std::string random_hex(int n) {
  static thread_local std::mt19937_64 rng(std::random_device{}());
  static const char* digits = "0123456789abcdef";
  std::string s;
  for (int i = 0; i < n; ++i) s += digits[rng() % 16];
  return s;
}

std::string first_bytes(const std::string& head) {
  std::string out;
  for (size_t i = 0; i < head.size() && i < 8; ++i) {
    char b[4];
    std::snprintf(b, sizeof b, "%02x", static_cast<unsigned char>(head[i]));
    if (i) out += ' ';
    out += b;
  }
  return out;
}

}  // namespace

UploadResult receive_photo(const httplib::ContentReader& reader, size_t declared,
                           const fs::path& dir, size_t max_bytes) {
  UploadResult r;
  if (declared == 0) {
    r.status = 400;
    r.error = "the upload is empty: send the photo's bytes as the request body";
    return r;
  }
  if (declared > max_bytes) {
    r.status = 413;
    r.error = "the photo is " + megabytes(declared) + ", over the " + megabytes(max_bytes) +
              " the studio takes";
    return r;
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  int fd = -1;
  fs::path path;
  for (int attempt = 0; attempt < 8 && fd < 0; ++attempt) {
    path = dir / ("upload-" + random_hex(16) + ".part");
    fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  }
  if (fd < 0) {
    r.status = 500;
    r.error = "cannot create a file in " + dir.string() + ": " + std::strerror(errno);
    return r;
  }
  r.file = TempFile(path);
  std::string head;  // the first bytes, until the type is known
  bool write_failed = false;
  const bool complete = reader([&](const char* data, size_t len) {
    if (r.bytes + len > max_bytes || r.bytes + len > declared) {
      r.status = 413;
      r.error = "the upload is longer than it said (" + std::to_string(declared) + " bytes)";
      return false;
    }
    if (r.type == ImageType::kUnknown) {
      head.append(data, std::min(len, size_t(16)));
      r.type = sniff_image(head.data(), head.size());
      if (r.type == ImageType::kUnknown && (head.size() >= 8 || r.bytes + len >= declared)) {
        r.status = 415;
        r.error = "not a PNG or JPEG image (by its content: it begins with " + first_bytes(head) +
                  "); the studio takes the photos create reads: PNG or JPEG";
        return false;
      }
    }
    for (size_t done = 0; done < len;) {
      const ssize_t w = ::write(fd, data + done, len - done);
      if (w < 0 && errno == EINTR) continue;
      if (w <= 0) {
        write_failed = true;
        r.status = 507;
        r.error = std::string("cannot store the upload: ") + std::strerror(errno);
        return false;
      }
      done += size_t(w);
    }
    r.bytes += len;
    return true;
  });
  const bool synced = !write_failed && ::fsync(fd) == 0;
  ::close(fd);
  if (r.status != 0) {  // refused (the body was not read to its end)
    r.file.remove();
    return r;
  }
  if (!complete || r.bytes != declared) {
    r.file.remove();  // the client went away mid-body
    r.status = 0;
    r.error = "the upload was cut off after " + std::to_string(r.bytes) + " of " +
              std::to_string(declared) + " bytes";
    return r;
  }
  if (!synced) {
    r.file.remove();
    r.status = 507;
    r.error = "cannot store the upload";
    return r;
  }
  r.status = 200;
  return r;
}

}  // namespace ks

#pragma once
// A photo uploaded to the studio: the request body streamed into a temporary file that the server
// names itself (the client's file name is never a path), its type decided by its first bytes (PNG
// or JPEG, what `create` reads) and refused at once otherwise, its size bounded, and the file
// removed whenever the upload does not complete (a client gone mid-body, a refusal, an error):
// nothing half-uploaded is left behind.
#include "web/httplib.hpp"

#include <cstddef>
#include <filesystem>
#include <string>

namespace ks {

enum class ImageType { kUnknown, kPng, kJpeg };

// PNG (the 8-byte signature) or JPEG (FF D8 FF) by the first bytes; kUnknown otherwise, also
// when fewer bytes than needed are given.
ImageType sniff_image(const char* data, size_t size);
const char* image_extension(ImageType t);  // ".png", ".jpg", ""

// "50 MB" (sizes in units of 2^20 bytes, one decimal below 10).
std::string megabytes(size_t bytes);

// A file that is removed when this goes out of scope, unless kept.
class TempFile {
 public:
  explicit TempFile(std::filesystem::path p = {}) : path_(std::move(p)) {}
  ~TempFile();
  TempFile(TempFile&& o) noexcept : path_(std::move(o.path_)) { o.path_.clear(); }
  TempFile& operator=(TempFile&& o) noexcept {
    if (this != &o) {
      remove();
      path_ = std::move(o.path_);
      o.path_.clear();
    }
    return *this;
  }
  TempFile(const TempFile&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path keep();  // the caller owns the file now
  void remove();

 private:
  std::filesystem::path path_;
};

struct UploadResult {
  int status = 0;     // 200: complete; else the HTTP status to answer (0: the client went away)
  std::string error;  // for the reply, when status is not 200
  ImageType type = ImageType::kUnknown;
  size_t bytes = 0;
  TempFile file;  // the complete upload, removed unless kept
};

// Reads the body through `reader` into a new file in `dir` (created 0600 with a name of the
// server's choosing). `declared` is the request's Content-Length (already checked against
// `max_bytes` by the server's route limit; checked again here as the bytes arrive).
UploadResult receive_photo(const httplib::ContentReader& reader, size_t declared,
                           const std::filesystem::path& dir, size_t max_bytes);

}  // namespace ks

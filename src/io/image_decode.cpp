#include "io/image_decode.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <opencv2/imgcodecs.hpp>

#include "core/error.hpp"

namespace ks {

namespace {

uint32_t be16(const uint8_t* p) {
  return uint32_t(p[0]) << 8 | p[1];
}
uint32_t be32(const uint8_t* p) {
  return be16(p) << 16 | be16(p + 2);
}

// Runs `f` with file descriptor 2 pointed at /dev/null (one caller at a time).
template <typename F>
auto without_stderr(F&& f) {
  static std::mutex m;
  std::lock_guard<std::mutex> lock(m);
  std::fflush(stderr);
  const int saved = ::dup(2);
  const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (saved >= 0 && null >= 0) ::dup2(null, 2);
  if (null >= 0) ::close(null);
  struct Restore {
    int saved;
    ~Restore() {
      std::fflush(stderr);
      if (saved >= 0) {
        ::dup2(saved, 2);
        ::close(saved);
      }
    }
  } restore{saved};
  return f();
}

}  // namespace

std::string png_chunk_problem(const std::vector<uint8_t>& b) {
  static const uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (b.size() < 8 || std::memcmp(b.data(), png_sig, 8) != 0) return {};
  size_t i = 8;
  while (i < b.size()) {
    const size_t left = b.size() - i;
    if (left < 8)
      return "it ends inside a chunk header at byte " + std::to_string(i) + " (truncated)";
    const uint64_t len = be32(&b[i]);
    std::string type(reinterpret_cast<const char*>(&b[i + 4]), 4);
    for (char& c : type)
      if (!std::isalpha(static_cast<unsigned char>(c))) c = '?';
    if (len > 0x7FFFFFFFu || len + 12 > left)
      return "its '" + type + "' chunk at byte " + std::to_string(i) + " claims " +
             std::to_string(len) + " bytes but only " + std::to_string(left) +
             " are left in the file (truncated or damaged)";
    if (type == "IEND") return {};
    i += 12 + len;
  }
  return "it has no IEND chunk (truncated)";
}

bool image_header_size(const std::vector<uint8_t>& b, int64_t& width, int64_t& height) {
  const size_t n = b.size();
  static const uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (n >= 24 && std::memcmp(b.data(), png_sig, 8) == 0 && std::memcmp(&b[12], "IHDR", 4) == 0) {
    width = be32(&b[16]);
    height = be32(&b[20]);
    return true;
  }
  if (n >= 4 && b[0] == 0xFF && b[1] == 0xD8) {  // JPEG: walk the segments to a start of frame
    size_t i = 2;
    while (i + 4 <= n) {
      // As libjpeg reads markers: bytes before a marker that are not 0xFF are skipped (it warns
      // of "extraneous bytes" and goes on), and so are 0xFF fill bytes.
      if (b[i] != 0xFF) {
        ++i;
        continue;
      }
      const uint8_t marker = b[i + 1];
      if (marker == 0xFF || marker == 0x00) {  // fill byte, or a stuffed 0xFF
        ++i;
        continue;
      }
      if (marker == 0xD9 || marker == 0xDA) break;
      const size_t len = be16(&b[i + 2]);
      const bool sof =
          marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
      if (sof && len >= 7 && i + 9 <= n) {
        height = be16(&b[i + 5]);
        width = be16(&b[i + 7]);
        return true;
      }
      if (len < 2) break;
      i += 2 + len;
    }
  }
  return false;
}

cv::Mat decode_image_file(const std::vector<uint8_t>& bytes, const std::string& path) {
  if (bytes.empty()) throw Error("cannot read image " + path + ": the file is empty");
  int64_t w = 0, h = 0;
  if (image_header_size(bytes, w, h) && h > 0 && w > kMaxImagePixels / h)  // w * h may overflow
    throw Error("cannot read image " + path + ": it is " + std::to_string(w) + " x " +
                std::to_string(h) + " pixels, more than the " + std::to_string(kMaxImagePixels) +
                " kinesplat reads (downscale it first)");
  const std::string chunk_problem = png_chunk_problem(bytes);
  if (!chunk_problem.empty()) throw Error("cannot read image " + path + ": " + chunk_problem);
  cv::Mat m = without_stderr([&] {
    try {
      return cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception&) {
      return cv::Mat();
    }
  });
  if (m.empty())
    throw Error("cannot read image " + path + ": not a PNG, JPEG or other readable image");
  return m;
}

}  // namespace ks

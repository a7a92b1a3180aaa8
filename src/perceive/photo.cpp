#include "perceive/photo.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/image_decode.hpp"
#include "io/image_io.hpp"

namespace ks {

namespace {

// A TIFF block (EXIF data): its byte order and the entries of its IFDs, every offset checked.
class Tiff {
 public:
  Tiff(const uint8_t* p, size_t n) : p_(p), n_(n) {
    if (n < 8) return;
    if (p[0] == 'I' && p[1] == 'I')
      le_ = true;
    else if (p[0] == 'M' && p[1] == 'M')
      le_ = false;
    else
      return;
    ok_ = u16(2) == 42;
  }
  // IFD0's offset; 0 when the block is not TIFF.
  size_t first_ifd() const { return ok_ ? u32(4) : 0; }
  // Tag `tag` of the IFD at `ifd` with type SHORT (3) or LONG (4): its value; false when absent.
  bool find(size_t ifd, uint32_t tag, uint32_t* value) const {
    if (!ok_ || ifd == 0 || ifd + 2 > n_) return false;
    const size_t count = u16(ifd);
    for (size_t i = 0; i < count; ++i) {
      const size_t e = ifd + 2 + 12 * i;
      if (e + 12 > n_) return false;
      if (u16(e) != tag) continue;
      const uint32_t type = u16(e + 2);
      if (type == 3)
        *value = u16(e + 8);
      else if (type == 4)
        *value = u32(e + 8);
      else
        return false;
      return true;
    }
    return false;
  }

 private:
  uint32_t u16(size_t o) const {
    if (o + 2 > n_) return 0;
    return le_ ? uint32_t(p_[o]) | uint32_t(p_[o + 1]) << 8
               : uint32_t(p_[o]) << 8 | uint32_t(p_[o + 1]);
  }
  uint32_t u32(size_t o) const {
    return le_ ? u16(o) | u16(o + 2) << 16 : u16(o) << 16 | u16(o + 2);
  }
  const uint8_t* p_;
  size_t n_;
  bool le_ = true, ok_ = false;
};

// The file's EXIF TIFF block (a JPEG's APP1 "Exif" segment or a PNG's eXIf chunk); size 0 when
// there is none.
std::pair<const uint8_t*, size_t> exif_block(const std::vector<uint8_t>& b) {
  const size_t n = b.size();
  if (n >= 4 && b[0] == 0xFF && b[1] == 0xD8) {  // JPEG: walk the marker segments
    size_t i = 2;
    while (i + 4 <= n && b[i] == 0xFF) {
      const uint8_t marker = b[i + 1];
      if (marker == 0xD9 || marker == 0xDA) break;  // end of image / start of scan
      const size_t len = size_t(b[i + 2]) << 8 | b[i + 3];
      if (len < 2 || i + 2 + len > n) break;
      if (marker == 0xE1 && len >= 8 && std::memcmp(&b[i + 4], "Exif\0\0", 6) == 0)
        return {&b[i + 10], len - 8};
      i += 2 + len;
    }
    return {nullptr, 0};
  }
  static const uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (n >= 8 && std::memcmp(b.data(), png_sig, 8) == 0) {  // PNG: look for the eXIf chunk
    size_t i = 8;
    while (i + 12 <= n) {
      const size_t len =
          size_t(b[i]) << 24 | size_t(b[i + 1]) << 16 | size_t(b[i + 2]) << 8 | b[i + 3];
      if (i + 12 + len > n) break;
      if (std::memcmp(&b[i + 4], "eXIf", 4) == 0) return {&b[i + 8], len};
      if (std::memcmp(&b[i + 4], "IEND", 4) == 0) break;
      i += 12 + len;
    }
  }
  return {nullptr, 0};
}

}  // namespace

int exif_orientation(const std::vector<uint8_t>& b) {
  const auto [p, n] = exif_block(b);
  if (n == 0) return 1;
  const Tiff t(p, n);
  uint32_t v = 0;
  if (!t.find(t.first_ifd(), 0x0112, &v)) return 1;
  return v >= 1 && v <= 8 ? int(v) : 1;
}

double exif_focal_35mm(const std::vector<uint8_t>& b) {
  const auto [p, n] = exif_block(b);
  if (n == 0) return 0;
  const Tiff t(p, n);
  uint32_t exif_ifd = 0, f = 0;
  if (!t.find(t.first_ifd(), 0x8769, &exif_ifd)) return 0;  // ExifIFDPointer
  if (!t.find(exif_ifd, 0xA405, &f)) return 0;              // FocalLengthIn35mmFilm
  return f > 0 && f < 10000 ? double(f) : 0.0;
}

double focal_px_from_35mm(double focal_35mm, int width, int height) {
  if (!(focal_35mm > 0) || width <= 0 || height <= 0) return 0;
  return focal_35mm * std::hypot(double(width), double(height)) / std::hypot(36.0, 24.0);
}

namespace {

cv::Mat decode(const std::vector<uint8_t>& bytes, const std::string& path) {
  return decode_image_file(bytes, path);
}

// OpenCV Mat (8/16-bit, 1-4 channels, BGR order) -> float Image in RGB(A) order.
Image to_image(cv::Mat m, const std::string& path, int& bits) {
  double scale;
  if (m.depth() == CV_8U) {
    scale = 1.0 / 255.0;
    bits = 8;
  } else if (m.depth() == CV_16U) {
    scale = 1.0 / 65535.0;
    bits = 16;
  } else {
    throw Error("cannot read image " + path +
                ": unsupported pixel depth (8 or 16 bits per channel)");
  }
  const int c = m.channels();
  if (c == 3) cv::cvtColor(m, m, cv::COLOR_BGR2RGB);
  if (c == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2RGBA);
  if (c == 2) throw Error("cannot read image " + path + ": two-channel images are not supported");
  cv::Mat f;
  m.convertTo(f, CV_MAKETYPE(CV_32F, c), scale);
  Image img(f.cols, f.rows, c);
  for (int y = 0; y < f.rows; ++y) std::copy_n(f.ptr<float>(y), size_t(f.cols) * c, img.row(y));
  return img;
}

Image channel(const Image& img, int c) {
  Image out(img.width, img.height, 1);
  for (size_t i = 0; i < img.pixel_count(); ++i) out.data[i] = img.data[i * img.channels + c];
  return out;
}

}  // namespace

Image apply_exif_orientation(const Image& img, int o) {
  if (o <= 1 || o > 8) return img;
  cv::Mat src(img.height, img.width, CV_32FC(img.channels), const_cast<float*>(img.data.data()));
  cv::Mat dst;
  switch (o) {
    case 2:  // mirrored horizontally
      cv::flip(src, dst, 1);
      break;
    case 3:  // rotated 180
      cv::rotate(src, dst, cv::ROTATE_180);
      break;
    case 4:  // mirrored vertically
      cv::flip(src, dst, 0);
      break;
    case 5:  // mirrored about the main diagonal
      cv::transpose(src, dst);
      break;
    case 6:  // stored rotated 90 counter-clockwise: turn it clockwise
      cv::rotate(src, dst, cv::ROTATE_90_CLOCKWISE);
      break;
    case 7: {  // mirrored about the anti-diagonal
      cv::Mat t;
      cv::transpose(src, t);
      cv::rotate(t, dst, cv::ROTATE_180);
      break;
    }
    case 8:  // stored rotated 90 clockwise: turn it counter-clockwise
      cv::rotate(src, dst, cv::ROTATE_90_COUNTERCLOCKWISE);
      break;
  }
  Image out(dst.cols, dst.rows, img.channels);
  for (int y = 0; y < dst.rows; ++y)
    std::copy_n(dst.ptr<float>(y), size_t(dst.cols) * img.channels, out.row(y));
  return out;
}

Photo load_photo(const std::string& path, int max_size) {
  if (max_size < 0) throw Error("perceive: the maximum image size must be positive");
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  if (bytes.empty()) throw Error("cannot read image " + path + ": the file is empty");
  Photo p;
  const cv::Mat m = decode(bytes, path);
  p.source_channels = m.channels();
  Image img = to_image(m, path, p.bit_depth);
  p.exif_orientation = exif_orientation(bytes);
  p.focal_35mm = exif_focal_35mm(bytes);
  img = apply_exif_orientation(img, p.exif_orientation);
  p.source_width = img.width;
  p.source_height = img.height;
  int w = img.width, h = img.height;
  const int longer = std::max(w, h);
  if (max_size > 0 && longer > max_size) {
    const double s = double(max_size) / longer;
    w = std::clamp(int(std::lround(img.width * s)), 1, max_size);
    h = std::clamp(int(std::lround(img.height * s)), 1, max_size);
    img = resize_area(img, w, h);
  }
  p.scale_x = double(w) / p.source_width;
  p.scale_y = double(h) / p.source_height;
  if (img.channels == 1) {
    p.rgb = Image(w, h, 3);
    for (size_t i = 0; i < img.pixel_count(); ++i)
      for (int c = 0; c < 3; ++c) p.rgb.data[i * 3 + c] = img.data[i];
  } else if (img.channels == 3) {
    p.rgb = std::move(img);
  } else {
    p.rgb = Image(w, h, 3);
    for (size_t i = 0; i < img.pixel_count(); ++i)
      for (int c = 0; c < 3; ++c) p.rgb.data[i * 3 + c] = img.data[i * 4 + c];
    p.alpha = channel(img, 3);
  }
  return p;
}

Image threshold_mask(const Image& img, float threshold) {
  Image out(img.width, img.height, 1);
  for (size_t i = 0; i < img.pixel_count(); ++i)
    out.data[i] = img.data[i * img.channels] >= threshold ? 1.0f : 0.0f;
  return out;
}

Image load_mask(const std::string& path, int source_width, int source_height, int width,
                int height) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  if (bytes.empty()) throw Error("cannot read mask " + path + ": the file is empty");
  int bits = 8;
  Image img = to_image(decode(bytes, path), path, bits);
  img = apply_exif_orientation(img, exif_orientation(bytes));
  if (img.width != source_width || img.height != source_height)
    throw Error("mask " + path + " is " + std::to_string(img.width) + "x" +
                std::to_string(img.height) + " but the photo is " + std::to_string(source_width) +
                "x" + std::to_string(source_height) + " (after its EXIF orientation)");
  Image grey;
  if (img.channels == 4) {
    grey = channel(img, 3);
    if (std::all_of(grey.data.begin(), grey.data.end(), [](float a) { return a >= 1.0f; }))
      grey = Image();  // an opaque alpha says nothing: use the colour
  }
  if (grey.empty()) {
    grey = Image(img.width, img.height, 1);
    for (size_t i = 0; i < img.pixel_count(); ++i) {
      if (img.channels == 1) {
        grey.data[i] = img.data[i];
      } else {
        const float* px = &img.data[i * img.channels];
        grey.data[i] = 0.299f * px[0] + 0.587f * px[1] + 0.114f * px[2];
      }
    }
  }
  return threshold_mask(resize_area(grey, width, height));
}

}  // namespace ks

#include "io/image_io.hpp"

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/image_decode.hpp"

namespace ks {

Image read_image(const std::string& path, int channels) {
  if (!std::filesystem::exists(path)) throw Error("cannot open image " + path + ": no such file");
  cv::Mat m = decode_image_file(read_file_bytes(path), path);
  int c = m.channels();
  if (c == 3) cv::cvtColor(m, m, cv::COLOR_BGR2RGB);
  if (c == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2RGBA);
  double scale = 1.0;
  switch (m.depth()) {
    case CV_8U:
      scale = 1.0 / 255.0;
      break;
    case CV_16U:
      scale = 1.0 / 65535.0;
      break;
    case CV_32F:
      scale = 1.0;
      break;
    default:
      throw Error("cannot read image " + path + ": unsupported pixel depth");
  }
  cv::Mat f;
  m.convertTo(f, CV_MAKETYPE(CV_32F, c), scale);
  if (channels == 1 && c != 1) {
    cv::cvtColor(f, f, c == 3 ? cv::COLOR_RGB2GRAY : cv::COLOR_RGBA2GRAY);
    c = 1;
  } else if (channels == 3 && c == 1) {
    cv::cvtColor(f, f, cv::COLOR_GRAY2RGB);
    c = 3;
  } else if (channels == 3 && c == 4) {
    cv::cvtColor(f, f, cv::COLOR_RGBA2RGB);
    c = 3;
  }
  Image img(f.cols, f.rows, c);
  for (int y = 0; y < f.rows; ++y) std::copy_n(f.ptr<float>(y), size_t(f.cols) * c, img.row(y));
  return img;
}

Image resize_area(const Image& in, int w, int h) {
  if (in.width == w && in.height == h) return in;
  cv::Mat src(in.height, in.width, CV_32FC(in.channels), const_cast<float*>(in.data.data()));
  Image out(w, h, in.channels);
  cv::Mat dst(h, w, CV_32FC(in.channels), out.data.data());
  cv::resize(src, dst, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  return out;
}

namespace {

// `img` as an OpenCV matrix of 8 or 16 bits in OpenCV's channel order (BGR, BGRA).
cv::Mat to_png_mat(const Image& img, int bits) {
  if (bits != 8 && bits != 16) throw Error("PNG bit depth must be 8 or 16");
  if (img.channels != 1 && img.channels != 3 && img.channels != 4)
    throw Error("PNG needs 1, 3 or 4 channels");
  const int c = img.channels;
  cv::Mat f(img.height, img.width, CV_MAKETYPE(CV_32F, c), const_cast<float*>(img.data.data()));
  cv::Mat out;
  const double scale = bits == 8 ? 255.0 : 65535.0;
  f.convertTo(out, CV_MAKETYPE(bits == 8 ? CV_8U : CV_16U, c), scale);  // saturating
  if (c == 3) cv::cvtColor(out, out, cv::COLOR_RGB2BGR);
  if (c == 4) cv::cvtColor(out, out, cv::COLOR_RGBA2BGRA);
  return out;
}

}  // namespace

std::vector<uint8_t> encode_png(const Image& img) {
  if (img.empty()) throw Error("cannot encode an empty image as PNG");
  const cv::Mat m = to_png_mat(img, 8);
  std::vector<uint8_t> bytes;
  if (!cv::imencode(".png", m, bytes)) throw Error("cannot encode a PNG");
  return bytes;
}

void write_png(const std::string& path, const Image& img, int bits) {
  const cv::Mat out = to_png_mat(img, bits);
  write_via_temp(path, [&](const std::string& tmp) {
    if (!cv::imwrite(tmp, out)) throw Error("cannot write PNG " + path);
  });
}

}  // namespace ks

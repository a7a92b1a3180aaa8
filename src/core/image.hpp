#pragma once
// A float image, interleaved channels, row-major, values nominally in [0, 1].
#include <cstddef>
#include <vector>

namespace ks {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<float> data;  // size = width * height * channels

  Image() = default;
  Image(int w, int h, int c, float fill = 0.0f)
      : width(w), height(h), channels(c), data(size_t(w) * h * c, fill) {}

  bool empty() const { return data.empty(); }
  size_t pixel_count() const { return size_t(width) * height; }
  float& at(int x, int y, int c) { return data[(size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return data[(size_t(y) * width + x) * channels + c]; }
  float* row(int y) { return data.data() + size_t(y) * width * channels; }
  const float* row(int y) const { return data.data() + size_t(y) * width * channels; }
};

}  // namespace ks

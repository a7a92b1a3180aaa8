#pragma once
// PNG (and any format OpenCV reads) to/from ks::Image. Channels are RGB(A) order, values in [0,1].
#include <cstdint>
#include <string>
#include <vector>

#include "core/image.hpp"

namespace ks {

// Reads an image; `channels` = 0 keeps the file's channels (1, 3 or 4), 1 gives grey, 3 gives RGB.
// Throws ks::Error for a missing or unreadable file.
Image read_image(const std::string& path, int channels = 0);
// Resamples to w x h with area averaging (OpenCV INTER_AREA); returns the input if the size
// matches.
Image resize_area(const Image& in, int w, int h);
// Writes a PNG with 8 or 16 bits per channel (1, 3 or 4 channels), atomically. Values clamped.
void write_png(const std::string& path, const Image& img, int bits = 8);
// The bytes of an 8-bit PNG of `img` (1, 3 or 4 channels, values clamped), e.g. to embed in a file.
std::vector<uint8_t> encode_png(const Image& img);

}  // namespace ks

#pragma once
// Decoding image files' bytes (PNG, JPEG, anything OpenCV reads) for read_image and perceive's
// load_photo: the size in the header is checked before anything is decoded, and the decoders'
// own messages (libpng's, libjpeg's, OpenCV's warnings) are kept off stderr, so that a bad file
// gives the one `error: ...` line and nothing else.
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace ks {

// The most pixels an image file may have (2^27, e.g. 13000 x 10000): a larger one is refused
// before it is decoded (a few kilobytes of JPEG can claim gigabytes of pixels).
inline constexpr int64_t kMaxImagePixels = int64_t(1) << 27;

// Width and height from a PNG's IHDR or a JPEG's SOF segment; false for other formats or when
// the header is unreadable (the decoder then decides).
bool image_header_size(const std::vector<uint8_t>& bytes, int64_t& width, int64_t& height);

// For a PNG, what is wrong with its chunk layout, empty when nothing is: every chunk's length must
// fit in the file (libpng allocates a chunk's claimed length before reading it, so 160 bytes that
// claim a 1 GB chunk cost 1 GB), and the chunks must reach IEND. Empty for other formats.
std::string png_chunk_problem(const std::vector<uint8_t>& bytes);

// cv::imdecode(bytes, IMREAD_UNCHANGED) with the checks above (header size, PNG chunks); throws
// ks::Error naming `path`
// ("cannot read image PATH: ...") for an empty, oversized or undecodable file.
cv::Mat decode_image_file(const std::vector<uint8_t>& bytes, const std::string& path);

}  // namespace ks

// io/image_decode: a well-formed PNG and JPEG decode; sizes and PNG chunk layouts that would make
// the decoders allocate far more than the file holds are refused before decoding, naming the file.
#include "io/image_decode.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "core/error.hpp"

namespace ks {
namespace {

std::vector<uint8_t> encode(const std::string& ext) {
  cv::Mat img(6, 8, CV_8UC3, cv::Scalar(10, 200, 30));
  std::vector<uint8_t> out;
  EXPECT_TRUE(cv::imencode(ext, img, out));
  return out;
}

void put_be32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int k = 0; k < 4; ++k) b[at + k] = uint8_t(v >> (24 - 8 * k));
}

std::string refusal(const std::vector<uint8_t>& bytes) {
  try {
    decode_image_file(bytes, "photo.png");
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

TEST(ImageDecode, WellFormedPngAndJpegDecode) {
  for (const std::string ext : {".png", ".jpg"}) {
    const std::vector<uint8_t> bytes = encode(ext);
    EXPECT_EQ(png_chunk_problem(bytes), "") << ext;
    int64_t w = 0, h = 0;
    ASSERT_TRUE(image_header_size(bytes, w, h)) << ext;
    EXPECT_EQ(w, 8);
    EXPECT_EQ(h, 6);
    const cv::Mat m = decode_image_file(bytes, "photo" + ext);
    EXPECT_EQ(m.cols, 8);
    EXPECT_EQ(m.rows, 6);
  }
}

TEST(ImageDecode, HeaderClaimingTooManyPixelsIsRefused) {
  std::vector<uint8_t> bytes = encode(".png");
  put_be32(bytes, 16, 60000);  // IHDR width
  put_be32(bytes, 20, 60000);  // IHDR height
  const std::string msg = refusal(bytes);
  EXPECT_NE(msg.find("photo.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("60000 x 60000"), std::string::npos) << msg;
}

TEST(ImageDecode, PngChunkLongerThanTheFileIsRefused) {
  std::vector<uint8_t> bytes = encode(".png");
  // The chunk after IHDR (8 signature + 25 IHDR bytes) claims a gigabyte.
  put_be32(bytes, 33, 0x40000000u);
  const std::string problem = png_chunk_problem(bytes);
  EXPECT_NE(problem.find("claims 1073741824 bytes"), std::string::npos) << problem;
  const std::string msg = refusal(bytes);
  EXPECT_NE(msg.find("photo.png"), std::string::npos) << msg;
  EXPECT_NE(msg.find("truncated or damaged"), std::string::npos) << msg;
}

TEST(ImageDecode, PngCutBeforeIendIsRefused) {
  std::vector<uint8_t> bytes = encode(".png");
  bytes.resize(bytes.size() - 12);  // drop IEND
  EXPECT_NE(png_chunk_problem(bytes).find("no IEND"), std::string::npos);
  bytes.resize(bytes.size() - 3);  // and cut into the last chunk
  EXPECT_NE(png_chunk_problem(bytes).find("truncated or damaged"), std::string::npos);
  EXPECT_NE(refusal(bytes), "");
}

TEST(ImageDecode, JpegSizeIsFoundAfterExtraneousBytes) {
  // libjpeg skips bytes that are not a marker (with a warning) and reads the frame header after
  // them: so must the size check, or a JPEG claiming a gigapixel slips past it.
  std::vector<uint8_t> bytes = encode(".jpg");
  size_t sof = 2;
  while (sof + 1 < bytes.size() && !(bytes[sof] == 0xFF && bytes[sof + 1] == 0xC0)) ++sof;
  ASSERT_LT(sof + 9, bytes.size());
  bytes[sof + 5] = 0x84, bytes[sof + 6] = 0x06;  // height 33798
  bytes[sof + 7] = 0x7A, bytes[sof + 8] = 0x07;  // width 31239
  bytes.insert(bytes.begin() + long(sof), {'c', 'c', 'c', 'c'});
  int64_t w = 0, h = 0;
  ASSERT_TRUE(image_header_size(bytes, w, h));
  EXPECT_EQ(w, 31239);
  EXPECT_EQ(h, 33798);
  EXPECT_NE(refusal(bytes).find("31239 x 33798"), std::string::npos);
}

TEST(ImageDecode, EmptyFileIsRefused) {
  EXPECT_NE(refusal({}).find("empty"), std::string::npos);
}

}  // namespace
}  // namespace ks

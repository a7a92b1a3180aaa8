#include "perceive/photo.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/image_io.hpp"
#include "perceive_util.hpp"

namespace ks {

namespace {

// A W x H image of 4 x 2 blocks of distinct colours (so every flip and turn is told apart).
constexpr int kW = 64, kH = 32, kBlock = 16;
std::array<uint8_t, 3> block_colour(int bx, int by) {
  return {uint8_t(40 + 60 * bx), uint8_t(by == 0 ? 30 : 220), uint8_t(bx % 2 == 0 ? 200 : 50)};
}
cv::Mat blocks_bgr() {
  cv::Mat m(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const auto c = block_colour(x / kBlock, y / kBlock);
      m.at<cv::Vec3b>(y, x) = {c[2], c[1], c[0]};
    }
  return m;
}

// A JPEG of blocks_bgr() at `quality` with an EXIF APP1 segment holding `tiff` (built by hand:
// OpenCV does not write EXIF), right after SOI.
std::vector<uint8_t> jpeg_with_exif(int quality, const std::vector<uint8_t>& tiff) {
  std::vector<uint8_t> jpg;
  cv::imencode(".jpg", blocks_bgr(), jpg, {cv::IMWRITE_JPEG_QUALITY, quality});
  std::vector<uint8_t> app1 = {0xFF, 0xE1, 0, 0, 'E', 'x', 'i', 'f', 0, 0};
  app1.insert(app1.end(), tiff.begin(), tiff.end());
  const size_t len = app1.size() - 2;
  app1[2] = uint8_t(len >> 8);
  app1[3] = uint8_t(len & 0xFF);
  std::vector<uint8_t> out;  // SOI, the APP1 segment, the rest of the JPEG
  out.reserve(jpg.size() + app1.size());
  for (size_t i = 0; i < jpg.size(); ++i) {
    if (i == 2)
      for (uint8_t b : app1) out.push_back(b);
    out.push_back(jpg[i]);
  }
  return out;
}

// A JPEG of blocks_bgr() with an EXIF APP1 segment carrying `orientation`. Big-endian ("MM") TIFF
// with one IFD entry.
std::vector<uint8_t> jpeg_with_orientation(int orientation) {
  const std::vector<uint8_t> tiff = {'M',  'M',
                                     0,    42,
                                     0,    0,
                                     0,    8,  // header, IFD at 8
                                     0,    1,  // one entry
                                     0x01, 0x12,
                                     0,    3,
                                     0,    0,
                                     0,    1,  // Orientation, SHORT, 1
                                     0,    uint8_t(orientation),
                                     0,    0,  // value
                                     0,    0,
                                     0,    0};  // no next IFD
  return jpeg_with_exif(98, tiff);
}

// A JPEG of blocks_bgr() whose EXIF holds IFD0 (orientation 1, the Exif IFD pointer) and an Exif
// IFD with FocalLengthIn35mmFilm = focal, little-endian ("II"); `exif_ifd_at` overrides the
// pointer (to test one that points outside the block).
std::vector<uint8_t> jpeg_with_focal(int focal, uint32_t exif_ifd_at = 38) {
  std::vector<uint8_t> t = {'I',
                            'I',
                            42,
                            0,
                            8,
                            0,
                            0,
                            0,  // header, IFD0 at 8
                            2,
                            0,  // two entries
                            0x12,
                            0x01,
                            3,
                            0,
                            1,
                            0,
                            0,
                            0,
                            1,
                            0,
                            0,
                            0,  // Orientation 1
                            0x69,
                            0x87,
                            4,
                            0,
                            1,
                            0,
                            0,
                            0,  // ExifIFDPointer, LONG
                            uint8_t(exif_ifd_at),
                            uint8_t(exif_ifd_at >> 8),
                            uint8_t(exif_ifd_at >> 16),
                            uint8_t(exif_ifd_at >> 24),
                            0,
                            0,
                            0,
                            0,  // no next IFD; the Exif IFD at 38:
                            1,
                            0,  // one entry
                            0x05,
                            0xA4,
                            3,
                            0,
                            1,
                            0,
                            0,
                            0,
                            uint8_t(focal),
                            uint8_t(focal >> 8),
                            0,
                            0,  // FocalLengthIn35mmFilm, SHORT
                            0,
                            0,
                            0,
                            0};
  return jpeg_with_exif(90, t);
}

// Where displayed pixel (x, y) comes from in the stored image, per the EXIF specification.
std::array<int, 2> stored_pixel(int o, int x, int y) {
  switch (o) {
    case 2:
      return {kW - 1 - x, y};
    case 3:
      return {kW - 1 - x, kH - 1 - y};
    case 4:
      return {x, kH - 1 - y};
    case 5:
      return {y, x};
    case 6:
      return {y, kH - 1 - x};
    case 7:
      return {kW - 1 - y, kH - 1 - x};
    case 8:
      return {kW - 1 - y, x};
    default:
      return {x, y};
  }
}

}  // namespace

TEST(Photo, JpegExifOrientationIsHonoured) {
  test::ScratchDir dir("photo_exif");
  for (int o = 1; o <= 8; ++o) {
    SCOPED_TRACE("orientation " + std::to_string(o));
    const auto bytes = jpeg_with_orientation(o);
    EXPECT_EQ(exif_orientation(bytes), o);
    const std::string path = dir / (std::to_string(o) + ".jpg");
    write_file_atomic(path, bytes.data(), bytes.size());
    const Photo p = load_photo(path);
    EXPECT_EQ(p.exif_orientation, o);
    const bool turned = o >= 5;
    ASSERT_EQ(p.rgb.width, turned ? kH : kW);
    ASSERT_EQ(p.rgb.height, turned ? kW : kH);
    EXPECT_EQ(p.source_width, p.rgb.width);
    EXPECT_TRUE(p.alpha.empty());
    // Block centres (away from JPEG's ringing at block edges) have their block's colour.
    for (int by = 0; by < 2; ++by)
      for (int bx = 0; bx < 4; ++bx) {
        const int sx = bx * kBlock + kBlock / 2, sy = by * kBlock + kBlock / 2;
        // The displayed pixel that shows stored (sx, sy).
        int dx = -1, dy = -1;
        for (int y = 0; y < p.rgb.height && dx < 0; ++y)
          for (int x = 0; x < p.rgb.width; ++x)
            if (stored_pixel(o, x, y) == std::array<int, 2>{sx, sy}) {
              dx = x;
              dy = y;
              break;
            }
        ASSERT_GE(dx, 0);
        const auto c = block_colour(bx, by);
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_NEAR(p.rgb.at(dx, dy, ch) * 255.0f, c[size_t(ch)], 12.0) << bx << "," << by;
      }
  }
}

// EXIF FocalLengthIn35mmFilm read through the Exif IFD; the pixel focal by the diagonal; a
// pointer outside the block, a truncated block or none at all: 0.
TEST(Photo, ExifFocalLength35mm) {
  const auto bytes = jpeg_with_focal(26);
  EXPECT_EQ(exif_orientation(bytes), 1);
  EXPECT_DOUBLE_EQ(exif_focal_35mm(bytes), 26.0);
  test::ScratchDir dir("photo_focal");
  write_file_atomic(dir / "f.jpg", bytes.data(), bytes.size());
  EXPECT_DOUBLE_EQ(load_photo(dir / "f.jpg").focal_35mm, 26.0);
  // 36 x 24 mm itself: f_px = f_mm * (pixels per mm).
  EXPECT_NEAR(focal_px_from_35mm(50, 3600, 2400), 5000.0, 1e-9);
  EXPECT_NEAR(focal_px_from_35mm(26, 3024, 4032), 26 * 5040.0 / std::hypot(36.0, 24.0), 1e-9);
  EXPECT_EQ(focal_px_from_35mm(0, 100, 100), 0.0);
  EXPECT_EQ(exif_focal_35mm(jpeg_with_focal(26, 5000)), 0.0);
  EXPECT_EQ(exif_focal_35mm(jpeg_with_orientation(6)), 0.0);
  std::vector<uint8_t> cut = bytes;
  cut.resize(60);  // inside the APP1 segment: its length runs past the end
  EXPECT_EQ(exif_focal_35mm(cut), 0.0);
  EXPECT_EQ(exif_focal_35mm({}), 0.0);
}

TEST(Photo, NoExifMeansUpright) {
  std::vector<uint8_t> jpg;
  cv::imencode(".jpg", blocks_bgr(), jpg);
  EXPECT_EQ(exif_orientation(jpg), 1);
  EXPECT_EQ(exif_orientation({1, 2, 3}), 1);
  // A truncated APP1 does not crash the reader.
  auto b = jpeg_with_orientation(6);
  b.resize(16);
  EXPECT_EQ(exif_orientation(b), 1);
}

TEST(Photo, RgbaAlphaIsKeptApartAndDownscaleIsAreaAveraged) {
  test::ScratchDir dir("photo_rgba");
  // 300 x 200 RGBA: left half opaque red, right half transparent; a 2-pixel checker in green.
  Image img(300, 200, 4);
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 300; ++x) {
      img.at(x, y, 0) = 1.0f;
      img.at(x, y, 1) = ((x / 2 + y / 2) % 2) ? 1.0f : 0.0f;
      img.at(x, y, 2) = 0.0f;
      img.at(x, y, 3) = x < 150 ? 1.0f : 0.0f;
    }
  write_png(dir / "rgba.png", img);
  const Photo full = load_photo(dir / "rgba.png");
  EXPECT_EQ(full.source_channels, 4);
  ASSERT_EQ(full.rgb.channels, 3);
  ASSERT_FALSE(full.alpha.empty());
  EXPECT_FLOAT_EQ(full.alpha.at(10, 10, 0), 1.0f);
  EXPECT_FLOAT_EQ(full.alpha.at(200, 10, 0), 0.0f);
  EXPECT_FLOAT_EQ(full.rgb.at(3, 1, 1), img.at(3, 1, 1));

  const Photo p = load_photo(dir / "rgba.png", 100);  // long side 300 -> 100
  EXPECT_EQ(p.rgb.width, 100);
  EXPECT_EQ(p.rgb.height, 67);  // 200 / 3 = 66.67, rounded
  EXPECT_EQ(p.source_width, 300);
  EXPECT_EQ(p.source_height, 200);
  EXPECT_DOUBLE_EQ(p.scale_x, 100.0 / 300.0);
  EXPECT_DOUBLE_EQ(p.scale_y, 67.0 / 200.0);
  // The checker averages to grey (area interpolation, not point sampling), red stays red.
  EXPECT_NEAR(p.rgb.at(20, 30, 1), 0.5f, 0.12f);
  EXPECT_NEAR(p.rgb.at(20, 30, 0), 1.0f, 1e-5f);
  EXPECT_NEAR(p.alpha.at(10, 30, 0), 1.0f, 1e-5f);
  EXPECT_NEAR(p.alpha.at(90, 30, 0), 0.0f, 1e-5f);
  // Smaller than the limit: untouched.
  const Photo same = load_photo(dir / "rgba.png", 1024);
  EXPECT_EQ(same.rgb.width, 300);
  EXPECT_DOUBLE_EQ(same.scale_x, 1.0);
}

TEST(Photo, MasksMustMatchThePhoto) {
  test::ScratchDir dir("photo_mask");
  Image m(60, 40, 1, 0.0f);
  for (int y = 10; y < 30; ++y)
    for (int x = 20; x < 40; ++x) m.at(x, y, 0) = 1.0f;
  write_png(dir / "mask.png", m);
  const Image half = load_mask(dir / "mask.png", 60, 40, 30, 20);
  EXPECT_EQ(half.width, 30);
  EXPECT_FLOAT_EQ(half.at(15, 10, 0), 1.0f);
  EXPECT_FLOAT_EQ(half.at(2, 2, 0), 0.0f);
  try {
    load_mask(dir / "mask.png", 80, 40, 80, 40);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("60x40 but the photo is 80x40"), std::string::npos);
  }
  // An RGBA mask: its alpha counts, not its colour.
  Image rgba(60, 40, 4, 1.0f);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 60; ++x) rgba.at(x, y, 3) = x < 30 ? 1.0f : 0.0f;
  write_png(dir / "alpha_mask.png", rgba);
  const Image am = load_mask(dir / "alpha_mask.png", 60, 40, 60, 40);
  EXPECT_FLOAT_EQ(am.at(5, 5, 0), 1.0f);
  EXPECT_FLOAT_EQ(am.at(50, 5, 0), 0.0f);
}

TEST(Photo, UnreadableFilesAreClearErrors) {
  test::ScratchDir dir("photo_bad");
  auto message = [](const std::string& path) {
    try {
      load_photo(path);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message(dir / "none.png").find("no such file"), std::string::npos);
  write_text_atomic(dir / "text.png", "this is not an image");
  EXPECT_NE(message(dir / "text.png").find("text.png"), std::string::npos);
  write_text_atomic(dir / "empty.jpg", "");
  EXPECT_NE(message(dir / "empty.jpg").find("empty"), std::string::npos);
}

}  // namespace ks

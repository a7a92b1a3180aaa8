#pragma once
// Photos for `perceive`: PNG or JPEG (anything OpenCV decodes), 8 or 16 bits, grey, RGB or RGBA,
// turned upright by its EXIF orientation and downscaled (area averaging) so that its longer side
// is at most a given size.
#include <cstdint>
#include <string>
#include <vector>

#include "core/image.hpp"

namespace ks {

struct Photo {
  Image rgb;             // 3 channels in [0, 1], upright, downscaled
  Image alpha;           // 1 channel, same size; empty when the file has no alpha channel
  int source_width = 0;  // upright (after EXIF orientation), before downscaling
  int source_height = 0;
  int source_channels = 0;   // as stored: 1, 2 (grey + alpha), 3 or 4
  int bit_depth = 8;         // 8 or 16
  int exif_orientation = 1;  // 1..8 as found (1 when none)
  double focal_35mm = 0;     // EXIF FocalLengthIn35mmFilm, mm (0 when none)
  double scale_x = 1.0;      // image pixels per source pixel
  double scale_y = 1.0;
};

// Loads and orients a photo, then downscales it so that max(width, height) <= max_size (0: no
// limit); the new size is the source size times max_size / longer side, rounded. Throws ks::Error
// naming the file: missing, not an image, unsupported depth.
Photo load_photo(const std::string& path, int max_size = 0);

// The EXIF orientation (1..8) in a JPEG's APP1 segment or a PNG's eXIf chunk; 1 when there is none
// or it is unreadable.
int exif_orientation(const std::vector<uint8_t>& file_bytes);

// EXIF FocalLengthIn35mmFilm (mm) from the Exif IFD of a JPEG's APP1 segment or a PNG's eXIf
// chunk; 0 when there is none or it is unreadable.
double exif_focal_35mm(const std::vector<uint8_t>& file_bytes);

// The focal length in pixels of a width x height image whose 35 mm equivalent focal length is
// `focal_35mm`: the equivalence is by the diagonal (CIPA DC-008), f_px = f35 * diag_px / 43.27 mm.
// 0 when focal_35mm is not positive.
double focal_px_from_35mm(double focal_35mm, int width, int height);

// Applies EXIF orientation `o` (1..8) to an interleaved image: the result is what a viewer shows.
Image apply_exif_orientation(const Image& img, int o);

// A binary person mask (1 channel, 0 or 1) from an image file: its alpha channel when it has one
// that is not everywhere opaque, else its grey level; >= 0.5 is the person. It must have the
// photo's upright source size; it is resampled to (width, height) by area averaging first.
Image load_mask(const std::string& path, int source_width, int source_height, int width,
                int height);

// 1 where `img` (1 channel) >= threshold, else 0.
Image threshold_mask(const Image& img, float threshold = 0.5f);

}  // namespace ks

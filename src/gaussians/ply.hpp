#pragma once
// The standard 3DGS .ply format: binary little-endian, one "vertex" element, every property
// float, in the original order
//   x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 f_rest_0..f_rest_{M-1} opacity scale_0..2 rot_0..3
// with raw (pre-activation) values: log-scales, opacity logit, un-normalised quaternion (w,x,y,z).
// f_rest is channel-major (all R coefficients 1..K-1, then G, then B); M = 3 (K - 1) is 0, 9, 24
// or 45 for SH degree 0..3. Reading accepts extra float properties after the standard ones
// (returned in `extra` when asked for) and ignores elements after "vertex".
#include <string>
#include <vector>

#include "gaussians/gaussians.hpp"

namespace ks {

struct PlyExtra {
  std::vector<std::string> names;  // extra property names, in file order
  std::vector<float> values;       // N * names.size(), Gaussian-major
};

// Throws ks::Error naming the file and the problem (ASCII / big-endian format, missing or
// misordered properties, non-float types, unsupported f_rest count, truncated data).
Gaussians read_ply(const std::string& path, PlyExtra* extra = nullptr);
// Writes atomically (temporary file + rename). `extra` (optional) is appended per Gaussian.
void write_ply(const std::string& path, const Gaussians& g, const PlyExtra* extra = nullptr);

}  // namespace ks

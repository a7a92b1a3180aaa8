#pragma once
// A reproducible avatar-like Gaussian cloud for benchmarks and demos: Gaussians on the surface of
// a union of ellipsoids and capsules shaped like a standing person about 1.7 m tall (world Y up,
// feet at y = 0, facing +Z), scales of a few mm to ~1.5 cm, opacities mostly high, SH degree 3.
#include <cstddef>

#include "core/camera.hpp"
#include "gaussians/gaussians.hpp"

namespace ks {

Gaussians make_avatar_cloud(size_t n, unsigned seed = 1);
// A camera in front of the person framing it in a portrait image (the person fills the height).
Camera avatar_camera(int width, int height);

}  // namespace ks

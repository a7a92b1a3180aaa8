// LineAlignedVector: storage on a 64-byte boundary at every size and after growth, and the
// rasterizer's record arrays (64 bytes a record) in whole cache lines after a forward pass.
#include "core/aligned.hpp"

#include <gtest/gtest.h>

#include <cstdint>

#include "raster/raster_scene.hpp"
#include "raster/rasterizer.hpp"

namespace ks {
namespace {

bool on_line(const void* p) {
  return reinterpret_cast<std::uintptr_t>(p) % 64 == 0;
}

TEST(AlignedVector, StartsOnACacheLineAtEverySize) {
  for (size_t n : {1u, 3u, 17u, 1000u, 300000u}) {
    LineAlignedVector<float> v(n, 1.f);
    EXPECT_TRUE(on_line(v.data())) << n;
    v.resize(3 * n + 5);  // reallocates
    EXPECT_TRUE(on_line(v.data())) << n;
    EXPECT_EQ(v[0], 1.f);
    LineAlignedVector<float> w = v;  // copies allocate too
    EXPECT_TRUE(on_line(w.data())) << n;
    EXPECT_EQ(w, v);
  }
}

TEST(AlignedVector, RenderRecordsLieInWholeLines) {
  test::SceneOptions o;
  o.n = 200;
  const Gaussians g = test::random_scene(o, 3);
  const Camera cam = test::test_camera(64, 48);
  for (bool image_only : {false, true}) {
    RasterSettings s;
    s.image_only = image_only;
    RasterResult r;
    rasterize_forward(g, cam, s, r);
    ASSERT_FALSE(r.packed.empty());
    EXPECT_TRUE(on_line(r.packed.data())) << image_only;
    EXPECT_TRUE(on_line(r.records.data())) << image_only;
  }
}

}  // namespace
}  // namespace ks

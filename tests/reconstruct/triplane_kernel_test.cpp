// The triplane's AVX2+FMA loops (reconstruct/triplane_kernels.hpp) against its portable loops:
// the same features and plane gradients up to float rounding, the portable path for channel
// counts that are not a multiple of 8, and results that do not depend on the thread count.
#include <gtest/gtest.h>

#include <omp.h>
#include <algorithm>
#include <cmath>
#include <random>
#include <tuple>
#include <vector>

#include "reconstruct/mlp_kernels.hpp"
#include "reconstruct/triplane.hpp"
#include "reconstruct/triplane_kernels.hpp"

namespace ks {

namespace {

namespace tk = triplane_kernels;

struct PathGuard {
  explicit PathGuard(tk::Path p) { tk::set_path(p); }
  ~PathGuard() { tk::set_path(tk::Path::kAuto); }
};

// A triplane over [-1, 1]^3 and n points, some outside the box (clamped to its border).
struct Scene {
  Triplane tp;
  std::vector<float> xs, ys, zs, dfeats;
  int n = 0;
};
Scene scene(int res, int C, int n, uint64_t seed) {
  Scene S;
  const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
  S.tp.init(res, C, lo, hi, seed, 0.5f);
  S.n = n;
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<float> u(-1.1f, 1.1f), d(-1.f, 1.f);
  for (int i = 0; i < n; ++i)
    S.xs.push_back(u(rng)), S.ys.push_back(u(rng)), S.zs.push_back(u(rng));
  S.dfeats.resize(size_t(n) * size_t(S.tp.feature_dim()));
  for (auto& v : S.dfeats) v = d(rng);
  return S;
}

struct Result {
  std::vector<float> feats, dplanes;
};
Result run(const Scene& S, tk::Path path) {
  PathGuard guard(path);
  Result r;
  r.feats.resize(S.dfeats.size());
  triplane_forward(S.tp, S.xs.data(), S.ys.data(), S.zs.data(), S.n, r.feats.data());
  r.dplanes.assign(S.tp.size(), 0.25f);  // the backward adds
  triplane_backward(S.tp, S.xs.data(), S.ys.data(), S.zs.data(), S.n, S.dfeats.data(),
                    r.dplanes.data());
  return r;
}

void expect_near(const std::vector<float>& a, const std::vector<float>& b, float tol) {
  ASSERT_EQ(a.size(), b.size());
  float worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  EXPECT_LE(worst, tol);
}

}  // namespace

TEST(TriplaneKernels, ChoosesTheAvx2LoopsOnlyForWholeVectorsOfChannels) {
  if (!mlp_kernels::cpu_has_avx2_fma()) GTEST_SKIP() << "CPU has no AVX2/FMA";
  PathGuard guard(tk::Path::kAvx2);
  EXPECT_TRUE(tk::use_avx2(32));
  EXPECT_TRUE(tk::use_avx2(8));
  EXPECT_FALSE(tk::use_avx2(12));
  tk::set_path(tk::Path::kPortable);
  EXPECT_FALSE(tk::use_avx2(32));
}

TEST(TriplaneKernels, MatchThePortableLoops) {
  if (!mlp_kernels::cpu_has_avx2_fma()) GTEST_SKIP() << "CPU has no AVX2/FMA";
  // 32 channels (the default) over many stripes; 8 over few (res 5: two stripes); 12 takes the
  // portable loops either way, so the two runs agree bit for bit.
  for (const auto& [res, C, n] : {std::tuple{64, 32, 3000}, {5, 8, 200}, {16, 12, 500}}) {
    const Scene S = scene(res, C, n, uint64_t(res * 100 + C));
    const Result a = run(S, tk::Path::kPortable), b = run(S, tk::Path::kAvx2);
    if (C % 8 == 0) {
      expect_near(a.feats, b.feats, 1e-6f);
      expect_near(a.dplanes, b.dplanes, 1e-5f);
      EXPECT_NE(a.feats, b.feats) << "res " << res << ": expected fused multiply-adds' rounding";
    } else {
      EXPECT_EQ(a.feats, b.feats);
      EXPECT_EQ(a.dplanes, b.dplanes);
    }
  }
}

TEST(TriplaneKernels, ThreadCountIndependent) {
  if (!mlp_kernels::cpu_has_avx2_fma()) GTEST_SKIP() << "CPU has no AVX2/FMA";
  const Scene S = scene(64, 32, 5000, 7);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const Result one = run(S, tk::Path::kAvx2);
  omp_set_num_threads(2);
  const Result two = run(S, tk::Path::kAvx2);
  omp_set_num_threads(saved);
  EXPECT_EQ(one.feats, two.feats);
  EXPECT_EQ(one.dplanes, two.dplanes);
}

}  // namespace ks

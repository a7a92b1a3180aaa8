#include "core/speed_probe.hpp"

#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>

// The probe runs its load on every thread and times it; its result is the load's, which the
// scalar reference computes step by step (so the timed loop did the work it claims).
TEST(SpeedProbe, EveryThreadDoesTheLoadItTimes) {
  const int64_t iterations = 1000;  // short: 0.9999^1000 = 0.905, the chains far from converged
  const ks::SpeedProbe p = ks::speed_probe(iterations, 3);
  EXPECT_EQ(p.threads, omp_get_max_threads());
  EXPECT_GT(p.ms, 0.0);
  EXPECT_TRUE(std::isfinite(p.ms));
  const double one = ks::speed_probe_reference(iterations);
  // Each of the 12 chains starts at or above 1 and stays there (its fixed point is 1).
  EXPECT_GT(one, 12.0);
  EXPECT_NEAR(p.checksum, p.threads * one, 1e-5 * p.threads * one);
}

TEST(SpeedProbe, NoRepetitionsStillMeasuresOne) {
  const ks::SpeedProbe p = ks::speed_probe(10, 0);
  EXPECT_GT(p.ms, 0.0);
  EXPECT_NEAR(p.checksum, p.threads * ks::speed_probe_reference(10), 1e-5 * p.threads * 12);
}

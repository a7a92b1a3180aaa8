// BlazePose's heels and foot indices as BODY_25's heels and big toes (perceive/perceive.hpp's
// body25_add_feet): taken where visible and where BlazePose's ankle agrees with the keypoints'.
#include <gtest/gtest.h>

#include "body/keypoints.hpp"
#include "perceive/perceive.hpp"

namespace ks {

namespace {

// 33 landmarks, all at (0, 0) unseen, but for the feet: left ankle (100, 500), heel (95, 520), foot
// index (130, 525); right ankle (60, 500), heel (55, 520), foot index (30, 525).
std::vector<std::array<double, 4>> landmarks(double vis) {
  std::vector<std::array<double, 4>> bp(33, {0, 0, 0, 0});
  bp[27] = {100, 500, 0.9, 0.9};
  bp[29] = {95, 520, vis, 0.9};
  bp[31] = {130, 525, vis, 0.9};
  bp[28] = {60, 500, 0.9, 0.9};
  bp[30] = {55, 520, vis, 0.9};
  bp[32] = {30, 525, vis, 0.9};
  return bp;
}

Body25 ankles(double lx, double rx) {
  Body25 b{};
  b[size_t(body25::kLAnkle)] = {lx, 501, 0.8};
  b[size_t(body25::kRAnkle)] = {rx, 499, 0.8};
  return b;
}

}  // namespace

TEST(PerceiveFeet, VisibleFeetBecomeHeelsAndBigToes) {
  Body25 b = ankles(101, 61);
  EXPECT_EQ(body25_add_feet(b, landmarks(0.8), 0.5f), 4);
  EXPECT_DOUBLE_EQ(b[size_t(body25::kLHeel)].x, 95);
  EXPECT_DOUBLE_EQ(b[size_t(body25::kLBigToe)].x, 130);
  EXPECT_DOUBLE_EQ(b[size_t(body25::kRHeel)].y, 520);
  EXPECT_DOUBLE_EQ(b[size_t(body25::kRBigToe)].conf, 0.8);
  EXPECT_FALSE(b[size_t(body25::kLSmallToe)].present());
}

TEST(PerceiveFeet, UnseenSwappedOrMissingSidesAreLeftOut) {
  Body25 b = ankles(101, 61);
  EXPECT_EQ(body25_add_feet(b, landmarks(0.3), 0.5f), 0);  // not visible enough
  EXPECT_FALSE(b[size_t(body25::kLHeel)].present());
  b = ankles(61, 101);  // the keypoints' left ankle where BlazePose has the right one
  EXPECT_EQ(body25_add_feet(b, landmarks(0.8), 0.5f), 0);
  b = ankles(101, 61);
  b[size_t(body25::kRAnkle)] = {};  // no right ankle: the right foot is not placed
  EXPECT_EQ(body25_add_feet(b, landmarks(0.8), 0.5f), 2);
  EXPECT_FALSE(b[size_t(body25::kRHeel)].present());
  EXPECT_EQ(body25_add_feet(b, {}, 0.5f), 0);              // no landmarks
  EXPECT_EQ(body25_add_feet(b, landmarks(0.8), 0.0f), 0);  // switched off
}

}  // namespace ks

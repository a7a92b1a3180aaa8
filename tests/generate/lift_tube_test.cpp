// The lift's cloth tube (generate/lift_tube.hpp): decided from the photo, joined to the mesh.
#include <gtest/gtest.h>

#include "generate/lift_tube.hpp"
#include "lift_case.hpp"

namespace ks {

TEST(LiftTube, DressGetsATubeJoinedAsAComponentOfItsOwn) {
  const test::LiftCase c(0);  // a dress
  const lift::LiftTube tube = lift::lift_tube(c.mask, c.body, c.fit.camera, c.options);
  ASSERT_TRUE(tube.present()) << tube.garment.summary;
  EXPECT_EQ(tube.skirt.hem, tube.garment.hem);
  const std::vector<uint8_t> under = lift::under_tube(tube, c.body);
  const long N = c.body.vertices(), T = tube.proxy.V.rows();
  ASSERT_EQ(long(under.size()), N);
  long enclosed = 0;
  for (uint8_t u : under) enclosed += u;
  EXPECT_GT(enclosed, 20);
  EXPECT_LT(enclosed, N / 2);

  SynthPerson P = c.body.person;
  lift::attach_tube(P, tube, c.body);
  ASSERT_EQ(P.rest.rows(), N + T);
  EXPECT_EQ(P.rest.topRows(N), c.body.person.rest);  // the body's vertices first, unchanged
  EXPECT_EQ(P.rest.bottomRows(T), tube.proxy.V);
  EXPECT_EQ(P.faces.rows(), c.body.person.faces.rows() + tube.proxy.F.rows());
  EXPECT_LT(P.faces.maxCoeff(), N + T);
  EXPECT_GE(P.faces.bottomRows(tube.proxy.F.rows()).minCoeff(), N);  // a component of its own
  ASSERT_EQ(long(P.labels.size()), N + T);
  ASSERT_EQ(P.stencil.rows(), N + T);
  EXPECT_EQ(P.stencil.cols(), c.body.person.stencil.cols());
  for (long i = 0; i < N + T; ++i) {
    EXPECT_NEAR(P.skin_weights.row(i).sum(), 1.0, 1e-5) << "vertex " << i;
    if (i >= N) {
      EXPECT_EQ(P.stencil.row(i).nonZeros(), 0);  // no body-model source
    }
  }
}

TEST(LiftTube, TrousersGetNone) {
  const test::LiftCase c(1);  // trousers
  const lift::LiftTube tube = lift::lift_tube(c.mask, c.body, c.fit.camera, c.options);
  EXPECT_FALSE(tube.present()) << tube.garment.summary;
  EXPECT_TRUE(lift::under_tube(tube, c.body).empty());
  SynthPerson P = c.body.person;
  lift::attach_tube(P, tube, c.body);
  EXPECT_EQ(P.rest, c.body.person.rest);
  EXPECT_EQ(P.faces, c.body.person.faces);
}

TEST(LiftTube, SwitchedOffMeansNoTube) {
  const test::LiftCase c(0);
  LiftOptions o = c.options;
  o.garment = false;
  const lift::LiftTube tube = lift::lift_tube(c.mask, c.body, c.fit.camera, o);
  EXPECT_TRUE(tube.garment.spans_legs);  // still decided and reported
  EXPECT_FALSE(tube.present());
}

}  // namespace ks

// The lift's step 3 (generate/lift_mirrors.hpp): mirrors, the head's colours, the blend.
#include <gtest/gtest.h>

#include "body/joints.hpp"
#include "body/parts.hpp"
#include "generate/lift_mirrors.hpp"
#include "lift_case.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

namespace {

// The body at rest with its own mirrors, and a seen colour to blend.
struct MirrorCase : test::LiftCase {
  Eigen::MatrixXd normals;
  lift::Mirrors mirrors;
  double cx = 0;
  explicit MirrorCase(uint64_t seed) : test::LiftCase(seed) {
    normals = body.rest_normals;
    mirrors = lift::find_mirrors(body.person.rest, body.person.faces, normals,
                                 body.person.skin_joints, body, options);
    cx = body.rest_state.rest_joints(smpl_joint::kPelvis, 0);
  }
  lift::SeenColour none() const {
    const long n = body.vertices();
    return {Eigen::MatrixXd::Zero(n, 3), Eigen::VectorXd::Zero(n)};
  }
};

}  // namespace

TEST(LiftMirrors, MirrorsAreOnTheOtherSide) {
  const MirrorCase c(1);
  const Eigen::MatrixXd& V = c.body.person.rest;
  const long n = V.rows();
  ASSERT_EQ(long(c.mirrors.left_right.size()), n);
  ASSERT_EQ(long(c.mirrors.front_back.size()), n);
  const double edge = mean_face_edge_length(V, c.body.person.faces);
  long lr = 0, fb = 0;
  for (long i = 0; i < n; ++i) {
    if (int j = c.mirrors.left_right[size_t(i)]; j >= 0) {
      ++lr;
      // Near the vertex's reflection through x = cx.
      const Eigen::Vector3d q(2 * c.cx - V(i, 0), V(i, 1), V(i, 2));
      EXPECT_LT((V.row(j).transpose() - q).norm(), 1.5 * c.options.left_right_radius_edges * edge);
      if (std::abs(V(i, 0) - c.cx) > 0.05) {
        EXPECT_LT((V(i, 0) - c.cx) * (V(j, 0) - c.cx), 0.0);
      }
    }
    if (int j = c.mirrors.front_back[size_t(i)]; j >= 0) {
      ++fb;
      EXPECT_LT(c.normals(i, 2) * c.normals(j, 2), 0.0);  // the other face
    }
  }
  EXPECT_GT(lr, n * 9 / 10);  // the body is nearly symmetric
  EXPECT_GT(fb, n / 2);
  // Switched off: none.
  LiftOptions o = c.options;
  o.mirror_left_right = o.mirror_front_back = false;
  const lift::Mirrors off =
      lift::find_mirrors(V, c.body.person.faces, c.normals, c.body.person.skin_joints, c.body, o);
  EXPECT_TRUE(off.left_right.empty());
  EXPECT_TRUE(off.front_back.empty());
}

TEST(LiftMirrors, MirroredColoursComeFromTheMirrorSide) {
  const MirrorCase c(1);
  const Eigen::MatrixXd& V = c.body.person.rest;
  const long n = V.rows();
  const Eigen::Vector3d red(1, 0, 0), green(0, 1, 0);
  // Left/right: only the +x side seen, in red.
  {
    lift::SeenColour s = c.none();
    for (long i = 0; i < n; ++i)
      if (V(i, 0) > c.cx + 0.02) {
        s.weight(i) = 1;
        s.colour.row(i) = red.transpose();
      }
    LiftOptions o = c.options;
    o.mirror_front_back = o.hair_back = false;
    const lift::Mirrors m{c.mirrors.left_right, {}};
    const lift::Blend b = lift::blend_colours(s, m, {}, c.body, o);
    long mirrored = 0;
    for (long i = 0; i < n; ++i) {
      const int j = m.left_right[size_t(i)];
      if (s.weight(i) > 0) {
        EXPECT_EQ(b.colour.row(i), red.transpose());  // seen: its own
        EXPECT_EQ(b.weight(i), 1.0);
      } else if (j >= 0 && s.weight(j) > 0) {
        EXPECT_NEAR((b.colour.row(i).transpose() - red).norm(), 0.0, 1e-12);
        EXPECT_DOUBLE_EQ(b.weight(i), o.w_left_right);
        ++mirrored;
      } else {
        EXPECT_EQ(b.weight(i), 0.0);
      }
    }
    EXPECT_GT(mirrored, n / 4);
    EXPECT_EQ(b.mirrored, mirrored);
  }
  // Front/back: only the front (normal z > 0) seen, in green; the back gets it but on the head.
  {
    lift::SeenColour s = c.none();
    for (long i = 0; i < n; ++i)
      if (c.normals(i, 2) > 0.2) {
        s.weight(i) = 1;
        s.colour.row(i) = green.transpose();
      }
    LiftOptions o = c.options;
    o.mirror_left_right = o.hair_back = false;
    const lift::Mirrors m{{}, c.mirrors.front_back};
    const lift::Blend b = lift::blend_colours(s, m, {}, c.body, o);
    long mirrored = 0;
    for (long i = 0; i < n; ++i) {
      const int j = m.front_back[size_t(i)];
      if (s.weight(i) > 0 || j < 0 || s.weight(j) == 0) continue;
      if (c.body.person.labels[size_t(i)] == kHeadNeck) {
        EXPECT_EQ(b.weight(i), 0.0);  // never the face onto the back of the head
      } else {
        EXPECT_NEAR((b.colour.row(i).transpose() - green).norm(), 0.0, 1e-12);
        EXPECT_DOUBLE_EQ(b.weight(i), o.w_front_back);
        ++mirrored;
      }
    }
    EXPECT_GT(mirrored, n / 5);
  }
}

TEST(LiftMirrors, BackOfTheHeadTakesTheHairAndTheNape) {
  const MirrorCase c(1);
  const long n = c.body.vertices();
  const Eigen::MatrixXd& V = c.body.person.rest;
  const lift::HeadColours head{Eigen::Vector3d(0.1, 0.05, 0.0), Eigen::Vector3d(0.8, 0.6, 0.5)};
  const lift::Blend b = lift::blend_colours(c.none(), c.mirrors, head, c.body, c.options);
  long hair = 0, nape = 0;
  for (long i = 0; i < n; ++i) {
    if (c.body.person.labels[size_t(i)] != kHeadNeck ||
        c.normals(i, 2) >= c.options.head_back_normal_z)
      continue;
    const Eigen::Vector3d want = V(i, 1) > c.body.head.hairline ? head.hair : head.nape;
    EXPECT_NEAR((b.colour.row(i).transpose() - want).norm(), 0.0, 1e-12);
    (V(i, 1) > c.body.head.hairline ? hair : nape) += 1;
  }
  EXPECT_GT(hair, 10);
  EXPECT_GT(nape, 3);
}

TEST(LiftMirrors, HeadColoursAreTheSeenCrownsAndSides) {
  const MirrorCase c(1);
  const long n = c.body.vertices();
  lift::SeenColour s = c.none();
  const Eigen::Vector3d brown(0.3, 0.2, 0.1);
  s.weight.setOnes();
  for (long i = 0; i < n; ++i) s.colour.row(i) = brown.transpose();
  const lift::HeadColours h = lift::head_colours(s, c.body, c.options);
  EXPECT_EQ(h.hair, brown);
  EXPECT_EQ(h.nape, brown);
  // Nothing seen: no hair colour, the nape falls back to it.
  const lift::HeadColours z = lift::head_colours(c.none(), c.body, c.options);
  EXPECT_EQ(z.hair, Eigen::Vector3d::Zero());
  EXPECT_EQ(z.nape, z.hair);
}

}  // namespace ks

#pragma once
// The built-in generator `lift` (needs no weights): the fitted body, subdivided, pushed out to the
// photo's silhouette where clothes or hair stand off it (the offsets carried smoothly round the
// back), and coloured from the photo where the photo sees it. Where it does not, colour comes from
// what it does see: the other side's limb (left <-> right), the other face of the body (front <->
// back, mirrored through the limb's or torso's own axis), the back of the head in the hair's
// colour, and what is left by diffusion over the surface. The result is a textured, skinned mesh
// that renders in any pose (synth/person.hpp's posing and rendering).
//
// The steps, each its own file and callable on its own (the tests do):
//   1. silhouette offsets (generate/lift_offsets.hpp), with the cloth tube across the legs
//      (generate/lift_tube.hpp);
//   2. colour where the photo sees the surface (generate/lift_seen.hpp);
//   3. mirrors and the head's rules for what it does not see (generate/lift_mirrors.hpp);
//   4. fill by propagation and smoothing of what is left (generate/lift_fill.hpp).
#include <Eigen/Core>
#include <string>

#include "core/image.hpp"
#include "fit/fit_file.hpp"
#include "reconstruct/garment/proxy.hpp"
#include "synth/person.hpp"

namespace ks {

struct LiftOptions {
  int subdivision_levels = 2;  // Loop subdivision of the body template

  // 1. Silhouette offsets (along the rest normals).
  double max_offset = 0.12;   // metres: how far clothes or hair may stand off the body
  double min_offset = -0.02;  // metres: how far inside the body the photo's outline may pull it
  // metres: a posed vertex is on the rim when it is visible to within this of the render's depth
  // and next to the render's outline (fit::rim_vertices).
  double rim_depth_tolerance = 0.02;
  // Weight of the pull towards zero standoff on surfaces the photo sees face-on (relative to a
  // rim vertex's 1; scaled by the squared cosine to the camera) where |cosine| > facing_min_cos.
  double w_facing_zero = 0.0;
  double facing_min_cos = 0.5;
  // Soft zeros on the front of the face (no clothes there), relative to a rim vertex's 1: head
  // vertices whose rest normal's z exceeds face_min_normal_z, between face_above_neck metres above
  // the neck joint and face_above_eye metres above the right eye.
  double w_face_zero = 0.3;
  double face_min_normal_z = 0.3;
  double face_above_neck = 0.03;  // metres
  double face_above_eye = 0.03;   // metres (the brows' height)
  // Smoothness of the offsets over the base mesh: weight of (x_a - x_b)^2 per edge, relative to
  // the data terms, within one body part; across parts times offset_cross_part (hair does not
  // spill onto the shoulders).
  double offset_smoothness = 0.5;
  double offset_cross_part = 0.05;

  // Cloth across the legs (generate/photo_garment.hpp) gets a tube of its own (reconstruct's
  // skirt proxy with the photo's hem and width) when it reaches at least min_garment_hem of the
  // way from the hips to the knees.
  bool garment = true;
  double min_garment_hem = 0.25;
  double clothing_allowance = 0.015;  // metres each leg's own clothing may stand off it
  double w_under_tube_zero = 0.3;     // pull towards zero offset of the body under the tube
  SkirtOptions skirt;

  // 2. Seen colour.
  double visible_cos =
      0.15;  // a vertex counts as seen when its normal faces the camera at least this much
  double full_view_cos = 0.6;      // ... and fully (seen weight 1, smoothstep between) from this
  double depth_tolerance = 0.015;  // metres: visibility test against the photo's depth buffer
  // Photo pixels (of its longer side) per pixel of the mask's outline left out of the seen
  // colour (the outline mixes the person with the background); at least 1 pixel.
  double outline_side_px = 400;

  // 3. Mirrors and the head, for what the photo does not see. Each source's weight is its
  // factor times (1 - seen weight)^2 times (for mirrors) the mirror vertex's own seen weight.
  bool mirror_left_right = true;
  bool mirror_front_back = true;
  bool hair_back = true;  // the back of the head in the hair's colour (not the face mirrored)
  // Mirror searches' radii in mean edge lengths of the lifted mesh.
  double left_right_radius_edges = 4;
  double front_back_radius_edges = 12;
  double w_left_right = 0.7;
  double w_front_back = 0.5;
  double w_head_back = 0.5;  // the hair's or the nape's colour at the back of the head
  // The back of the head: head vertices whose rest normal's z is below this.
  double head_back_normal_z = -0.3;
  // The hair's colour: the median of the seen crown (head vertices crown_above_brow metres above
  // the brows, seen weight above hair_min_seen).
  double crown_above_brow = 0.02;  // metres
  double hair_min_seen = 0.3;
  // The hairline at the nape: hairline_below_nose metres below the nose. Below it the nape takes
  // the colour the sides of the head show (median over head vertices in the band of nape_band
  // metres below the hairline, |rest normal x| > nape_side_min_normal_x, |z| <
  // nape_side_max_normal_z, seen weight above nape_min_seen).
  double hairline_below_nose = 0.04;  // metres
  double nape_band = 0.1;             // metres
  double nape_side_min_normal_x = 0.6;
  double nape_side_max_normal_z = 0.4;
  double nape_min_seen = 0.2;

  // 4. Fill and smoothing. A vertex's colour counts as known (a seed of the fill; "mirrored" in
  // the report) from this total weight; "seen" in the report from seen weight counted_seen.
  double known_weight = 0.05;
  double counted_seen = 0.5;
  // Smoothing passes over the surface where the photo did not see it well. Each pass moves a
  // vertex towards its neighbours' mean by 1 - keep, keep = its seen weight (smooth_mirrored:
  // mirrored colours are softened too) or its total weight (they are kept).
  int unseen_smoothing = 10;
  bool smooth_mirrored = true;
};

struct LiftReport {
  int vertices = 0;
  double seen = 0;       // fraction of vertices coloured from the photo directly
  double mirrored = 0;   // ... from a mirror (left/right or front/back) or the hair rule
  double diffused = 0;   // ... by diffusion alone
  int rim_vertices = 0;  // rim vertices that gave a silhouette offset
  double offset_median_m = 0, offset_max_m = 0;  // of the silhouette offsets over the body
  Eigen::Vector3d hair_colour = Eigen::Vector3d::Zero();
  std::string garment;       // the photo's garment decision (one line)
  int garment_vertices = 0;  // of the tube, 0 = none
};

// Lifts the photo (RGB, the fit's camera's size) and its mask (1 channel) onto the fitted body.
// The returned person renders with pose_synth_person / render_synth.
SynthPerson lift_person(const Image& photo, const Image& mask, const SubjectFit& fit,
                        const LiftOptions& options = {}, LiftReport* report = nullptr);

}  // namespace ks

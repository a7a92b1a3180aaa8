#include "generate/lift.hpp"

#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/math.hpp"
#include "generate/lift_body.hpp"
#include "generate/lift_fill.hpp"
#include "generate/lift_mirrors.hpp"
#include "generate/lift_offsets.hpp"
#include "generate/lift_seen.hpp"
#include "generate/lift_tube.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

SynthPerson lift_person(const Image& photo, const Image& mask, const SubjectFit& fit,
                        const LiftOptions& o, LiftReport* report) {
  using namespace lift;
  const Camera& cam = fit.camera;
  if (photo.width != cam.width || photo.height != cam.height)
    throw Error("lift: the photo is " + std::to_string(photo.width) + "x" +
                std::to_string(photo.height) + ", the fit's camera " + std::to_string(cam.width) +
                "x" + std::to_string(cam.height));
  if (mask.width != photo.width || mask.height != photo.height)
    throw Error("lift: the mask's size differs from the photo's");
  const LiftBody body = lift_body(fit, o);
  const long N = body.vertices();

  // 1. Silhouette offsets at the rim of the posed body, smoothed over the whole body; cloth
  // across the legs gets a tube of its own, which the body under it moves with.
  const LiftTube tube = lift_tube(mask, body, cam, o);
  const std::vector<RimOffset> rim =
      rim_offsets(body.posed.vertices, body.posed_normals, cam, body.render, mask, o);
  Eigen::VectorXd offset = Eigen::VectorXd::Zero(N);
  if (!rim.empty())
    offset = smooth_offsets(body.person.stencil, *fit.model,
                            offset_targets(rim, under_tube(tube, body), body, cam, o), o);
  SynthPerson P = body.person;
  P.rest += body.rest_normals.cwiseProduct(offset.replicate(1, 3));
  attach_tube(P, tube, body);
  const long Nall = P.rest.rows();

  // 2. Colour from the photo where it sees the surface, inside the mask's outline.
  const PosedPerson posed = pose_synth_person(P, fit.params);
  const SeenColour seen = seen_colour(photo, inner_mask(mask, o), posed.vertices,
                                      vertex_normals(posed.vertices, P.faces),
                                      render_depth(posed.vertices, P.faces, cam), cam, o);

  // 3. Mirrors and the head's rules for what the photo does not see.
  const Mirrors mirrors =
      find_mirrors(P.rest, P.faces, vertex_normals(P.rest, P.faces), P.skin_joints, body, o);
  const HeadColours head = head_colours(seen, body, o);
  Blend blend = blend_colours(seen, mirrors, head, body, o);

  // 4. What is left: propagation over the surface, then smoothing where not seen well.
  const auto adj = vertex_adjacency(P.faces, int(Nall));
  const int n_diffused = fill_by_propagation(adj, blend.weight, o.known_weight, blend.colour);
  smooth_unseen(adj, o.smooth_mirrored ? seen.weight : blend.weight, o.unseen_smoothing,
                blend.colour);
  P.colors = blend.colour.cwiseMax(0.0).cwiseMin(1.0);

  if (report) {
    report->vertices = int(Nall);
    report->seen = double(blend.seen) / Nall;
    report->mirrored = double(blend.mirrored) / Nall;
    report->diffused = double(n_diffused) / Nall;
    report->garment = tube.garment.summary;
    report->garment_vertices = int(Nall - N);
    report->rim_vertices = int(rim.size());
    report->offset_median_m = median(std::vector<double>(offset.data(), offset.data() + N));
    report->offset_max_m = offset.size() ? offset.maxCoeff() : 0.0;
    report->hair_colour = head.hair;
  }
  return P;
}

}  // namespace ks

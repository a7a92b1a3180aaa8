#pragma once
// The lift's cloth across the legs (part of step 1, generate/lift.hpp): skirts, dresses and coats
// get a tube of their own, reconstruct's skirt proxy (reconstruct/garment/proxy.hpp) around the
// hips and thighs, down to the hem the photo shows (generate/photo_garment.hpp), as wide as it
// shows. The body under it gets no silhouette offsets of its own and moves with it.
#include <cstdint>
#include <vector>

#include "core/camera.hpp"
#include "core/image.hpp"
#include "generate/lift.hpp"
#include "generate/lift_body.hpp"
#include "generate/photo_garment.hpp"
#include "reconstruct/garment/proxy.hpp"
#include "synth/person.hpp"

namespace ks::lift {

struct LiftTube {
  PhotoGarment garment;  // the photo's decision
  SkirtJoints joints;
  SkirtOptions skirt;  // LiftOptions::skirt with the photo's hem and half-widths
  SkirtProxy proxy;    // rest pose; no vertices: no tube
  bool present() const { return proxy.V.rows() > 0; }
};

// The photo's garment decision (mask: the photo's) and, when it spans the legs and
// LiftOptions::garment is on, the tube around the body's rest pose.
LiftTube lift_tube(const Image& mask, const LiftBody& body, const Camera& cam,
                   const LiftOptions& o);

// Per body vertex: 1 where the tube encloses it (at rest); empty without a tube.
std::vector<uint8_t> under_tube(const LiftTube& tube, const LiftBody& body);

// Joins the tube to `person` (the body's N vertices first, as lift_body made it, rest moved by
// the offsets or not) as a mesh component of its own: its vertices after the body's, labelled
// hips, with no body-model source in the stencil; the body under it and the tube skinned as the
// skirt (reconstruct/garment/skinning.hpp) at its starting follow. No tube: unchanged.
void attach_tube(SynthPerson& person, const LiftTube& tube, const LiftBody& body);

}  // namespace ks::lift

#pragma once
// What each libFuzzer harness does with one input (docs/robustness.md), shared by the harnesses
// (fuzz/fuzz_<name>.cpp) and the regression test that replays the inputs they found
// (tests/robustness/fuzz_regressions_test.cpp). Every reader is called as the CLI calls it, on a
// file; the only acceptable failure is a ks::Error (the CLI's one `error: ...` line). Any other
// exception escapes to libFuzzer (or the test), as every sanitizer report does.
#include <fstream>
#include <functional>
#include <map>
#include <string>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "avatar/tiny_avatar.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "fit/fit_file.hpp"
#include "fuzz_common.hpp"
#include "gaussians/ply.hpp"
#include "gltf/glb.hpp"
#include "io/image_io.hpp"
#include "io/npz.hpp"
#include "motion/amass.hpp"
#include "motion/bvh_motion.hpp"
#include "perceive/openpose.hpp"
#include "perceive/photo.hpp"

namespace ks::fuzz {

// The .npz reader (zip, stored and deflated entries, .npy headers); every element read.
inline void npz(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "input.npz");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const NpzFile z = read_npz(path);
    double sum = 0;
    for (const auto& [name, a] : z.arrays)
      for (int64_t i = 0; i < a.size(); ++i) sum += a.as_double(i);
    (void)sum;
  });
}

// A body model from an .npz (smplx layout), as `--body FILE` loads it, then posed once.
inline void body_model(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "model.npz");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const BodyModel m = load_body_model(path);
    BodyParams p;
    p.body_pose = Eigen::VectorXd::Constant(3 * m.num_body_pose_joints(), 0.1);
    const BodyState s = body_forward(m, p);
    (void)s;
  });
}

// The 3DGS .ply reader (`render`), extra properties included.
inline void ply(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "scene.ply");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    PlyExtra extra;
    const Gaussians g = read_ply(path, &extra);
    (void)g;
  });
}

// DIR/dataset.json as Dataset::load reads it (reconstruct, evaluate). The directory holds img.png,
// mask.png and model.npz (one-byte files) so that references to them pass the existence checks.
inline void dataset(const uint8_t* data, size_t size) {
  static const bool once = [] {
    for (const char* n : {"img.png", "mask.png", "model.npz"})
      std::ofstream(scratch_dir() / n).put('\n');
    return true;
  }();
  (void)once;
  input_file(data, size, "dataset.json");
  const std::string dir = scratch_dir().string();
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Dataset d = Dataset::load(dir);
    for (size_t i = 0; i < d.frames.size(); ++i) (void)d.params(i);
    (void)d.body_model_path(dir);
  });
}

// The .ksavatar reader (animate, export, view, evaluate), then posing it once as playback does.
inline void avatar(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "input.ksavatar");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Avatar a = load_avatar(path);
    BodyParams p;
    p.global_orient = Eigen::Vector3d(0.1, 0.2, 0.3);
    p.body_pose = Eigen::VectorXd::Constant(69, 0.05);
    const Gaussians g = pose_avatar(a, p);
    (void)g;
    (void)avatar_anchor_normals(a);
  });
}

// AMASS motions (.npz) as `animate --motion FILE.npz` loads them.
inline void amass(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "motion.npz");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Motion m = load_amass_npz(path, 0);
    (void)m;
  });
}

// BVH motions as `animate --motion FILE.bvh` loads them: parsed, mapped onto the body's joints
// and retargeted; then written back as BVH text.
inline void bvh(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "motion.bvh");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Bvh b = read_bvh(path);
    (void)format_bvh(b);
    const Motion m = load_bvh_motion(path, 0);
    (void)m;
  });
}

// GLB files as the glTF readers read them (read_glb): the container, then every accessor read
// as floats and, for integer ones, as unsigned integers.
inline void glb(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "avatar.glb");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const GlbDocument d = read_glb(path);
    const nlohmann::json acc = d.gltf.value("accessors", nlohmann::json::array());
    if (!acc.is_array()) return;
    for (int i = 0; i < int(acc.size()) && i < 64; ++i) {
      KS_FUZZ_EXPECT_ONLY_KS_ERROR({
        (void)d.accessor_count(i);
        (void)d.accessor_components(i);
        (void)d.read_floats(i);
      });
      KS_FUZZ_EXPECT_ONLY_KS_ERROR({ (void)d.read_uints(i); });
    }
  });
}

// Camera JSON (`render --camera`, `animate --camera`; dataset frames and fit.json use the same
// parser).
inline void camera(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "camera.json");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Camera c = Camera::load(path);
    (void)scale_camera(c, 7, 5);
  });
}

// Body-parameter JSON (PARAMS.json: `body pose --params`, `export --pose`), read for an SMPL-kind
// skeleton, an SMPL-X-kind model and the tiny test avatar.
inline void params(const uint8_t* data, size_t size) {
  static const Avatar tiny = test::tiny_avatar();
  // from_json consults the kind and the coefficient counts; full_pose the skeleton.
  static const BodyModel smpl = [] {
    BodyModel m;
    m.kind = BodyKind::kDefault;
    m.num_betas = 10;
    m.parents.resize(24);
    for (int j = 0; j < 24; ++j) m.parents[size_t(j)] = j - 1;
    m.joint_names = body_joint_names(m.kind);
    return m;
  }();
  static const BodyModel smplx = [] {
    BodyModel m;
    m.kind = BodyKind::kSMPLX;
    m.num_betas = 10;
    m.num_expression = 10;
    return m;
  }();
  const std::string path = input_file(data, size, "params.json");
  nlohmann::json j;
  try {
    j = read_json(path);
  } catch (const Error&) {
    return;
  }
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const BodyParams p = BodyParams::from_json(j, smpl);
    (void)p.full_pose(smpl);
    (void)p.to_json();
  });
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({ (void)BodyParams::from_json(j, smplx); });
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const BodyParams p = avatar_params_from_json(tiny, j);
    (void)avatar_full_pose(tiny, p);
  });
}

// OpenPose / DWPose / COCO keypoint JSON (`fit`, `perceive --keypoints`), both pixel conventions.
inline void keypoints(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "keypoints.json");
  for (double centre : {0.0, 0.5}) {
    KS_FUZZ_EXPECT_ONLY_KS_ERROR({
      KeypointReadOptions o;
      o.pixel_centre = centre;
      const KeypointFile k = read_keypoints(path, o);
      (void)openpose_json(k.person);
    });
  }
}

// SUBJECT/fit.json (`evaluate-fit`, `evaluate --fit`, `sample`), the body then posed once.
inline void fit_json(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "fit.json");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const SubjectFit f = load_fit(path);
    (void)body_forward(*f.model, f.params);
  });
}

// PNG / JPEG loading as the project calls it: perceive's load_photo (EXIF orientation, alpha,
// downscale) and load_mask, and read_image (datasets, fit). OpenCV's decoders are not
// instrumented; the project's code around them (the EXIF walk, channel handling) is.
inline void image(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, "photo.img");
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({
    const Photo p = load_photo(path, 32);
    (void)load_mask(path, p.source_width, p.source_height, p.rgb.width, p.rgb.height);
  });
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({ (void)read_image(path, 3); });
  KS_FUZZ_EXPECT_ONLY_KS_ERROR({ (void)read_image(path, 1); });
}

// Every harness by its name (fuzz_<name>).
inline const std::map<std::string, std::function<void(const uint8_t*, size_t)>>& all_targets() {
  static const std::map<std::string, std::function<void(const uint8_t*, size_t)>> t = {
      {"fuzz_npz", npz},
      {"fuzz_body_model", body_model},
      {"fuzz_ply", ply},
      {"fuzz_dataset", dataset},
      {"fuzz_avatar", avatar},
      {"fuzz_amass", amass},
      {"fuzz_bvh", bvh},
      {"fuzz_glb", glb},
      {"fuzz_camera", camera},
      {"fuzz_params", params},
      {"fuzz_keypoints", keypoints},
      {"fuzz_fit_json", fit_json},
      {"fuzz_image", image}};
  return t;
}

}  // namespace ks::fuzz

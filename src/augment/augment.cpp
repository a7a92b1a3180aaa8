#include "augment/augment.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>

#include "augment/face_fusion.hpp"
#include "augment/face_warp.hpp"
#include "body/keypoints.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/process.hpp"
#include "core/progress.hpp"
#include "dataset/dataset.hpp"
#include "fit/fit_file.hpp"
#include "io/image_io.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

// The face's landmarks (nose, right eye, left eye) of a posed body seen by a camera, and whether
// the camera sees the face: the head's forward axis (+Z at rest) within max_angle of the
// direction to the camera.
bool face_landmarks(const BodyModel& model, const std::array<Body25Source, kBody25Count>& src,
                    const BodyParams& params, const Camera& cam, double max_angle,
                    FaceLandmarks& out) {
  const BodyState st = body_forward(model, params);
  const Eigen::Vector3d head = st.joints.row(15).transpose();
  const Eigen::Vector3d fwd = st.transforms[15].topLeftCorner<3, 3>() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d to_cam = (cam.centre() - head).normalized();
  if (fwd.normalized().dot(to_cam) < std::cos(max_angle * M_PI / 180.0)) return false;
  const Eigen::MatrixXd P = body25_points(src, st.joints, st.vertices);
  out.points.clear();
  for (int k : {body25::kNose, body25::kREye, body25::kLEye}) {
    const Eigen::Vector3d c = cam.to_camera(P.row(k).transpose());
    if (c.z() <= 0) return false;
    out.points.push_back(cam.project_camera(c));
  }
  return true;
}

}  // namespace

AugmentReport run_augment(const std::string& prior_dir, const std::string& subject_dir,
                          const AugmentOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path prior(prior_dir), in_dir = prior / "dataset", sdir(subject_dir);
  const Dataset ds = Dataset::load(in_dir.string());
  AugmentReport rep;
  const SubjectFit fit = load_fit((sdir / "fit.json").string());
  const Image photo = read_image((sdir / "image.png").string(), 3);
  const Image photo_mask = read_image((sdir / "mask.png").string(), 1);
  const auto src = body25_sources(*fit.model);
  FaceLandmarks photo_face;
  const bool photo_has_face =
      face_landmarks(*fit.model, src, fit.params, fit.camera, o.max_face_angle_degrees, photo_face);

  if (o.face_warp != "body" && o.face_warp != "similarity")
    throw Error("augment: face warp \"" + o.face_warp + "\" is not body or similarity");
  // The body's surface as the photo sees it (for the warp through the body).
  Eigen::MatrixXd photo_seen;
  if (o.face_fusion && photo_has_face && o.face_warp == "body")
    photo_seen = photo_surface(body_forward(*fit.model, fit.params).vertices, fit.model->faces,
                               fit.camera, photo_mask);

  StagedDir staged((prior / "refined").string());
  const fs::path root = staged.staging();
  Dataset out = ds;
  Progress progress("augment", long(ds.frames.size()));
  const std::string log = (prior / "augment_restore.log").string();
  if (!o.restore_command.empty()) fs::remove(log);
  for (size_t i = 0; i < ds.frames.size(); ++i) {
    const DatasetFrame& f = ds.frames[i];
    Image img = ds.load_image(in_dir.string(), i);
    const Image mask = ds.load_mask(in_dir.string(), i);
    const bool generated = i > 0;
    if (generated) ++rep.frames;
    if (generated && o.face_fusion && photo_has_face) {
      FaceLandmarks ff;
      BodyParams p = f.pose;
      p.betas = ds.betas;
      if (face_landmarks(*fit.model, src, p, f.camera, o.max_face_angle_degrees, ff)) {
        Image warped, valid;
        if (o.face_warp == "body")
          warp_photo_through_body(photo, photo_seen, body_forward(*fit.model, p).vertices,
                                  fit.model->faces, f.camera, warped, valid);
        else
          warp_face_similarity(photo, photo_mask, photo_face, ff, img.width, img.height, warped,
                               valid);
        if (blend_face(warped, valid, img, mask, ff)) ++rep.faces_fused;
      }
    }
    const std::string out_image = (root / f.image).string();
    write_png(out_image, img);
    if (generated && !o.restore_command.empty()) {
      const std::string restored = out_image + ".restored.png";
      const std::string cmd = [&] {
        std::string c = o.restore_command;
        for (const auto& [key, value] :
             {std::pair<std::string, std::string>{"{in}", out_image}, {"{out}", restored}})
          for (size_t at; (at = c.find(key)) != std::string::npos;)
            c.replace(at, key.size(), shell_quote(value));
        return c;
      }();
      const int status = run_shell(cmd, log);
      if (status != 0 || !fs::exists(restored))
        throw Error("augment: the restoration command " +
                    (status != 0 ? "exited with status " + std::to_string(status)
                                 : std::string("wrote no ") + restored) +
                    " on frame " + std::to_string(i) + " (its output: " + log + ")\n" +
                    log_tail(log));
      const Image r = read_image(restored, 3);
      if (r.width != img.width || r.height != img.height)
        throw Error("augment: the restoration command changed frame " + std::to_string(i) +
                    "'s size");
      fs::rename(restored, out_image);
      ++rep.restored;
    }
    if (!f.mask.empty()) write_png((root / f.mask).string(), mask);
    if (o.progress) progress.update(long(i + 1));
  }
  out.save(root.string());
  staged.commit();
  if (o.progress) progress.finish();
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rep;
}

}  // namespace ks

#include "register/register.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "io/image_io.hpp"
#include "raster/rasterizer.hpp"
#include "reconstruct/adam.hpp"

namespace ks {

namespace {

// The body joints' rows of the full pose (avatar_full_pose): 1 .. body_joints.
int body_joint_rows(const Avatar& a) {
  const int J = a.num_joints();
  return (J == 52 || J == 55) ? 21 : J - 1;
}

// One scale's target: the frame composited on the background by its mask, the mask, the camera.
struct Level {
  Image target, mask;
  Camera camera;
  double area = 1;  // mask pixels (at least one)
  bool has_mask = false;
};

Level make_level(const Image& image, const Image& mask, const Camera& cam, float scale,
                 const float bg[3]) {
  Level L;
  const int w = std::max(8, int(std::lround(image.width * double(scale))));
  const int h = std::max(8, int(std::lround(image.height * double(scale))));
  const Image img = (w == image.width && h == image.height) ? image : resize_area(image, w, h);
  L.has_mask = mask.width > 0;
  L.mask = !L.has_mask                             ? Image(w, h, 1, 1.f)
           : (w == mask.width && h == mask.height) ? mask
                                                   : resize_area(mask, w, h);
  L.target = Image(w, h, 3);
  double area = 0;
  for (size_t p = 0; p < size_t(w) * size_t(h); ++p) {
    const float m = std::clamp(L.mask.data[p], 0.f, 1.f);
    area += m;
    for (int c = 0; c < 3; ++c)
      L.target.data[3 * p + size_t(c)] = img.data[3 * p + size_t(c)] * m + bg[c] * (1.f - m);
  }
  L.area = std::max(1.0, area);
  L.camera = scale_camera(cam, w, h);
  return L;
}

struct Loss {
  double total = 0, colour = 0, mask = 0, prior = 0;
};

class Problem {
 public:
  Problem(const Avatar& a, const BodyParams& start, const float bg[3], const RegisterOptions& o)
      : a_(a), start_(start), o_(o), rows_(1 + body_joint_rows(a)) {
    for (int k = 0; k < 3; ++k) rs_.background[k] = bg[k];
    const Eigen::MatrixXd full = avatar_full_pose(a, start);
    rot0_.resize(3 * size_t(rows_));
    for (int r = 0; r < rows_; ++r)
      for (int k = 0; k < 3; ++k) rot0_[3 * size_t(r) + size_t(k)] = float(full(r, k));
  }
  int rows() const { return rows_; }
  const std::vector<float>& rot0() const { return rot0_; }

  BodyParams params(const std::vector<float>& rot, const std::vector<float>& tr) const {
    BodyParams p = start_;
    p.global_orient = Eigen::Vector3d(rot[0], rot[1], rot[2]);
    p.body_pose.resize(3 * (rows_ - 1));
    for (int i = 0; i < 3 * (rows_ - 1); ++i) p.body_pose[i] = double(rot[3 + size_t(i)]);
    p.transl = Eigen::Vector3d(tr[0], tr[1], tr[2]);
    return p;
  }

  // The loss at (rot, tr); with gradients into grot, gtr when they are given.
  Loss evaluate(const Level& L, const std::vector<float>& rot, const std::vector<float>& tr,
                std::vector<float>* grot, std::vector<float>* gtr) {
    const BodyParams p = params(rot, tr);
    pose_avatar(a_, p, posed_, state_);
    rasterize_forward(posed_, L.camera, rs_, rr_);
    const size_t np = size_t(L.camera.width) * size_t(L.camera.height);
    Loss loss;
    const bool grads = grot != nullptr;
    if (grads) {
      dcolor_ = Image(L.camera.width, L.camera.height, 3);
      dalpha_ = Image(L.camera.width, L.camera.height, 1);
    }
    const double wc = double(o_.colour_weight) / (3.0 * L.area);
    const double wm = L.has_mask ? double(o_.mask_weight) / L.area : 0.0;
    double sc = 0, sm = 0;
    for (size_t q = 0; q < np; ++q) {
      for (int c = 0; c < 3; ++c) {
        const double d =
            double(rr_.color.data[3 * q + size_t(c)]) - L.target.data[3 * q + size_t(c)];
        sc += d * d;
        if (grads) dcolor_.data[3 * q + size_t(c)] = float(2.0 * wc * d);
      }
      const double d = double(rr_.alpha.data[q]) - std::clamp(L.mask.data[q], 0.f, 1.f);
      sm += d * d;
      if (grads) dalpha_.data[q] = float(2.0 * wm * d);
    }
    loss.colour = wc * sc;
    loss.mask = wm * sm;
    const double wp = rows_ > 1 ? double(o_.pose_prior) / double(rows_ - 1) : 0.0;
    for (size_t i = 3; i < rot.size(); ++i) {
      const double d = double(rot[i]) - rot0_[i];
      loss.prior += wp * d * d;
    }
    loss.total = loss.colour + loss.mask + loss.prior;
    if (!grads) return loss;
    rasterize_backward(posed_, L.camera, rs_, rr_, dcolor_, dalpha_, rg_);
    Eigen::MatrixXd dpose;
    Eigen::Vector3d dtr;
    pose_avatar_backward(a_, state_, rg_.means, rg_.quats, dpose, dtr);
    grot->assign(rot.size(), 0.f);
    for (int r = 0; r < rows_; ++r) {
      if (r > 0 && !o_.body_joints) continue;
      for (int k = 0; k < 3; ++k) {
        const size_t i = 3 * size_t(r) + size_t(k);
        double g = dpose(r, k);
        if (r > 0) g += 2.0 * wp * (double(rot[i]) - rot0_[i]);
        (*grot)[i] = float(g);
      }
    }
    gtr->assign(3, 0.f);
    for (int k = 0; k < 3; ++k) (*gtr)[size_t(k)] = float(dtr[k]);
    return loss;
  }

 private:
  const Avatar& a_;
  const BodyParams& start_;
  const RegisterOptions& o_;
  int rows_;
  std::vector<float> rot0_;
  RasterSettings rs_;
  RasterResult rr_;
  RasterGrads rg_;
  Gaussians posed_;
  AvatarPoseState state_;
  Image dcolor_, dalpha_;
};

}  // namespace

RegisterResult register_pose(const Avatar& avatar, const BodyParams& start, const Camera& camera,
                             const Image& image, const Image& mask, const float background[3],
                             const RegisterOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  if (image.channels != 3 || image.width <= 0 || image.height <= 0)
    throw Error("register: the frame must be an RGB image");
  if (mask.width > 0 &&
      (mask.width != image.width || mask.height != image.height || mask.channels != 1))
    throw Error("register: the mask must be one channel of the frame's size (" +
                std::to_string(image.width) + " x " + std::to_string(image.height) + ")");
  if (camera.width != image.width || camera.height != image.height)
    throw Error("register: the camera is for " + std::to_string(camera.width) + " x " +
                std::to_string(camera.height) + ", the frame is " + std::to_string(image.width) +
                " x " + std::to_string(image.height));
  if (o.scales.empty() || o.scales.size() != o.iterations.size())
    throw Error("register: one iteration count per scale needed");
  for (size_t l = 0; l < o.scales.size(); ++l)
    if (!(o.scales[l] > 0.f && o.scales[l] <= 1.f) || o.iterations[l] < 0)
      throw Error("register: scales must be in (0, 1] and iterations >= 0");
  if (!(o.lr_rotation >= 0.f) || !(o.lr_translation >= 0.f) || !(o.pose_prior >= 0.f) ||
      !(o.colour_weight >= 0.f) || !(o.mask_weight >= 0.f))
    throw Error("register: learning rates and weights must be >= 0");

  Problem prob(avatar, start, background, o);
  std::vector<float> rot = prob.rot0();
  std::vector<float> tr = {float(start.transl[0]), float(start.transl[1]), float(start.transl[2])};
  std::vector<float> grot, gtr;
  RegisterResult res;
  for (size_t l = 0; l < o.scales.size(); ++l) {
    const Level L = make_level(image, mask, camera, o.scales[l], background);
    Adam adam;
    adam.eps = 1e-12f;
    adam.total_steps = std::max(1, o.iterations[l]);
    adam.add_group("rotation", &rot, &grot, o.lr_rotation);
    adam.add_group("translation", &tr, &gtr, o.lr_translation);
    for (int it = 0; it < o.iterations[l]; ++it) {
      prob.evaluate(L, rot, tr, &grot, &gtr);
      adam.step();
      ++res.steps;
    }
  }
  // Kept only where the finest level's loss fell.
  const Level fine = make_level(image, mask, camera, o.scales.back(), background);
  std::vector<float> rot0 = prob.rot0();
  std::vector<float> tr0 = {float(start.transl[0]), float(start.transl[1]), float(start.transl[2])};
  const Loss before = prob.evaluate(fine, rot0, tr0, nullptr, nullptr);
  const Loss after = prob.evaluate(fine, rot, tr, nullptr, nullptr);
  res.cost_before = before.total, res.colour_before = before.colour, res.mask_before = before.mask;
  res.improved = after.total < before.total;
  const Loss& kept = res.improved ? after : before;
  res.cost_after = kept.total, res.colour_after = kept.colour, res.mask_after = kept.mask;
  res.params = res.improved ? prob.params(rot, tr) : start;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace ks

#pragma once
// Linear blend skinning with top-k skin weights, one implementation for training and playback
// (Gaussians) and for meshes (points). For point i with weights w_ik over joints j_ik and the
// skinning transforms A_j (rest -> posed, body/posing.hpp):
//   M_i = sum_k w_ik A_{j_ik}[0:3, :]        (blended 3 x 4, accumulated in double)
//   x'_i = M_i[:, 0:3] (x_i + pose_offset_i) + M_i[:, 3]
// and for a Gaussian also
//   q'_i = q(M_i) * q_i     (q(M) the unit quaternion of the blended 3 x 3, core/rotation.hpp)
//   log_scale' = log_scale  (the blend is treated as a rotation)
// The blended transforms depend only on the pose and the weights, so the backward pass to the
// canonical means and rotations is linear: dx = M^T dx', dq = conj(q(M)) * dq'.
#include <Eigen/Core>
#include <Eigen/StdVector>
#include <memory>
#include <vector>

#include "gaussians/gaussians.hpp"

namespace ks {

// The blended top 3 rows of sum_k w_k A_{j_k} (zero weights skipped).
template <class W>
inline Eigen::Matrix<double, 3, 4> blend_skin_transform(
    const std::vector<Eigen::Matrix4d>& transforms, const int* joints, const W* weights, int k) {
  Eigen::Matrix<double, 3, 4> M = Eigen::Matrix<double, 3, 4>::Zero();
  for (int q = 0; q < k; ++q) {
    const W w = weights[q];
    if (w == W(0)) continue;
    M += double(w) * transforms[size_t(joints[q])].topRows<3>();
  }
  return M;
}

// Back-face culling for playback (an approximation; `evaluate` never uses it). A Gaussian hangs
// on the template surface, so one whose anchor normal, posed with the same blended transform as
// its mean, points away from the camera (cos(normal, mean - eye) > `threshold`) is behind the
// body's front surface; lbs_forward then gives it an opacity logit of kCulledOpacityLogit and the
// rasterizer drops it before sorting, binning and compositing.
struct BackfaceCull {
  const std::vector<float>* normals = nullptr;  // 3N canonical unit normals; empty: no culling
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  float threshold = 0.4f;  // cosine in [0, 1]; 1 culls nothing
};
constexpr float kCulledOpacityLogit = -100.f;

// What the backward pass needs: the blended transforms and their rotations' quaternions.
struct LbsCache {
  std::vector<float> M;       // 12 N: blended 3 x 4, row-major
  std::vector<float> qblend;  // 4 N: q(M) (w, x, y, z)
};

// The skinning transforms as the posing kernels read them (here and on the GPU): each one's top
// 3 x 4, row-major, in single precision, 12 floats a joint.
void skin_transforms_3x4(const std::vector<Eigen::Matrix4d>& transforms, std::vector<float>& tf);

// Poses canonical Gaussians with k = skin_joints.size() / N weights each. pose_offsets: 3N or
// nullptr. Opacities, scales and SH are copied (opacities of culled Gaussians set to
// kCulledOpacityLogit when `cull` is given). `posed` is resized, its buffers reused; `cache` may
// be nullptr (playback). keep_unposed: `posed` holds these canonical Gaussians' scales and SH
// from an earlier call (playback of one avatar), so they are not copied again (the SH are most
// of the bytes); a size mismatch copies them anyway. OpenMP over Gaussians. Throws ks::Error on
// inconsistent sizes and on a skin joint out of range (then `posed` holds no valid pose).
void lbs_forward(const Gaussians& canonical, const float* pose_offsets,
                 const std::vector<int>& skin_joints, const std::vector<float>& skin_weights,
                 const std::vector<Eigen::Matrix4d>& transforms, Gaussians& posed,
                 LbsCache* cache = nullptr, const BackfaceCull* cull = nullptr,
                 bool keep_unposed = false);
// lbs_forward's posing of the means, rotations and opacity logits (culled ones at
// kCulledOpacityLogit) for one range of Gaussians at a time, into the caller's arrays: playback
// poses each chunk as the rasterizer's projection reads it (raster/rasterizer.hpp
// GaussianSource), so the posed Gaussians never make a round trip through memory. The skin is
// checked once, at construction (ks::Error: sizes, a joint outside [0, num_transforms)); the
// references must outlive this.
struct LbsJob;
class LbsRanges {
 public:
  LbsRanges(const Gaussians& canonical, const std::vector<int>& skin_joints,
            const std::vector<float>& skin_weights, int num_transforms);
  ~LbsRanges();
  LbsRanges(const LbsRanges&) = delete;
  LbsRanges& operator=(const LbsRanges&) = delete;
  // This frame's skinning transforms (num_transforms of them), pose-corrective offsets (3N, or
  // nullptr) and back-face culling (or nullptr); the pointers must outlive the calls to pose.
  void set_pose(const std::vector<Eigen::Matrix4d>& transforms, const float* pose_offsets,
                const BackfaceCull* cull);
  // Gaussians [b, e) into means[3 (i - b) ..], quats[4 (i - b) ..], opacity_logits[i - b]: what
  // lbs_forward writes for them, bit for bit. Thread-safe for disjoint ranges; after set_pose;
  // does not throw (it runs inside the projection's parallel loop).
  void pose(size_t b, size_t e, float* means, float* quats, float* opacity_logits) const;

 private:
  std::unique_ptr<LbsJob> job_;
  int J_;
  std::vector<float> tf_;
};

// lbs_forward works on blocks of 8 Gaussians (AVX2, where the CPU has it) or 4 (SSE2), the same
// operations at both widths. Tests pin the baseline (false) to compare the two; returns the
// previous setting.
bool lbs_allow_avx2(bool allow);
// dmeans (3N), dquats (4N) of the posed Gaussians -> canonical (overwrites dmeans_c, dquats_c).
// Log-scales, opacities and SH pass through unchanged (the caller reuses their gradients).
void lbs_backward(const LbsCache& cache, const std::vector<float>& dmeans_posed,
                  const std::vector<float>& dquats_posed, std::vector<float>& dmeans_canonical,
                  std::vector<float>& dquats_canonical);

// The backward to the skinning transforms (registration: the pose is learned, the Gaussians are
// fixed): from dmeans (3N) and dquats (4N) of the posed Gaussians, per Gaussian
//   dM_i[:, 0:3] = g_i (x_i + o_i)^T + d q(M)/dM^T (R(q_i)^T dq'_i),   dM_i[:, 3] = g_i
// (q' = q(M) * q = R(q) q(M); core/rotation.hpp matrix_to_quat_backward), then
// dtransforms_j = sum over Gaussians and slots with joint j of w_ik dM_i (J entries, the top
// 3 x 4 rows, overwritten). doffsets (3N: d loss / d pose_offsets = M_i[:, 0:3]^T g_i) may be
// nullptr. `canonical`, `pose_offsets` and the skin are lbs_forward's, `cache` its output.
void lbs_transforms_backward(const Gaussians& canonical, const float* pose_offsets,
                             const std::vector<int>& skin_joints,
                             const std::vector<float>& skin_weights, int num_transforms,
                             const LbsCache& cache, const std::vector<float>& dmeans_posed,
                             const std::vector<float>& dquats_posed,
                             std::vector<Eigen::Matrix<double, 3, 4>>& dtransforms,
                             std::vector<float>* doffsets);

// Skins points (N x 3 rows; offsets: rows added before skinning where present, may be nullptr or
// have fewer rows) with k = joints.cols() weights per row (row-major N x k).
using SkinJoints = Eigen::Matrix<int, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using SkinWeights = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
Eigen::MatrixXd skin_points(const Eigen::MatrixXd& points, const Eigen::MatrixXd* offsets,
                            const SkinJoints& joints, const SkinWeights& weights,
                            const std::vector<Eigen::Matrix4d>& transforms);

}  // namespace ks

#include "augment/face_fusion.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "core/error.hpp"

namespace ks {

namespace {

cv::Mat to_u8(const Image& img) {
  cv::Mat m(img.height, img.width, img.channels == 1 ? CV_8UC1 : CV_8UC3);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < img.channels && c < 3; ++c)
        m.ptr<uint8_t>(y)[x * m.channels() + c] =
            uint8_t(std::clamp(img.at(x, y, c), 0.f, 1.f) * 255.f + 0.5f);
  return m;
}

}  // namespace

Eigen::Matrix<double, 2, 3> similarity_2d(const std::vector<Eigen::Vector2d>& from,
                                          const std::vector<Eigen::Vector2d>& to) {
  if (from.size() != to.size() || from.size() < 2)
    throw Error("face fusion: at least two landmark pairs needed");
  // As complex numbers: to = a from + b with a = s e^{i theta}, least squares.
  const double n = double(from.size());
  Eigen::Vector2d mf = Eigen::Vector2d::Zero(), mt = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < from.size(); ++i) {
    mf += from[i] / n;
    mt += to[i] / n;
  }
  double re = 0, im = 0, den = 0;
  for (size_t i = 0; i < from.size(); ++i) {
    const Eigen::Vector2d p = from[i] - mf, q = to[i] - mt;
    re += p.x() * q.x() + p.y() * q.y();  // conj(p) q
    im += p.x() * q.y() - p.y() * q.x();
    den += p.squaredNorm();
  }
  if (!(den > 0)) throw Error("face fusion: the landmarks coincide");
  Eigen::Matrix2d A;
  A << re / den, -im / den, im / den, re / den;
  Eigen::Matrix<double, 2, 3> S;
  S.leftCols<2>() = A;
  S.col(2) = mt - A * mf;
  return S;
}

namespace {

Image from_u8(const cv::Mat& m) {
  Image img(m.cols, m.rows, m.channels());
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      for (int c = 0; c < m.channels(); ++c)
        img.at(x, y, c) = m.ptr<uint8_t>(y)[x * m.channels() + c] / 255.f;
  return img;
}

}  // namespace

void warp_face_similarity(const Image& photo, const Image& photo_mask, const FaceLandmarks& pf,
                          const FaceLandmarks& ff, int width, int height, Image& src,
                          Image& src_valid) {
  const Eigen::Matrix<double, 2, 3> S = similarity_2d(pf.points, ff.points);
  // OpenCV's pixel centres are at integers, the landmarks' at integer + 0.5.
  cv::Mat M(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) M.at<double>(r, c) = S(r, c);
  const Eigen::Vector2d shift =
      S.leftCols<2>() * Eigen::Vector2d(0.5, 0.5) - Eigen::Vector2d(0.5, 0.5);
  M.at<double>(0, 2) += shift.x();
  M.at<double>(1, 2) += shift.y();
  const cv::Size size(width, height);
  cv::Mat s, sm;
  cv::warpAffine(to_u8(photo), s, M, size, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::warpAffine(to_u8(photo_mask), sm, M, size, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  src = from_u8(s);
  src_valid = Image(width, height, 1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) src_valid.at(x, y, 0) = sm.at<uint8_t>(y, x) >= 128 ? 1.f : 0.f;
}

bool blend_face(const Image& src_img, const Image& src_valid, Image& frame, const Image& frame_mask,
                const FaceLandmarks& ff, const FaceFusionOptions& o, Image* region) {
  if (ff.points.size() < 3) throw Error("face fusion: the nose and both eyes are needed");
  if (src_img.width != frame.width || src_img.height != frame.height ||
      src_valid.width != frame.width || src_valid.height != frame.height)
    throw Error("face fusion: the warped photo is not the frame's size");
  const double iod = (ff.points[1] - ff.points[2]).norm();
  if (!(iod >= 4.0)) return false;
  const cv::Size size(frame.width, frame.height);
  // The face region: an ellipse around the nose, where the warped photo and the frame both show
  // the person.
  cv::Mat mask(size, CV_8UC1, cv::Scalar(0));
  const Eigen::Vector2d nose = ff.points[0];
  const Eigen::Vector2d eyes = 0.5 * (ff.points[1] + ff.points[2]);
  const Eigen::Vector2d up =
      (eyes - nose).norm() > 1e-6 ? (eyes - nose).normalized() : Eigen::Vector2d(0, -1);
  const double angle = std::atan2(up.y(), up.x()) * 180.0 / M_PI + 90.0;
  cv::ellipse(mask, cv::Point2d(nose.x() - 0.5, nose.y() - 0.5),
              cv::Size2d(o.width * iod, o.height * iod), angle, 0, 360, cv::Scalar(255),
              cv::FILLED);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      if (src_valid.at(x, y, 0) < 0.5f || frame_mask.at(x, y, 0) < 0.5f) mask.at<uint8_t>(y, x) = 0;
  // seamlessClone needs the region away from the image's border.
  cv::rectangle(mask, cv::Rect(0, 0, size.width, size.height), cv::Scalar(0), 2);
  const cv::Rect box = cv::boundingRect(mask);
  if (box.width < 8 || box.height < 8) return false;
  cv::Mat dst = to_u8(frame), out;
  const cv::Point centre(box.x + box.width / 2, box.y + box.height / 2);
  cv::seamlessClone(to_u8(src_img), dst, mask, centre, out, cv::NORMAL_CLONE);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      for (int c = 0; c < 3; ++c) frame.at(x, y, c) = out.at<cv::Vec3b>(y, x)[c] / 255.f;
  if (region) {
    *region = Image(size.width, size.height, 1);
    for (int y = 0; y < size.height; ++y)
      for (int x = 0; x < size.width; ++x) region->at(x, y, 0) = mask.at<uint8_t>(y, x) / 255.f;
  }
  return true;
}

bool fuse_face(const Image& photo, const Image& photo_mask, const FaceLandmarks& pf, Image& frame,
               const Image& frame_mask, const FaceLandmarks& ff, const FaceFusionOptions& o,
               Image* region) {
  if (pf.points.size() < 3 || ff.points.size() != pf.points.size())
    throw Error("face fusion: the nose and both eyes are needed in both images");
  const double iod = (ff.points[1] - ff.points[2]).norm();
  if (!(iod >= 4.0)) return false;
  Image src, valid;
  warp_face_similarity(photo, photo_mask, pf, ff, frame.width, frame.height, src, valid);
  return blend_face(src, valid, frame, frame_mask, ff, o, region);
}

}  // namespace ks

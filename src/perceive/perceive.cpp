#include "perceive/perceive.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "io/image_io.hpp"
#include "perceive/detection.hpp"
#include "perceive/guided_filter.hpp"
#include "perceive/helper.hpp"
#include "perceive/overlay.hpp"
#include "perceive/photo.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

constexpr int kMinBodyKeypoints = 4;

struct Box {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive pixel rows/columns
  bool empty() const { return x1 < x0; }
  int longer() const { return empty() ? 0 : std::max(x1 - x0 + 1, y1 - y0 + 1); }
};

Box mask_box(const Image& m) {
  Box b{m.width, m.height, -1, -1};
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      if (m.at(x, y, 0) > 0.5f) {
        b.x0 = std::min(b.x0, x);
        b.y0 = std::min(b.y0, y);
        b.x1 = std::max(b.x1, x);
        b.y1 = std::max(b.y1, y);
      }
  if (b.x1 < 0) return Box{};
  return b;
}

int count_present(const Body25& b) {
  return int(std::count_if(b.begin(), b.end(), [](const Keypoint2D& k) { return k.present(); }));
}

// The folder may be replaced only when it is empty or an earlier perceive output.
void check_out_dir(const std::string& out_dir) {
  const fs::path p(out_dir);
  std::error_code ec;
  if (!fs::exists(p, ec)) return;
  if (!fs::is_directory(p, ec))
    throw Error("perceive: the output folder " + out_dir + " exists and is not a folder");
  if (fs::is_empty(p, ec) || fs::exists(p / "perceive.json", ec)) return;
  throw Error("perceive: the output folder " + out_dir +
              " is a non-empty folder that is not a perceive output; choose a new folder");
}

nlohmann::json keypoint_list(const Body25& b) {
  nlohmann::json a = nlohmann::json::array();
  for (int k = 0; k < kBody25Count; ++k)
    if (b[size_t(k)].present()) a.push_back(body25_names()[size_t(k)]);
  return a;
}

}  // namespace

Body25 body25_from_detector(const std::vector<std::array<double, 3>>& coco17, float min_score) {
  if (coco17.size() != size_t(kCoco17Size))
    throw Error("perceive: the detector gave " + std::to_string(coco17.size()) +
                " keypoints, not 17");
  std::array<Keypoint2D, kCoco17Size> c;
  for (size_t k = 0; k < c.size(); ++k)
    if (coco17[k][2] >= min_score && coco17[k][2] > 0)
      c[k] = {coco17[k][0], coco17[k][1], coco17[k][2]};
  return body25_from_coco17(c);
}

int body25_add_feet(Body25& body, const std::vector<std::array<double, 4>>& bp,
                    float min_visibility) {
  if (bp.size() != 33 || !(min_visibility > 0)) return 0;
  // BlazePose's landmarks: 27 / 28 left / right ankle, 29 / 30 heel, 31 / 32 foot index.
  struct Side {
    int ankle, heel, toe;        // BlazePose
    int k_ankle, k_heel, k_toe;  // BODY_25
  };
  using namespace body25;
  const Side sides[2] = {{27, 29, 31, kLAnkle, kLHeel, kLBigToe},
                         {28, 30, 32, kRAnkle, kRHeel, kRBigToe}};
  int added = 0;
  for (const Side& sd : sides) {
    const auto &a = bp[size_t(sd.ankle)], &h = bp[size_t(sd.heel)], &t = bp[size_t(sd.toe)];
    if (h[2] < min_visibility || t[2] < min_visibility) continue;
    const Keypoint2D& ankle = body[size_t(sd.k_ankle)];
    if (!ankle.present()) continue;
    const double foot = std::hypot(h[0] - t[0], h[1] - t[1]);
    if (std::hypot(a[0] - ankle.x, a[1] - ankle.y) > std::max(foot, 1.0)) continue;
    body[size_t(sd.k_heel)] = {h[0], h[1], h[2]};
    body[size_t(sd.k_toe)] = {t[0], t[1], t[2]};
    added += 2;
  }
  return added;
}

namespace {

// What run_perceive gathers before it writes: the subject's parts and perceive.json.
struct Subject {
  Photo photo;
  PersonKeypoints person;
  bool have_keypoints = false;  // the user's
  Image mask;                   // empty until one is found
  nlohmann::json info;          // perceive.json
};

void check_request(const std::string& out_dir, const PerceiveOptions& opts) {
  if (out_dir.empty()) throw Error("perceive: no output folder given");
  if (opts.max_size < 0)
    throw Error("perceive: the longer side's limit must be >= 0 (0 keeps the photo's size), got " +
                std::to_string(opts.max_size));
  check_out_dir(out_dir);
}

// perceive.json's record of the photo and image.png.
nlohmann::json photo_info(const std::string& photo, const Photo& p) {
  nlohmann::json info;
  info["format"] = "kinesplat-perceive";
  info["version"] = "1.0";
  info["source"] = {{"path", fs::absolute(photo).lexically_normal().string()},
                    {"width", p.source_width},
                    {"height", p.source_height},
                    {"channels", p.source_channels},
                    {"bit_depth", p.bit_depth},
                    {"exif_orientation", p.exif_orientation}};
  info["image"] = {{"file", "image.png"}, {"width", p.rgb.width}, {"height", p.rgb.height}};
  if (p.focal_35mm > 0) {  // the camera's focal length, as the photo's EXIF gives it
    info["source"]["focal_35mm"] = p.focal_35mm;
    info["image"]["focal_px"] = focal_px_from_35mm(p.focal_35mm, p.rgb.width, p.rgb.height);
  }
  info["scale"] = {p.scale_x, p.scale_y};
  info["pixel_centre"] = 0.5;
  return info;
}

// How far outside the image a keypoint may lie, as a share of the image's size.
constexpr double kKeypointSlack = 0.25;

// Keypoints far outside the photo were made for another image (or are normalised).
void check_keypoints_in_photo(const Body25& body, const Photo& p, const std::string& path) {
  const int W = p.rgb.width, H = p.rgb.height;
  for (int k = 0; k < kBody25Count; ++k) {
    const auto& q = body[size_t(k)];
    if (q.present() && (q.x < -kKeypointSlack * W || q.x > (1 + kKeypointSlack) * W ||
                        q.y < -kKeypointSlack * H || q.y > (1 + kKeypointSlack) * H))
      throw Error("perceive: keypoint " + std::string(body25_names()[size_t(k)]) + " in " + path +
                  " lies far outside the photo (" + std::to_string(p.source_width) + "x" +
                  std::to_string(p.source_height) + "): are the keypoints in this photo's pixels?");
  }
}

// The user's keypoints (photo pixels -> image.png pixels).
void read_user_keypoints(const PerceiveOptions& opts, Subject& s, PerceiveReport& rep) {
  KeypointFile kf = read_keypoints(opts.keypoints_path, {opts.keypoints_pixel_centre});
  s.person = kf.person;
  for (auto& k : s.person.body)
    if (k.present()) k.x *= s.photo.scale_x, k.y *= s.photo.scale_y;
  for (auto& k : s.person.face)
    if (k.present()) k.x *= s.photo.scale_x, k.y *= s.photo.scale_y;
  check_keypoints_in_photo(s.person.body, s.photo, opts.keypoints_path);
  s.have_keypoints = true;
  rep.keypoints_source = "user";
  for (auto& w : kf.warnings) rep.notes.push_back(w);
  s.info["keypoints"] = {{"source", "user"},
                         {"file", fs::absolute(opts.keypoints_path).lexically_normal().string()},
                         {"format", keypoint_format_name(kf.format)},
                         {"people_in_file", kf.people},
                         {"pixel_centre_in_file", opts.keypoints_pixel_centre}};
}

constexpr float kAlphaThreshold = 0.5f;  // alpha that counts as opaque

// An alpha channel is a cut-out only when it has both a person and a background: one that is
// (nearly) all opaque or all transparent is not a mask (some PNGs carry a few stray transparent
// pixels).
void mask_from_alpha(const PerceiveOptions& opts, Subject& s, PerceiveReport& rep) {
  const Image& alpha = s.photo.alpha;
  size_t opaque = 0;
  for (float a : alpha.data) opaque += a >= kAlphaThreshold;
  const double share = double(opaque) / double(alpha.data.size());
  if (share < opts.min_alpha_share || share > 1.0 - opts.min_alpha_share) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "the photo's alpha channel is %.2f%% opaque: not a cut-out, not used as the "
                  "mask",
                  100.0 * share);
    rep.notes.push_back(buf);
    return;
  }
  s.mask = threshold_mask(alpha, kAlphaThreshold);
  rep.mask_source = "alpha";
  s.info["mask"] = {
      {"source", "alpha"}, {"threshold", double(kAlphaThreshold)}, {"opaque_share", share}};
}

// The user's mask, or the photo's alpha channel.
void read_user_mask(const PerceiveOptions& opts, Subject& s, PerceiveReport& rep) {
  if (!opts.mask_path.empty()) {
    const Photo& p = s.photo;
    s.mask = load_mask(opts.mask_path, p.source_width, p.source_height, p.rgb.width, p.rgb.height);
    rep.mask_source = "user";
    s.info["mask"] = {{"source", "user"},
                      {"file", fs::absolute(opts.mask_path).lexically_normal().string()}};
  } else if (!s.photo.alpha.empty()) {
    mask_from_alpha(opts, s, rep);
  }
}

// The detector helper, started; none (and a note) when it cannot start and only the face is
// wanted from it (need_detector false). `dir`: where it was found.
std::unique_ptr<PerceiveHelper> start_helper(const PerceiveOptions& opts, bool need_detector,
                                             std::string& dir, PerceiveReport& rep) {
  try {
    dir = opts.helper_dir.empty() ? find_perceive_helper() : opts.helper_dir;
    if (!opts.helper_dir.empty() && !fs::exists(fs::path(dir) / "perceive.js"))
      throw Error("the perceive helper is not installed: " + dir +
                  " has no perceive.js; run `make deps` in the kinesplat source tree");
    HelperOptions ho;
    ho.request_timeout_s = opts.helper_timeout_s;
    return std::make_unique<PerceiveHelper>(dir, ho);
  } catch (const Error& e) {
    if (need_detector) throw;
    rep.notes.push_back(std::string("no face landmarks: ") + e.what());
  }
  return nullptr;
}

// perceive.json's "detector".
nlohmann::json detector_info(const std::string& dir, const PerceiveHelper& helper,
                             const nlohmann::json& r, int people) {
  const nlohmann::json& hello = helper.hello();
  return {{"helper", fs::absolute(dir).lexically_normal().string()},
          {"helper_version", hello.value("version", std::string("?"))},
          {"tfjs", hello.value("tfjs", std::string("?"))},
          {"backend", hello.value("backend", std::string("?"))},
          {"models", hello.value("models", nlohmann::json::object())},
          {"people_found", people},
          {"person", r.value("person", nlohmann::json())},
          {"movenet_crop", r.value("movenet_crop", nlohmann::json())},
          {"times_ms", r.value("times_ms", nlohmann::json())},
          {"warnings", r.value("warnings", nlohmann::json::array())}};
}

void keypoints_from_detection(const Detection& d, const PerceiveOptions& opts, Subject& s,
                              PerceiveReport& rep) {
  s.person.body = body25_from_detector(d.coco17, opts.min_keypoint_score);
  const int feet = body25_add_feet(s.person.body, d.blazepose, opts.min_foot_visibility);
  rep.keypoints_source = "detector";
  s.info["keypoints"] = {
      {"source", "detector"},
      {"model", feet > 0 ? "movenet-thunder (COCO-17 -> BODY_25; kNeck and kMidHip "
                           "derived) + blazepose-full heels and foot indices as BODY_25 "
                           "heels and big toes (small toes absent)"
                         : "movenet-thunder (COCO-17 -> BODY_25; kNeck and kMidHip "
                           "derived; toes and heels absent)"},
      {"min_score", opts.min_keypoint_score},
      {"min_foot_visibility", opts.min_foot_visibility},
      {"feet_points", feet},
      {"coco17", d.response["keypoints"]}};
}

// The detector's segmentation, carried onto the photo's edges (guided filter), thresholded.
void mask_from_detection(const Detection& d, const PerceiveOptions& opts, Subject& s,
                         PerceiveReport& rep) {
  Image prob = d.mask_prob;
  const double cell = d.response.value("segmentation_scale", 0.0);
  if (opts.refine_mask && cell > 1.0) {
    const int radius = std::max(1, int(std::lround(opts.refine_radius_cells * cell)));
    prob = guided_filter(s.photo.rgb, prob, radius, opts.refine_eps);
  }
  s.mask = threshold_mask(prob, opts.mask_threshold);
  rep.mask_source = "detector";
  s.info["mask"] = {{"source", "detector"},
                    {"model", "blazepose-full segmentation"},
                    {"segmentation_cell_px", cell},
                    {"guided_filter",
                     opts.refine_mask ? nlohmann::json({{"radius_cells", opts.refine_radius_cells},
                                                        {"eps", opts.refine_eps}})
                                      : nlohmann::json(nullptr)},
                    {"threshold", opts.mask_threshold}};
}

// No face where the keypoints put one: the head is seen from behind or the side, and a nose or
// eyes there sit on the hair or a cap (the fit would turn the head round).
void drop_face_points(Body25& body, PerceiveReport& rep) {
  bool dropped = false;
  for (int k : {body25::kNose, body25::kREye, body25::kLEye})
    if (body[size_t(k)].present()) {
      body[size_t(k)] = Keypoint2D{};
      dropped = true;
    }
  if (dropped)
    rep.notes.push_back(
        "nose and eyes left out: no face found (the head is seen from "
        "behind or the side)");
}

// Runs the detector and takes from it what the user did not give: keypoints, mask, face.
void detect(PerceiveHelper& helper, const std::string& dir, const std::string& photo,
            const PerceiveOptions& opts, bool want_face, Subject& s, PerceiveReport& rep) {
  const Detection d = run_detector(helper, s.photo.rgb, photo, opts);
  const auto& r = d.response;
  rep.people = r.value("people", 0);
  if (r.contains("warnings") && r["warnings"].is_array())
    for (const auto& w : r["warnings"])
      if (w.is_string()) rep.notes.push_back(w.get<std::string>());
  s.info["detector"] = detector_info(dir, helper, r, rep.people);
  if (!s.have_keypoints) keypoints_from_detection(d, opts, s, rep);
  if (s.mask.empty()) mask_from_detection(d, opts, s, rep);
  if (want_face && d.face_mesh.empty() && rep.keypoints_source == "detector")
    drop_face_points(s.person.body, rep);
  if (want_face && !d.face_mesh.empty()) {
    s.person.face = face70_from_facemesh(d.face_mesh, d.face_score);
    s.info["face"] = {{"source", "detector"},
                      {"model", "blazeface + facemesh (468 landmarks -> OpenPose face 70)"},
                      {"score", d.face_score}};
  }
}

// The detector for what the user's files left out (keypoints, mask, face); perceive.json's
// "detector" and "face".
// `warm`: a helper the caller keeps running (none: one is started here).
void detect_missing(const std::string& photo, const PerceiveOptions& opts, Subject& s,
                    PerceiveReport& rep, PerceiveHelper* warm) {
  const bool need_detector = !s.have_keypoints || s.mask.empty();
  const bool want_face = opts.face && s.person.face.empty();
  s.info["detector"] = nullptr;
  if (warm && (need_detector || want_face)) {
    detect(*warm, warm->dir(), photo, opts, want_face, s, rep);
  } else if (need_detector || want_face) {
    std::string dir;
    const std::unique_ptr<PerceiveHelper> helper = start_helper(opts, need_detector, dir, rep);
    if (helper) detect(*helper, dir, photo, opts, want_face, s, rep);
  }
  if (!s.info.contains("face"))
    s.info["face"] =
        s.person.face.empty() ? nlohmann::json(nullptr) : nlohmann::json({{"source", "user"}});
}

// The person must be there and big enough, with enough body keypoints.
Box check_person(const std::string& photo, const PerceiveOptions& opts, Subject& s,
                 PerceiveReport& rep) {
  const Box box = mask_box(s.mask);
  if (box.empty())
    throw Error(rep.mask_source == "detector"
                    ? "perceive: no person found in " + photo + " (the detector's mask is empty)"
                    : "perceive: the mask (" + rep.mask_source + ") has no person pixels");
  if (box.longer() < opts.min_person_size)
    throw Error("perceive: the person in " + photo +
                " is too small: " + std::to_string(box.x1 - box.x0 + 1) + "x" +
                std::to_string(box.y1 - box.y0 + 1) + " px in the " +
                std::to_string(s.photo.rgb.width) + "x" + std::to_string(s.photo.rgb.height) +
                " image; at least " + std::to_string(opts.min_person_size) +
                " px along its longer side is needed (crop the photo around the person)");
  derive_neck_and_midhip(s.person.body);
  rep.body_keypoints = count_present(s.person.body);
  if (rep.body_keypoints < kMinBodyKeypoints)
    throw Error("perceive: no person found in " + photo + ": only " +
                std::to_string(rep.body_keypoints) + " body keypoints are confident enough");
  return box;
}

// The subject folder, written atomically; perceive.json last, with the time since t0.
void write_subject(const std::string& out_dir, const PerceiveOptions& opts,
                   std::chrono::steady_clock::time_point t0, Subject& s, PerceiveReport& rep) {
  const Photo& p = s.photo;
  StagedDir staged(out_dir);
  Image mask8(p.rgb.width, p.rgb.height, 1);
  for (size_t i = 0; i < s.mask.data.size(); ++i)
    mask8.data[i] = s.mask.data[i] > 0.5f ? 1.0f : 0.0f;
  write_png(staged.path("image.png"), p.rgb, p.bit_depth == 16 ? 16 : 8);
  write_png(staged.path("mask.png"), mask8, 8);
  write_openpose(staged.path("keypoints.json"), s.person);
  if (opts.overlay)
    write_png(staged.path("perceive_overlay.png"), perceive_overlay(p.rgb, mask8, s.person), 8);
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  s.info["time_s"] = rep.seconds;
  write_json_atomic(staged.path("perceive.json"), s.info);
  staged.commit();
}

PerceiveReport perceive_photo(const std::string& photo, const std::string& out_dir,
                              const PerceiveOptions& opts, PerceiveHelper* warm) {
  const auto t0 = std::chrono::steady_clock::now();
  check_request(out_dir, opts);
  PerceiveReport rep;
  rep.out_dir = out_dir;

  Subject s;
  s.photo = load_photo(photo, opts.max_size);
  rep.width = s.photo.rgb.width;
  rep.height = s.photo.rgb.height;
  rep.source_width = s.photo.source_width;
  rep.source_height = s.photo.source_height;
  s.info = photo_info(photo, s.photo);

  // The user's keypoints and mask (or the photo's alpha) win; the detector gives the rest.
  if (!opts.keypoints_path.empty()) read_user_keypoints(opts, s, rep);
  read_user_mask(opts, s, rep);
  detect_missing(photo, opts, s, rep, warm);

  const Box box = check_person(photo, opts, s, rep);
  rep.face = !s.person.face.empty();
  s.info["person_box"] = {box.x0, box.y0, box.x1 + 1, box.y1 + 1};
  s.info["keypoints"]["present"] = keypoint_list(s.person.body);
  s.info["notes"] = rep.notes;

  write_subject(out_dir, opts, t0, s, rep);
  return rep;
}

}  // namespace

PerceiveReport run_perceive(const std::string& photo, const std::string& out_dir,
                            const PerceiveOptions& opts) {
  return perceive_photo(photo, out_dir, opts, nullptr);
}

PerceiveReport run_perceive(const std::string& photo, const std::string& out_dir,
                            const PerceiveOptions& opts, PerceiveHelper& helper) {
  return perceive_photo(photo, out_dir, opts, &helper);
}

}  // namespace ks

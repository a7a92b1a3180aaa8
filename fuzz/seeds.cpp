// Writes the fuzzers' seed corpora with the project's own writers (no binary seeds in git):
//   fuzz_seeds OUT_DIR  ->  OUT_DIR/fuzz_<name>/<seed files>
// Every seed is small (a 3-vertex body model, a 6-Gaussian avatar, 8x6 images) so that libFuzzer's
// mutations stay fast.
#include <zlib.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "avatar/avatar.hpp"
#include "avatar/from_body.hpp"
#include "avatar/tiny_avatar.hpp"
#include "body/body_model.hpp"
#include "core/camera.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "fit/fit_file.hpp"
#include "gaussians/ply.hpp"
#include "gltf/glb.hpp"
#include "io/image_io.hpp"
#include "io/npz.hpp"
#include "motion/bvh_motion.hpp"
#include "perceive/openpose.hpp"

namespace fs = std::filesystem;
using namespace ks;

namespace {

fs::path out_root;

std::string seed(const std::string& harness, const std::string& name) {
  const fs::path d = out_root / harness;
  fs::create_directories(d);
  return (d / name).string();
}

void put(const std::string& harness, const std::string& name, const std::vector<uint8_t>& b) {
  write_file_atomic(seed(harness, name), b.data(), b.size());
}

// A tiny body model with `J` joints (a chain) and 3 vertices, saved by save_body_model.
BodyModel tiny_model(int J, bool posedirs) {
  BodyModel m;
  m.kind = J == 24 ? BodyKind::kSMPL : J == 52 ? BodyKind::kSMPLH : BodyKind::kSMPLX;
  m.v_template.resize(3, 3);
  m.v_template << 0, 0, 0, 0.1, 0.5, 0, -0.1, 1.0, 0.05;
  m.faces.resize(1, 3);
  m.faces << 0, 1, 2;
  m.num_betas = 2;
  m.shapedirs = Eigen::MatrixXd::Constant(9, 2, 0.01);
  m.posedirs = posedirs ? Eigen::MatrixXd::Constant(9, 9 * (J - 1), 0.001)
                        : Eigen::MatrixXd::Zero(9, 9 * (J - 1));
  m.J_regressor = Eigen::MatrixXd::Constant(J, 3, 1.0 / 3);
  m.weights = Eigen::MatrixXd::Zero(3, J);
  for (int v = 0; v < 3; ++v) m.weights(v, (v * 7) % J) = 1.0;
  m.parents.resize(size_t(J));
  for (int j = 0; j < J; ++j) m.parents[size_t(j)] = j - 1;
  m.joint_names = body_joint_names(m.kind);
  m.part_labels = part_labels_from_weights(m.weights, m.kind);
  m.update_posedirs_flag();
  return m;
}

Image gradient_image(int w, int h, int c) {
  Image img(w, h, c);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < c; ++k) img.at(x, y, k) = float((x + 2 * y + 3 * k) % 7) / 6.f;
  return img;
}

std::vector<uint8_t> file_bytes(const std::string& p) {
  return read_file_bytes(p);
}

// The TIFF block of an EXIF segment holding only an orientation tag.
std::vector<uint8_t> tiff_orientation_block(int o, bool little) {
  std::vector<uint8_t> t;
  auto u16 = [&](uint32_t v) {
    if (little) {
      t.push_back(uint8_t(v));
      t.push_back(uint8_t(v >> 8));
    } else {
      t.push_back(uint8_t(v >> 8));
      t.push_back(uint8_t(v));
    }
  };
  auto u32 = [&](uint32_t v) {
    if (little) {
      u16(v & 0xffff);
      u16(v >> 16);
    } else {
      u16(v >> 16);
      u16(v & 0xffff);
    }
  };
  t.push_back(little ? 'I' : 'M');
  t.push_back(little ? 'I' : 'M');
  u16(42);
  u32(8);
  u16(1);       // one entry
  u16(0x0112);  // orientation
  u16(3);       // SHORT
  u32(1);
  u16(uint32_t(o));
  u16(0);
  u32(0);  // no next IFD
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_seeds OUT_DIR\n");
    return 2;
  }
  out_root = argv[1];
  try {
    // npz: stored and deflated, every dtype the reader takes.
    {
      std::map<std::string, NpyArray> a;
      const double d[6] = {1, -2, 3.5, 0, 1e-3, 7};
      const int64_t n[6] = {0, 1, 2, 3, 250, 9};
      a["f8"] = NpyArray::from_doubles({2, 3}, d);
      a["f4"] = NpyArray::from_doubles({3, 2}, d, true);
      a["i4"] = NpyArray::from_ints({6}, n, 'i', 4);
      a["u1"] = NpyArray::from_ints({2, 1, 3}, n, 'u', 1);
      a["i8"] = NpyArray::from_ints({}, n + 4, 'i', 8);
      a["empty"] = NpyArray::from_doubles({0, 3}, d);
      put("fuzz_npz", "stored.npz", npz_bytes(a, false));
      put("fuzz_npz", "deflated.npz", npz_bytes(a, true));
      std::map<std::string, NpyArray> one;
      one["x"] = NpyArray::from_doubles({6}, d);
      put("fuzz_npz", "one_stored.npz", npz_bytes(one, false));
    }
    // Body models (3 vertices; SMPL / SMPL+H / SMPL-X joint counts), saved by save_body_model.
    save_body_model(seed("fuzz_body_model", "smpl.npz"), tiny_model(24, false));
    save_body_model(seed("fuzz_body_model", "smpl_posedirs.npz"), tiny_model(24, true));
    save_body_model(seed("fuzz_body_model", "smplh.npz"), tiny_model(52, false));
    save_body_model(seed("fuzz_body_model", "smplx.npz"), tiny_model(55, false));
    // .ply: SH degree 0 and 1, extra properties.
    {
      Avatar a = test::tiny_avatar(0);
      write_ply(seed("fuzz_ply", "deg0.ply"), a.gaussians);
      Avatar b = test::tiny_avatar(1);
      PlyExtra ex;
      ex.names = {"extra_a", "extra_b"};
      ex.values.assign(2 * b.gaussians.size(), 0.25f);
      write_ply(seed("fuzz_ply", "deg1_extra.ply"), b.gaussians, &ex);
      Gaussians g;
      g.resize(0);
      write_ply(seed("fuzz_ply", "empty.ply"), g);
    }
    // Avatars: the tiny test avatar (SH 0 and 1), and one from the tiny body model (posedirs).
    {
      save_avatar(seed("fuzz_avatar", "tiny.ksavatar"), test::tiny_avatar(0));
      save_avatar(seed("fuzz_avatar", "tiny_sh1.ksavatar"), test::tiny_avatar(1));
      const BodyModel m = tiny_model(24, true);
      save_avatar(seed("fuzz_avatar", "from_body.ksavatar"),
                  avatar_from_body(m, Eigen::VectorXd::Zero(2)));
    }
    // Cameras.
    const Camera cam = Camera::look_at_fov({0.3, 1.0, 3.0}, {0, 0.9, 0}, 8, 6, 40.0);
    cam.save(seed("fuzz_camera", "camera.json"));
    Camera::look_at({0, 0, -2}, {0, 0, 0}, {0, 1, 0}, 640, 480, 500, 510, 320, 240)
        .save(seed("fuzz_camera", "camera_b.json"));
    // Body parameters (PARAMS.json), by BodyParams::to_json.
    {
      BodyParams p;
      p.betas = Eigen::VectorXd::Constant(2, 0.0);
      p.global_orient = Eigen::Vector3d(0.1, 0, 0);
      p.body_pose = Eigen::VectorXd::Constant(69, 0.02);
      p.transl = Eigen::Vector3d(0, 0.1, 0);
      write_json_atomic(seed("fuzz_params", "smpl.json"), p.to_json());
      BodyParams x;
      x.body_pose = Eigen::VectorXd::Constant(63, -0.01);
      x.jaw_pose = Eigen::Vector3d(0.2, 0, 0);
      x.left_hand_pose = Eigen::VectorXd::Constant(45, 0.1);
      x.right_hand_pose = Eigen::VectorXd::Constant(45, -0.1);
      x.expression = Eigen::VectorXd::Constant(3, 0.0);
      write_json_atomic(seed("fuzz_params", "smplx.json"), x.to_json());
    }
    // dataset.json (the harness's directory has img.png, mask.png and model.npz).
    {
      Dataset d;
      d.betas = Eigen::VectorXd::Constant(3, 0.1);
      for (int i = 0; i < 2; ++i) {
        DatasetFrame f;
        f.image = "img.png";
        if (i == 1) f.mask = "mask.png";
        f.pose.body_pose = Eigen::VectorXd::Constant(69, 0.01 * i);
        f.pose.global_orient = Eigen::Vector3d(0, 0.5 * i, 0);
        f.camera = cam;
        f.weight = i == 1 ? 2.0 : 1.0;
        d.frames.push_back(f);
      }
      write_json_atomic(seed("fuzz_dataset", "default.json"), d.to_json());
      d.body_model = "model.npz";
      d.frames[0].pose.body_pose = Eigen::VectorXd::Zero(63);
      d.frames[1].pose.body_pose = Eigen::VectorXd::Zero(63);
      d.frames[1].pose.left_hand_pose = Eigen::VectorXd::Zero(45);
      d.frames[1].pose.jaw_pose = Eigen::Vector3d(0.1, 0, 0);
      write_json_atomic(seed("fuzz_dataset", "smplx.json"), d.to_json());
    }
    // AMASS motions: SMPL+H, SMPL-X, SMPL; with and without a frame rate.
    for (int D : {156, 165, 72}) {
      const int N = 3;
      std::vector<double> poses(size_t(N * D)), trans(size_t(N * 3));
      for (size_t i = 0; i < poses.size(); ++i) poses[i] = 0.01 * double(i % 17);
      for (size_t i = 0; i < trans.size(); ++i) trans[i] = 0.1 * double(i);
      std::map<std::string, NpyArray> a;
      a["poses"] = NpyArray::from_doubles({N, D}, poses.data(), D == 72);
      a["trans"] = NpyArray::from_doubles({N, 3}, trans.data());
      const std::string name = "amass_" + std::to_string(D);
      put("fuzz_amass", name + "_nofps.npz", npz_bytes(a, D != 165));
      const double fps = 60;
      a[D == 165 ? "mocap_frame_rate" : "mocap_framerate"] = NpyArray::from_doubles({}, &fps);
      put("fuzz_amass", name + ".npz", npz_bytes(a, true));
    }
    // BVH: the default body's skeleton as `export --bvh` writes it (two frames), and a small
    // Mixamo-named chain with an End Site and a root without position channels.
    {
      const BodyModel& m = default_body_model();
      BodyParams zero;
      zero.betas = Eigen::VectorXd::Zero(m.num_betas);
      zero.body_pose = Eigen::VectorXd::Zero(3 * m.num_body_pose_joints());
      const BodyState rest = body_forward(m, zero);
      std::vector<Eigen::MatrixXd> poses(2, Eigen::MatrixXd::Zero(m.num_joints(), 3));
      poses[1](1, 0) = 0.4;
      poses[1](18, 2) = -0.6;
      const std::vector<Eigen::Vector3d> transl = {Eigen::Vector3d::Zero(),
                                                   Eigen::Vector3d(0.02, 0, 0.05)};
      const std::string text =
          format_bvh(poses_to_bvh(m.parents, m.joint_names, rest.rest_joints, poses, transl, 30));
      put("fuzz_bvh", "smpl.bvh", std::vector<uint8_t>(text.begin(), text.end()));
      const std::string mixamo =
          "HIERARCHY\nROOT mixamorig:Hips\n{\n OFFSET 0 100 0\n CHANNELS 3 Zrotation Xrotation "
          "Yrotation\n JOINT mixamorig:LeftUpLeg\n {\n  OFFSET 10 -5 0\n  CHANNELS 3 Zrotation "
          "Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 -40 0\n  }\n }\n}\nMOTION\nFrames: "
          "2\nFrame Time: 0.0333333\n0 0 0 0 0 0\n10 -5 2.5 30 0 0\n";
      put("fuzz_bvh", "mixamo_chain.bvh", std::vector<uint8_t>(mixamo.begin(), mixamo.end()));
    }
    // GLB: a container with float, byte and short accessors and a JSON chunk that uses them.
    {
      GlbBuilder b;
      b.gltf["asset"] = {{"version", "2.0"}};
      b.add_floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3", kGltfArrayBuffer, true);
      b.add_uints({0, 1, 2, 3}, "VEC4", kGltfUnsignedByte, kGltfArrayBuffer);
      b.add_uints({0, 1, 2}, "SCALAR", kGltfUnsignedShort, kGltfElementArrayBuffer);
      b.add_floats({0.f, 0.5f}, "SCALAR", 0, true);
      put("fuzz_glb", "accessors.glb", b.finish());
    }
    // Keypoints: OpenPose BODY_25 with a face (write_openpose), COCO-18, COCO annotations and
    // results, DWPose's normalised canvas.
    {
      PersonKeypoints p;
      for (int k = 0; k < kBody25Count; ++k)
        p.body[size_t(k)] = {10.0 + k, 20.0 + 2 * k, k % 5 == 0 ? 0.0 : 0.9};
      p.face.resize(kFace70Size);
      for (int k = 0; k < kFace70Size; ++k) p.face[size_t(k)] = {50.0 + k % 10, 5.0 + k / 10, 0.8};
      write_openpose(seed("fuzz_keypoints", "body25_face.json"), p);
      nlohmann::json coco18 = {{"people", nlohmann::json::array()}};
      nlohmann::json dw = {
          {"people", nlohmann::json::array()}, {"canvas_width", 64}, {"canvas_height", 48}};
      std::vector<double> k18, k18n, c17, c17r;
      for (int k = 0; k < kCoco18Size; ++k) {
        k18.insert(k18.end(), {5.0 * k, 3.0 * k, 0.7});
        k18n.insert(k18n.end(), {0.05 * k, 0.04 * k, 0.9});
      }
      for (int k = 0; k < kCoco17Size; ++k) {
        c17.insert(c17.end(), {4.0 * k, 6.0 * k, double(k % 3)});
        c17r.insert(c17r.end(), {4.0 * k, 6.0 * k, 0.5});
      }
      coco18["people"].push_back({{"pose_keypoints_2d", k18}});
      coco18["people"].push_back({{"pose_keypoints_2d", k18}});
      dw["people"].push_back({{"pose_keypoints_2d", k18n}});
      write_json_atomic(seed("fuzz_keypoints", "coco18.json"), coco18);
      write_json_atomic(seed("fuzz_keypoints", "dwpose.json"), dw);
      write_json_atomic(seed("fuzz_keypoints", "coco_annotations.json"),
                        {{"annotations", {{{"keypoints", c17}}}}});
      write_json_atomic(seed("fuzz_keypoints", "coco_results.json"),
                        nlohmann::json::array({{{"keypoints", c17r}, {"score", 0.9}}}));
    }
    // fit.json: save_fit, with the default model and with a body model file next to it.
    {
      FitResult r;
      r.params.betas = Eigen::VectorXd::Constant(2, 0.1);
      r.params.body_pose = Eigen::VectorXd::Constant(69, 0.03);
      r.camera = cam;
      r.costs = {{"keypoints", 1.5}, {"silhouette", 0.25}};
      save_fit(seed("fuzz_fit_json", "fit_default.json"), "default", r);
      save_fit(seed("fuzz_fit_json", "fit_extra.json"), "default", r, {{"note", "x"}});
    }
    // Images: PNG 8/16-bit, grey / RGB / RGBA (write_png), JPEG with EXIF orientation, PNG with
    // an eXIf chunk.
    {
      write_png(seed("fuzz_image", "rgb8.png"), gradient_image(8, 6, 3), 8);
      write_png(seed("fuzz_image", "grey16.png"), gradient_image(8, 6, 1), 16);
      write_png(seed("fuzz_image", "rgba8.png"), gradient_image(6, 8, 4), 8);
      // JPEG (OpenCV's writer, as perceive's tests use), then an APP1 Exif segment after SOI.
      const std::string jp = seed("fuzz_image", "plain.jpg");
      cv::Mat m(6, 8, CV_8UC3, cv::Scalar(30, 120, 200));
      cv::imwrite(jp, m, {cv::IMWRITE_JPEG_QUALITY, 50});
      std::vector<uint8_t> jpg = file_bytes(jp);
      for (int o : {6, 3}) {
        const auto tiff = tiff_orientation_block(o, o == 6);
        std::vector<uint8_t> app1 = {0xFF, 0xE1, 0, 0, 'E', 'x', 'i', 'f', 0, 0};
        app1.insert(app1.end(), tiff.begin(), tiff.end());
        const size_t len = app1.size() - 2;
        app1[2] = uint8_t(len >> 8);
        app1[3] = uint8_t(len);
        std::vector<uint8_t> j2(jpg.begin(), jpg.begin() + 2);
        j2.insert(j2.end(), app1.begin(), app1.end());
        j2.insert(j2.end(), jpg.begin() + 2, jpg.end());
        put("fuzz_image", "exif" + std::to_string(o) + ".jpg", j2);
      }
      // PNG with an eXIf chunk right after IHDR (8 signature + 25 IHDR bytes).
      std::vector<uint8_t> png = file_bytes(seed("fuzz_image", "rgb8.png"));
      const auto tiff = tiff_orientation_block(8, false);
      std::vector<uint8_t> chunk;
      const uint32_t len = uint32_t(tiff.size());
      for (int s = 24; s >= 0; s -= 8) chunk.push_back(uint8_t(len >> s));
      const uint8_t type[4] = {'e', 'X', 'I', 'f'};
      chunk.insert(chunk.end(), type, type + 4);
      chunk.insert(chunk.end(), tiff.begin(), tiff.end());
      uLong crc = crc32(0L, chunk.data() + 4, uInt(4 + tiff.size()));
      for (int s = 24; s >= 0; s -= 8) chunk.push_back(uint8_t(crc >> s));
      png.insert(png.begin() + 33, chunk.begin(), chunk.end());
      put("fuzz_image", "exif8.png", png);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}

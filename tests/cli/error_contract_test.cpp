// The command line's error contract (docs/robustness.md), for every command that reads a file: a
// bad input gives exactly one line `error: ...` on stderr naming the file, nothing on stdout, exit
// status 1 (never a signal), and nothing written or half-written anywhere. The bad inputs: a
// missing file, an empty file, a directory where a file is expected, bytes of another kind, huge
// counts in headers (which must not be allocated), NaN / infinite numbers, wrong image sizes.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <zlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>

#include "avatar/avatar.hpp"
#include "avatar/tiny_avatar.hpp"
#include "body/body_model.hpp"
#include "cli_run.hpp"
#include "core/camera.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "fit/fit_file.hpp"
#include "gaussians/ply.hpp"
#include "io/image_io.hpp"
#include "io/npz.hpp"
#include "perceive/openpose.hpp"
#include "sample/poses_file.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

using test::CliRun;
using test::run_cli;

// ---------------------------------------------------------------------------------------------
// Checking one run.

// Every file under `root` with its size (directories too, size -1).
std::map<std::string, int64_t> snapshot(const fs::path& root) {
  std::map<std::string, int64_t> s;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    const std::string rel = fs::relative(e.path(), root).string();
    s[rel] = e.is_regular_file() ? int64_t(e.file_size()) : -1;
  }
  return s;
}

std::string diff(const std::map<std::string, int64_t>& a, const std::map<std::string, int64_t>& b) {
  std::string d;
  for (const auto& [k, v] : b)
    if (!a.count(k))
      d += " +" + k;
    else if (a.at(k) != v)
      d += " ~" + k;
  for (const auto& [k, v] : a)
    if (!b.count(k)) d += " -" + k;
  return d;
}

// Runs `args` in a state where `root` holds all inputs and outputs; checks the contract.
void expect_clear_error(const fs::path& root, const std::string& args, const std::string& names) {
  SCOPED_TRACE("kinesplat " + args);
  const auto before = snapshot(root);
  const CliRun r = run_cli(args);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(r.out, "") << "stdout must stay empty on an error";
  EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
  EXPECT_TRUE(!r.err.empty() && r.err.back() == '\n' && r.err.find('\n') == r.err.size() - 1)
      << "not exactly one line:\n"
      << r.err;
  EXPECT_NE(r.err.find(names), std::string::npos) << "does not name " << names << ":\n" << r.err;
  const auto after = snapshot(root);
  EXPECT_TRUE(before == after) << "files changed:" << diff(before, after);
}

// ---------------------------------------------------------------------------------------------
// Bad files.

using Maker = std::function<void(const std::string& path)>;
struct Bad {
  std::string label;
  Maker make;
};

void write_bytes(const std::string& path, const std::string& bytes) {
  write_file_atomic(path, bytes.data(), bytes.size());
}

// What any reader must refuse: missing, empty, a directory, bytes of something else.
std::vector<Bad> any_file() {
  return {
      {"missing", [](const std::string&) {}},
      {"empty", [](const std::string& p) { write_bytes(p, ""); }},
      {"directory", [](const std::string& p) { fs::create_directories(p); }},
      {"garbage",
       [](const std::string& p) { write_bytes(p, std::string("\x01\x02garbage\xff", 11)); }},
  };
}

std::vector<Bad> with(std::vector<Bad> a, const std::vector<Bad>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// JSON text with a number too large for a double (1e999) where `marker` is in `j`'s text: JSON
// has no NaN or infinity, and a number that overflows must be refused, not read as infinity.
void write_json_with_inf(const std::string& path, nlohmann::json j, const std::string& marker) {
  std::string s = j.dump();
  const size_t p = s.find(marker);
  if (p == std::string::npos) std::abort();
  s.replace(p, marker.size(), "1e999");
  write_bytes(path, s);
}

const double kMarker = 123456.5;  // dumped as 123456.5, replaced by 1e999

std::vector<uint8_t> npz_with(const std::map<std::string, NpyArray>& a, bool compress = true) {
  return npz_bytes(a, compress);
}

// An .npz whose one array's header claims `shape` with no data behind it.
std::vector<uint8_t> npz_claiming(const std::string& name, const std::vector<int64_t>& shape) {
  NpyArray a;
  a.kind = 'f';
  a.itemsize = 8;
  a.shape = shape;
  return npz_with({{name, a}}, false);
}

// A deflated .npz whose entry claims ~4 GB uncompressed (the buffer must not be allocated).
std::vector<uint8_t> npz_inflate_bomb_claim() {
  const double v[3] = {1, 2, 3};
  std::vector<uint8_t> b = npz_with({{"v_template", NpyArray::from_doubles({1, 3}, v)}}, true);
  const uint32_t huge = 0xF0000000u;
  for (size_t p = 0; p + 4 <= b.size(); ++p) {
    const uint32_t sig = uint32_t(b[p]) | uint32_t(b[p + 1]) << 8 | uint32_t(b[p + 2]) << 16 |
                         uint32_t(b[p + 3]) << 24;
    const size_t at = sig == 0x04034b50u ? p + 22 : sig == 0x02014b50u ? p + 24 : 0;
    if (at)
      for (int k = 0; k < 4; ++k) b[at + k] = uint8_t(huge >> (8 * k));
  }
  return b;
}

void put(const std::string& path, const std::vector<uint8_t>& b) {
  write_file_atomic(path, b.data(), b.size());
}

BodyModel tiny_model() {
  BodyModel m;
  m.kind = BodyKind::kSMPL;
  m.v_template.resize(3, 3);
  m.v_template << 0, 0, 0, 0.1, 0.5, 0, -0.1, 1.0, 0.05;
  m.faces.resize(1, 3);
  m.faces << 0, 1, 2;
  m.num_betas = 2;
  m.shapedirs = Eigen::MatrixXd::Constant(9, 2, 0.01);
  m.posedirs = Eigen::MatrixXd::Zero(9, 9 * 23);
  m.J_regressor = Eigen::MatrixXd::Constant(24, 3, 1.0 / 3);
  m.weights = Eigen::MatrixXd::Zero(3, 24);
  for (int v = 0; v < 3; ++v) m.weights(v, v) = 1.0;
  m.parents.resize(24);
  for (int j = 0; j < 24; ++j) m.parents[size_t(j)] = j - 1;
  m.joint_names = body_joint_names(m.kind);
  m.part_labels = part_labels_from_weights(m.weights, m.kind);
  return m;
}

std::vector<Bad> bad_body_models() {
  return with(any_file(), {{"npy header claiming 2^40 x 3 elements",
                            [](const std::string& p) {
                              put(p, npz_claiming("v_template", {1LL << 40, 3}));
                            }},
                           {"npy shape whose product overflows",
                            [](const std::string& p) {
                              put(p, npz_claiming("v_template", {1LL << 40, 1LL << 40, 1LL << 40}));
                            }},
                           {"zip entry claiming 4 GB uncompressed",
                            [](const std::string& p) { put(p, npz_inflate_bomb_claim()); }},
                           {"NaN in v_template", [](const std::string& p) {
                              BodyModel m = tiny_model();
                              m.v_template(1, 1) = std::nan("");
                              save_body_model(p, m);
                            }}});
}

std::string ply_header(const std::string& count) {
  std::string h = "ply\nformat binary_little_endian 1.0\nelement vertex " + count + "\n";
  for (const char* n : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    h += std::string("property float ") + n + "\n";
  return h + "end_header\n";
}

std::vector<Bad> bad_plys() {
  return with(any_file(), {{"vertex count 2^62",
                            [](const std::string& p) {
                              write_bytes(
                                  p, ply_header("4611686018427387904") + std::string(68, '\0'));
                            }},
                           {"vertex count 10^9 with one vertex of data",
                            [](const std::string& p) {
                              write_bytes(p, ply_header("1000000000") + std::string(68, '\0'));
                            }},
                           {"NaN mean",
                            [](const std::string& p) {
                              Gaussians g = test::tiny_avatar().gaussians;
                              g.means[4] = std::nanf("");
                              write_ply(p, g);
                            }},
                           {"infinite scale", [](const std::string& p) {
                              Gaussians g = test::tiny_avatar().gaussians;
                              g.log_scales[0] = INFINITY;
                              write_ply(p, g);
                            }}});
}

Camera good_camera() {
  return Camera::look_at_fov({0, 1, 3}, {0, 0.5, 0}, 16, 16, 40);
}

std::vector<Bad> bad_cameras() {
  auto inf_at = [](const std::string& key) {
    return [key](const std::string& p) {
      nlohmann::json j = good_camera().to_json();
      if (key == "t")
        j["t"][1] = kMarker;
      else if (key == "R")
        j["R"][0][0] = kMarker;
      else
        j[key] = kMarker;
      write_json_with_inf(p, j, "123456.5");
    };
  };
  return with(any_file(),
              {{"fx of 1e999", inf_at("fx")},
               {"cy of 1e999", inf_at("cy")},
               {"t of 1e999", inf_at("t")},
               {"R of 1e999", inf_at("R")},
               {"width 1e30", inf_at("width")},
               {"width 2.5",
                [](const std::string& p) {
                  nlohmann::json j = good_camera().to_json();
                  j["width"] = 2.5;
                  write_json_atomic(p, j);
                }},
               {"not an object", [](const std::string& p) { write_bytes(p, "[1, 2]"); }}});
}

// The tiny avatar's file with its header edited (and, optionally, its data section).
std::vector<uint8_t> avatar_with_header(
    const std::function<void(nlohmann::json&)>& edit,
    const std::function<void(nlohmann::json&, std::vector<uint8_t>&)>& edit_data = nullptr) {
  std::vector<uint8_t> b = serialize_avatar(test::tiny_avatar());
  const uint32_t hl =
      uint32_t(b[8]) | uint32_t(b[9]) << 8 | uint32_t(b[10]) << 16 | uint32_t(b[11]) << 24;
  nlohmann::json h = nlohmann::json::parse(b.begin() + 12, b.begin() + 12 + hl);
  edit(h);
  const size_t data_start = (12 + hl + 15) / 16 * 16;
  std::vector<uint8_t> data(b.begin() + data_start, b.end());
  if (edit_data) edit_data(h, data);
  const std::string s = h.dump();
  const size_t new_start = (12 + s.size() + 15) / 16 * 16;
  std::vector<uint8_t> out(new_start, 0);
  std::memcpy(out.data(), b.data(), 8);
  for (int k = 0; k < 4; ++k) out[8 + k] = uint8_t(s.size() >> (8 * k));
  std::memcpy(out.data() + 12, s.data(), s.size());
  out.insert(out.end(), data.begin(), data.end());
  return out;
}

std::vector<Bad> bad_avatars() {
  return with(
      any_file(),
      {{"2^62 Gaussians claimed",
        [](const std::string& p) {
          put(p, avatar_with_header([](nlohmann::json& h) {
                const int64_t n = int64_t(1) << 62;
                h["counts"]["gaussians"] = n;
                for (auto& [name, blk] : h["blocks"].items())
                  if (name != "template_vertices" && name != "template_faces") {
                    blk["shape"][0] = n;
                    blk["size"] = 0;
                  }
              }));
        }},
       {"joint count 1e30",
        [](const std::string& p) {
          put(p, avatar_with_header([](nlohmann::json& h) { h["counts"]["joints"] = 1e30; }));
        }},
       {"block size 1e300",
        [](const std::string& p) {
          put(p,
              avatar_with_header([](nlohmann::json& h) { h["blocks"]["means"]["size"] = 1e300; }));
        }},
       {"NaN mean (with a matching CRC)",
        [](const std::string& p) {
          // The writer refuses NaN: patch the stored float and its block's CRC.
          put(p, avatar_with_header([](nlohmann::json&) {},
                                    [](nlohmann::json& h, std::vector<uint8_t>& data) {
                                      auto& blk = h["blocks"]["means"];
                                      const size_t off = blk["offset"].get<size_t>();
                                      const float nan = std::nanf("");
                                      std::memcpy(&data[off + 4], &nan, 4);
                                      blk["crc32"] = uint32_t(crc32(
                                          0L, data.data() + off, uInt(blk["size"].get<size_t>())));
                                    }));
        }},
       {"truncated", [](const std::string& p) {
          std::vector<uint8_t> b = serialize_avatar(test::tiny_avatar());
          b.erase(b.end() - 40, b.end());
          put(p, b);
        }}});
}

std::vector<Bad> bad_params(bool smpl_sized) {
  const int n = smpl_sized ? 69 : 6;
  return with(any_file(), {{"body_pose value of 1e999",
                            [n](const std::string& p) {
                              std::vector<double> v(size_t(n), 0.0);
                              v[2] = kMarker;
                              write_json_with_inf(p, {{"body_pose", v}}, "123456.5");
                            }},
                           {"body_pose of 70 values",
                            [](const std::string& p) {
                              write_json_atomic(p, {{"body_pose", std::vector<double>(70, 0.0)}});
                            }},
                           {"transl of 2 values",
                            [](const std::string& p) {
                              write_json_atomic(p, {{"transl", {0.0, 1.0}}});
                            }},
                           {"body_pose of strings", [](const std::string& p) {
                              write_json_atomic(p, {{"body_pose", {"a", "b"}}});
                            }}});
}

std::vector<Bad> bad_motions() {
  auto amass = [](int N, int D, double bad_trans) {
    std::vector<double> poses(size_t(N * D), 0.01), trans(size_t(N * 3), 0.0);
    trans[4] = bad_trans;
    const double fps = 60;
    return npz_with({{"poses", NpyArray::from_doubles({N, D}, poses.data())},
                     {"trans", NpyArray::from_doubles({N, 3}, trans.data())},
                     {"mocap_framerate", NpyArray::from_doubles({}, &fps)}});
  };
  return {{"missing", [](const std::string&) {}},
          {"empty", [](const std::string& p) { write_bytes(p, ""); }},
          {"directory", [](const std::string& p) { fs::create_directories(p); }},
          {"garbage", [](const std::string& p) { write_bytes(p, "PK\x03\x04garbage"); }},
          {"NaN in trans", [amass](const std::string& p) { put(p, amass(3, 156, std::nan(""))); }},
          {"infinite trans", [amass](const std::string& p) { put(p, amass(3, 72, INFINITY)); }},
          {"poses claiming 2^40 frames",
           [](const std::string& p) {
             put(p, npz_claiming("poses", {1LL << 40, 156}));
           }},
          {"poses of 100 columns", [](const std::string& p) {
             std::vector<double> poses(300, 0.0), trans(9, 0.0);
             put(p, npz_with({{"poses", NpyArray::from_doubles({3, 100}, poses.data())},
                              {"trans", NpyArray::from_doubles({3, 3}, trans.data())}}));
           }}};
}

void write_image(const std::string& path, int w, int h, int c = 3) {
  Image img(w, h, c, 0.5f);
  write_png(path, img);
}

std::vector<uint8_t> png_claiming(uint32_t w, uint32_t h) {
  std::vector<uint8_t> b = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  auto chunk = [&](const char* type, const std::vector<uint8_t>& data) {
    const uint32_t n = uint32_t(data.size());
    for (int s = 24; s >= 0; s -= 8) b.push_back(uint8_t(n >> s));
    std::vector<uint8_t> td(type, type + 4);
    td.insert(td.end(), data.begin(), data.end());
    b.insert(b.end(), td.begin(), td.end());
    const uint32_t crc = uint32_t(crc32(0L, td.data(), uInt(td.size())));
    for (int s = 24; s >= 0; s -= 8) b.push_back(uint8_t(crc >> s));
  };
  std::vector<uint8_t> ihdr;
  for (uint32_t v : {w, h})
    for (int s = 24; s >= 0; s -= 8) ihdr.push_back(uint8_t(v >> s));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});
  chunk("IHDR", ihdr);
  chunk("IDAT", {0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01});
  chunk("IEND", {});
  return b;
}

std::vector<Bad> bad_images() {
  return with(any_file(), {{"PNG claiming 60000 x 60000 pixels",
                            [](const std::string& p) { put(p, png_claiming(60000, 60000)); }},
                           {"PNG claiming 20000 x 20000 pixels",
                            [](const std::string& p) { put(p, png_claiming(20000, 20000)); }},
                           {"PNG chunk claiming 1 GB",
                            [](const std::string& p) {
                              write_image(p, 16, 16);
                              auto b = read_file_bytes(p);
                              for (int k = 0; k < 4; ++k)  // the chunk after IHDR
                                b[33 + k] = uint8_t(0x40000000u >> (24 - 8 * k));
                              put(p, b);
                            }},
                           {"truncated PNG", [](const std::string& p) {
                              write_image(p, 16, 16);
                              auto b = read_file_bytes(p);
                              b.resize(b.size() / 2);
                              put(p, b);
                            }}});
}

std::vector<Bad> bad_keypoints() {
  return with(any_file(),
              {{"coordinate of 1e999",
                [](const std::string& p) {
                  std::vector<double> k(75, 1.0);
                  k[3] = kMarker;
                  write_json_with_inf(p, {{"people", {{{"pose_keypoints_2d", k}}}}}, "123456.5");
                }},
               {"canvas of 1e999",
                [](const std::string& p) {
                  std::vector<double> k(75, 0.5);
                  write_json_with_inf(p,
                                      {{"canvas_width", kMarker},
                                       {"canvas_height", 10},
                                       {"people", {{{"pose_keypoints_2d", k}}}}},
                                      "123456.5");
                }},
               {"74 numbers",
                [](const std::string& p) {
                  write_json_atomic(
                      p, {{"people", {{{"pose_keypoints_2d", std::vector<double>(74, 1.0)}}}}});
                }},
               {"no people", [](const std::string& p) {
                  write_json_atomic(p, {{"people", nlohmann::json::array()}});
                }}});
}

FitResult good_fit() {
  FitResult r;
  r.params.betas = Eigen::VectorXd::Zero(2);
  r.params.body_pose = Eigen::VectorXd::Zero(69);
  r.camera = good_camera();
  return r;
}

// save_fit's JSON (written to a scratch file and read back).
nlohmann::json read_json_of_fit() {
  static const nlohmann::json j = [] {
    test::TempDir t("ks_contract_fit");
    save_fit(t / "fit.json", "default", good_fit());
    return read_json(t / "fit.json");
  }();
  return j;
}

std::vector<Bad> bad_fits() {
  return with(any_file(), {{"camera focal of 1e999",
                            [](const std::string& p) {
                              nlohmann::json j = read_json_of_fit();
                              j["camera"]["fx"] = kMarker;
                              write_json_with_inf(p, j, "123456.5");
                            }},
                           {"transl of 1e999",
                            [](const std::string& p) {
                              nlohmann::json j = read_json_of_fit();
                              j["params"]["transl"] = {0.0, kMarker, 0.0};
                              write_json_with_inf(p, j, "123456.5");
                            }},
                           {"body_pose of 60 values",
                            [](const std::string& p) {
                              nlohmann::json j = read_json_of_fit();
                              j["params"]["body_pose"] = std::vector<double>(60, 0.0);
                              write_json_atomic(p, j);
                            }},
                           {"body model that is not one", [](const std::string& p) {
                              nlohmann::json j = read_json_of_fit();
                              j["body_model"] = "/dev/null";
                              write_json_atomic(p, j);
                            }}});
}

// A valid one-frame dataset in `dir` (16 x 16 image and mask).
void write_dataset(const std::string& dir) {
  Dataset d;
  DatasetFrame f;
  f.image = "img.png";
  f.mask = "mask.png";
  f.pose.body_pose = Eigen::VectorXd::Zero(69);
  f.camera = good_camera();
  d.frames.push_back(f);
  fs::create_directories(dir);
  write_image(dir + "/img.png", 16, 16);
  write_image(dir + "/mask.png", 16, 16, 1);
  d.save(dir);
}

// Bad datasets: each maker gets the dataset directory; `names` what the error must name.
struct BadDataset {
  std::string label;
  Maker make;
  std::string names;
};

std::vector<BadDataset> bad_datasets() {
  auto edit_json = [](const std::function<void(nlohmann::json&)>& e, bool inf = false) {
    return [e, inf](const std::string& dir) {
      write_dataset(dir);
      nlohmann::json j = read_json(dir + "/dataset.json");
      e(j);
      if (inf)
        write_json_with_inf(dir + "/dataset.json", j, "123456.5");
      else
        write_json_atomic(dir + "/dataset.json", j);
    };
  };
  return {
      {"missing directory", [](const std::string&) {}, "ds"},
      {"a file, not a directory", [](const std::string& d) { write_bytes(d, "x"); }, "ds"},
      {"no dataset.json", [](const std::string& d) { fs::create_directories(d); }, "dataset.json"},
      {"empty dataset.json",
       [](const std::string& d) {
         write_dataset(d);
         write_bytes(d + "/dataset.json", "");
       },
       "dataset.json"},
      {"dataset.json is a directory",
       [](const std::string& d) {
         write_dataset(d);
         fs::remove(d + "/dataset.json");
         fs::create_directories(d + "/dataset.json");
       },
       "dataset.json"},
      {"body_pose value of 1e999",
       edit_json([](nlohmann::json& j) { j["frames"][0]["pose"]["body_pose"][5] = kMarker; }, true),
       "dataset.json"},
      {"camera t of 1e999",
       edit_json([](nlohmann::json& j) { j["frames"][0]["camera"]["t"][2] = kMarker; }, true),
       "dataset.json"},
      {"weight of 1e999",
       edit_json([](nlohmann::json& j) { j["frames"][0]["weight"] = kMarker; }, true),
       "dataset.json"},
      {"body_pose of 66 values", edit_json([](nlohmann::json& j) {
         j["frames"][0]["pose"]["body_pose"] = std::vector<double>(66, 0.0);
       }),
       "dataset.json"},
      {"image of the wrong size",
       [](const std::string& d) {
         write_dataset(d);
         write_image(d + "/img.png", 12, 16);
       },
       "img.png"},
      {"mask of the wrong size",
       [](const std::string& d) {
         write_dataset(d);
         write_image(d + "/mask.png", 16, 20, 1);
       },
       "mask.png"},
      {"empty image file",
       [](const std::string& d) {
         write_dataset(d);
         write_bytes(d + "/img.png", "");
       },
       "img.png"},
      {"image is a directory",
       [](const std::string& d) {
         write_dataset(d);
         fs::remove(d + "/img.png");
         fs::create_directories(d + "/img.png");
       },
       "img.png"},
  };
}

// Runs each bad variant of one input through `command(path)` in a fresh directory.
void check_all(
    const std::string& tag, const std::vector<Bad>& bads, const std::string& file,
    const std::function<void(const test::TempDir&)>& fixtures,
    const std::function<std::string(const test::TempDir&, const std::string&)>& command) {
  for (const Bad& b : bads) {
    SCOPED_TRACE(tag + ": " + b.label);
    test::TempDir t("ks_contract");
    fixtures(t);
    const std::string p = t / file;
    fs::remove_all(p);  // a fixture's good file is replaced by the bad one
    b.make(p);
    expect_clear_error(t.path(), command(t, p), fs::path(file).filename().string());
  }
}

void no_fixtures(const test::TempDir&) {}

// ---------------------------------------------------------------------------------------------

TEST(ErrorContract, Render) {
  auto fixtures = [](const test::TempDir& t) {
    write_ply(t / "scene.ply", test::tiny_avatar().gaussians);
    good_camera().save(t / "cam.json");
  };
  check_all("render scene", bad_plys(), "bad.ply", fixtures, [](auto& t, auto& p) {
    return "render " + p + " --camera " + (t / "cam.json") + " --out " + (t / "o.png");
  });
  check_all("render camera", bad_cameras(), "badcam.json", fixtures, [](auto& t, auto& p) {
    return "render " + (t / "scene.ply") + " --camera " + p + " --out " + (t / "o.png");
  });
}

TEST(ErrorContract, Body) {
  check_all("body info", bad_body_models(), "model.npz", no_fixtures,
            [](auto&, auto& p) { return "body info " + p; });
  check_all("body pose model", bad_body_models(), "model.npz", no_fixtures,
            [](auto& t, auto& p) { return "body pose " + p + " --out " + (t / "o.obj"); });
  check_all("body pose params", bad_params(true), "params.json", no_fixtures, [](auto& t, auto& p) {
    return "body pose default --params " + p + " --out " + (t / "o.obj");
  });
}

TEST(ErrorContract, AnimateExportView) {
  auto fixtures = [](const test::TempDir& t) {
    save_avatar(t / "a.ksavatar", test::tiny_avatar());
    good_camera().save(t / "cam.json");
  };
  check_all("animate avatar", bad_avatars(), "bad.ksavatar", fixtures, [](auto& t, auto& p) {
    return "animate " + p + " --frames 2 --size 16x16 --out " + (t / "frames");
  });
  check_all("animate motion", bad_motions(), "motion.npz", fixtures, [](auto& t, auto& p) {
    return "animate " + (t / "a.ksavatar") + " --motion " + p + " --size 16x16 --out " +
           (t / "frames");
  });
  check_all("animate camera", bad_cameras(), "badcam.json", fixtures, [](auto& t, auto& p) {
    return "animate " + (t / "a.ksavatar") + " --camera " + p + " --frames 2 --size 16x16 --out " +
           (t / "frames");
  });
  check_all("export avatar", bad_avatars(), "bad.ksavatar", fixtures,
            [](auto& t, auto& p) { return "export " + p + " --out " + (t / "o.ply"); });
  check_all("export pose", bad_params(false), "pose.json", fixtures, [](auto& t, auto& p) {
    return "export " + (t / "a.ksavatar") + " --pose " + p + " --out " + (t / "o.ply");
  });
  check_all("view avatar", bad_avatars(), "bad.ksavatar", fixtures,
            [](auto&, auto& p) { return "view " + p + " --port 0"; });
}

TEST(ErrorContract, EvaluateAndReconstructDatasets) {
  for (const BadDataset& b : bad_datasets()) {
    SCOPED_TRACE("dataset: " + b.label);
    for (int cmd = 0; cmd < 2; ++cmd) {
      test::TempDir t("ks_contract");
      save_avatar(t / "a.ksavatar", test::tiny_avatar());
      b.make(t / "ds");
      const std::string args =
          cmd == 0
              ? "evaluate " + (t / "a.ksavatar") + " " + (t / "ds") + " -q -o " + (t / "m.json")
              : "reconstruct " + (t / "ds") + " --iters 1 -q -o " + (t / "out.ksavatar");
      expect_clear_error(t.path(), args, b.names);
    }
  }
}

TEST(ErrorContract, EvaluateAvatar) {
  auto fixtures = [](const test::TempDir& t) { write_dataset(t / "ds"); };
  check_all("evaluate avatar", bad_avatars(), "bad.ksavatar", fixtures, [](auto& t, auto& p) {
    return "evaluate " + p + " " + (t / "ds") + " -q -o " + (t / "m.json");
  });
}

// A subject for `fit`: image.png, mask.png and keypoints.json (a plausible standing person).
void write_subject(const std::string& dir) {
  fs::create_directories(dir);
  write_image(dir + "/image.png", 64, 96);
  write_image(dir + "/mask.png", 64, 96, 1);
  PersonKeypoints p;
  auto set = [&](int k, double x, double y) { p.body[size_t(k)] = {x, y, 0.9}; };
  set(body25::kNose, 32, 12);
  set(body25::kNeck, 32, 22);
  set(body25::kRShoulder, 24, 22);
  set(body25::kLShoulder, 40, 22);
  set(body25::kMidHip, 32, 50);
  set(body25::kRHip, 27, 50);
  set(body25::kLHip, 37, 50);
  set(body25::kRKnee, 27, 70);
  set(body25::kLKnee, 37, 70);
  set(body25::kRAnkle, 27, 90);
  set(body25::kLAnkle, 37, 90);
  write_openpose(dir + "/keypoints.json", p);
}

TEST(ErrorContract, Fit) {
  auto fixtures = [](const test::TempDir& t) { write_subject(t / "subject"); };
  check_all("fit keypoints", bad_keypoints(), "subject/keypoints.json", fixtures,
            [](auto& t, auto&) { return "fit " + (t / "subject") + " -q"; });
  auto images = bad_images();
  images.erase(images.begin());  // a missing image.png: `fit` says so (covered by its own tests)
  check_all("fit image", images, "subject/image.png", fixtures,
            [](auto& t, auto&) { return "fit " + (t / "subject") + " -q"; });
  check_all("fit mask size",
            {{"mask of the wrong size", [](const std::string& p) { write_image(p, 64, 90, 1); }}},
            "subject/mask.png", fixtures,
            [](auto& t, auto&) { return "fit " + (t / "subject") + " -q"; });
  check_all("fit body", bad_body_models(), "model.npz", fixtures,
            [](auto& t, auto& p) { return "fit " + (t / "subject") + " -q --body " + p; });
}

TEST(ErrorContract, Perceive) {
  test::TempDir helper("ks_contract_nohelper");
  ::setenv("KS_PERCEIVE_HELPER", helper.str().c_str(), 1);  // the detector is never needed here
  auto fixtures = [](const test::TempDir& t) {
    write_subject(t / "in");
    fs::remove(t / "in/image.png");
    write_image(t / "photo.png", 64, 96);
  };
  auto args = [](const test::TempDir& t, const std::string& photo, const std::string& kp,
                 const std::string& mask) {
    return "perceive " + photo + " --out " + (t / "subject") + " --no-face --keypoints " + kp +
           " --mask " + mask;
  };
  check_all("perceive photo", bad_images(), "bad.png", fixtures, [&](auto& t, auto& p) {
    return args(t, p, t / "in/keypoints.json", t / "in/mask.png");
  });
  check_all("perceive keypoints", bad_keypoints(), "kp.json", fixtures,
            [&](auto& t, auto& p) { return args(t, t / "photo.png", p, t / "in/mask.png"); });
  check_all("perceive mask",
            with(bad_images(), {{"mask of the wrong size",
                                 [](const std::string& p) { write_image(p, 64, 90, 1); }}}),
            "badmask.png", fixtures,
            [&](auto& t, auto& p) { return args(t, t / "photo.png", t / "in/keypoints.json", p); });
  ::unsetenv("KS_PERCEIVE_HELPER");
}

TEST(ErrorContract, FitFiles) {
  auto fixtures = [](const test::TempDir& t) {
    save_fit(t / "truth.json", "default", good_fit());
    fs::create_directories(t / "subject");
    write_image(t / "subject/image.png", 16, 16);
    write_openpose(t / "kp.json", PersonKeypoints{});
  };
  check_all("evaluate-fit", bad_fits(), "fit.json", fixtures, [](auto& t, auto& p) {
    return "evaluate-fit " + p + " " + (t / "truth.json") + " --out " + (t / "o.json");
  });
  check_all("sample", bad_fits(), "subject/fit.json", fixtures, [](auto& t, auto&) {
    return "sample " + (t / "subject") + " --frames 2 --no-video -q --out " + (t / "prior");
  });
  check_all("calibrate-keypoints truth", bad_fits(), "fit.json", fixtures,
            [](auto& t, auto& p) { return "calibrate-keypoints " + p + " " + (t / "kp.json"); });
  check_all("calibrate-keypoints keypoints", bad_keypoints(), "bad_kp.json", fixtures,
            [](auto& t, auto& p) { return "calibrate-keypoints " + (t / "truth.json") + " " + p; });
}

TEST(ErrorContract, GenerateAndAugment) {
  // generate reads PRIOR/poses.json; augment reads PRIOR/dataset.
  check_all(
      "generate poses.json",
      with(any_file(), {{"fps of 1e999",
                         [](const std::string& p) {
                           write_json_with_inf(p, {{"fps", kMarker}, {"frames", {1}}}, "123456.5");
                         }}}),
      "prior/poses.json", [](const test::TempDir& t) { fs::create_directories(t / "prior"); },
      [](auto& t, auto&) { return "generate " + (t / "prior") + " -q"; });
  for (const BadDataset& b : bad_datasets()) {
    if (b.label == "missing directory" || b.label == "a file, not a directory") continue;
    SCOPED_TRACE("augment dataset: " + b.label);
    test::TempDir t("ks_contract");
    b.make(t / "prior/dataset");
    save_fit(t / "subject/fit.json", "default", good_fit());
    write_image(t / "subject/image.png", 16, 16);
    write_image(t / "subject/mask.png", 16, 16, 1);
    expect_clear_error(
        t.path(),
        "augment " + (t / "prior") + " --subject " + (t / "subject") + " --face-fusion off -q",
        b.names);
  }
}

TEST(ErrorContract, CreatePhoto) {
  // create checks the photo (and everything else) before it makes DIR or runs a stage.
  check_all("create photo", bad_images(), "photo.png", no_fixtures,
            [](auto& t, auto& p) { return "create " + p + " --out " + (t / "out") + " -q"; });
}

// batch reports every problem of a manifest at once: the first line is `error: MANIFEST: N
// problems, nothing was run:`, then one indented line per problem, each naming the manifest.
TEST(ErrorContract, BatchManifest) {
  auto fixtures = [](const test::TempDir& t) { write_image(t / "photo.png", 16, 16); };
  const std::vector<Bad> bads = with(
      any_file(),
      {{"unknown option",
        [](const std::string& p) { write_bytes(p, "id,photo,stepz\na,photo.png,3\n"); }},
       {"duplicate id and missing photo",
        [](const std::string& p) { write_bytes(p, "id,photo\na,photo.png\na,none.png\n"); }},
       {"unterminated quote", [](const std::string& p) { write_bytes(p, "id,photo\n\"a,b\n"); }},
       {"JSON lines with a bad line",
        [](const std::string& p) {
          write_bytes(p, "{\"id\": \"a\", \"photo\": \"photo.png\"}\n{\"id\n");
        }},
       {"header only", [](const std::string& p) { write_bytes(p, "id,photo\n"); }}});
  for (const Bad& b : bads) {
    SCOPED_TRACE("batch manifest: " + b.label);
    test::TempDir t("ks_contract");
    fixtures(t);
    const std::string m = t / "m.csv";
    b.make(m);
    const auto before = snapshot(t.path());
    const CliRun r = run_cli("batch " + m + " --out " + (t / "out") + " --scheduler local");
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_EQ(r.out, "");
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(r.err.back(), '\n');
    size_t start = 0, lines = 0;
    while (start < r.err.size()) {
      const size_t end = r.err.find('\n', start);
      const std::string line = r.err.substr(start, end - start);
      if (lines > 0) {
        EXPECT_EQ(line.rfind("  ", 0), 0u) << "not an indented problem: " << line;
      }
      EXPECT_NE(line.find("m.csv"), std::string::npos) << "does not name m.csv: " << line;
      ++lines;
      start = end + 1;
    }
    const auto after = snapshot(t.path());
    EXPECT_TRUE(before == after) << "files changed:" << diff(before, after);
  }
}

TEST(ErrorContract, Synth) {
  check_all("synth body", bad_body_models(), "model.npz", no_fixtures, [](auto& t, auto& p) {
    return "synth --seed 1 --size 16x24 --frames 1 --body " + p + " --out " + (t / "out");
  });
}

// Floating-point options refuse NaN and infinities (CLI11 parses them; a range check lets NaN
// through): status 1, the option named, nothing written.
TEST(ErrorContract, FloatOptionsAreFinite) {
  test::TempDir t("ks_contract");
  save_avatar(t / "a.ksavatar", test::tiny_avatar());
  write_dataset(t / "ds");
  write_subject(t / "subject");
  struct Case {
    std::string args, option;
  };
  const std::vector<Case> cases = {
      {"reconstruct " + (t / "ds") + " -q --iters 1 -o " + (t / "o.ksavatar") + " --scale nan",
       "--scale"},
      {"reconstruct " + (t / "ds") + " -q --iters 1 -o " + (t / "o.ksavatar") + " --w-l1 inf",
       "--w-l1"},
      {"evaluate " + (t / "a.ksavatar") + " " + (t / "ds") + " -q --scale -inf -o " +
           (t / "m.json"),
       "--scale"},
      {"animate " + (t / "a.ksavatar") + " --backface-cull nan --frames 1 --size 16x16 --out " +
           (t / "f"),
       "--backface-cull"},
      {"fit " + (t / "subject") + " -q --fov nan", "--fov"},
      {"fit " + (t / "subject") + " -q --focal 1e999", "--focal"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    const auto before = snapshot(t.path());
    const CliRun r = run_cli(c.args);
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.err.find(c.option), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("finite"), std::string::npos) << r.err;
    EXPECT_TRUE(before == snapshot(t.path()));
  }
}

}  // namespace
}  // namespace ks

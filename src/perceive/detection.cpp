#include "perceive/detection.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

// A private temporary folder, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "ks-perceive-XXXXXX").string();
    if (!::mkdtemp(tmpl.data()))
      throw Error("perceive: cannot create a temporary folder in " +
                  fs::temp_directory_path().string());
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

double number(const nlohmann::json& j, const std::string& what) {
  if (!j.is_number())
    throw Error("perceive helper: malformed answer (" + what + " is not a number)");
  const double v = j.get<double>();
  if (!std::isfinite(v))
    throw Error("perceive helper: malformed answer (" + what + " is not finite)");
  return v;
}

}  // namespace

Detection run_detector(PerceiveHelper& helper, const Image& rgb, const std::string& photo,
                       const PerceiveOptions& opts) {
  TempDir tmp;
  const std::string rgb_path = tmp.file("image.rgb");
  const std::string mask_path = tmp.file("mask.u8");
  {
    std::vector<uint8_t> bytes(rgb.data.size());
    for (size_t i = 0; i < bytes.size(); ++i)
      bytes[i] = uint8_t(std::lround(std::clamp(rgb.data[i], 0.0f, 1.0f) * 255.0f));
    std::ofstream out(rgb_path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) throw Error("perceive: cannot write " + rgb_path);
  }
  nlohmann::json req = {{"cmd", "detect"},      {"image", rgb_path},     {"width", rgb.width},
                        {"height", rgb.height}, {"mask_out", mask_path}, {"face", opts.face}};
  Detection d;
  d.response = helper.request(req, opts.helper_timeout_s);
  const auto& r = d.response;
  if (!r.value("ok", false)) {
    const std::string code = r.value("code", std::string());
    const std::string err = r.value("error", std::string("(no message)"));
    if (code == "no_person")
      throw Error("perceive: no person found in " + photo + " (" + err + ")");
    throw Error("perceive: the detector failed on " + photo + ": " + err);
  }
  const auto& kp = r["keypoints"];
  if (!kp.is_array() || kp.size() != 17)
    throw Error("perceive helper: malformed answer (keypoints is not 17 entries)");
  for (size_t k = 0; k < 17; ++k) {
    if (!kp[k].is_array() || kp[k].size() != 3)
      throw Error("perceive helper: malformed answer (keypoint " + std::to_string(k) + ")");
    d.coco17.push_back({number(kp[k][0], "x"), number(kp[k][1], "y"), number(kp[k][2], "score")});
  }
  const std::vector<uint8_t> mb = read_file_bytes(mask_path);
  if (mb.size() != rgb.pixel_count())
    throw Error("perceive helper: its mask has " + std::to_string(mb.size()) + " bytes, not " +
                std::to_string(rgb.pixel_count()));
  d.mask_prob = Image(rgb.width, rgb.height, 1);
  for (size_t i = 0; i < mb.size(); ++i) d.mask_prob.data[i] = mb[i] / 255.0f;
  if (r.contains("blazepose")) {
    const auto& bp = r["blazepose"];
    if (!bp.is_array() || bp.size() != 33)
      throw Error("perceive helper: malformed answer (blazepose is not 33 landmarks)");
    for (const auto& p : bp) {
      if (!p.is_array() || p.size() != 4)
        throw Error(
            "perceive helper: malformed answer (a blazepose landmark is not [x, y, visibility, "
            "presence])");
      d.blazepose.push_back({number(p[0], "blazepose x"), number(p[1], "blazepose y"),
                             number(p[2], "blazepose visibility"),
                             number(p[3], "blazepose presence")});
    }
  }
  if (r.contains("face") && r["face"].is_object()) {
    const auto& f = r["face"];
    const auto& lm = f["landmarks"];
    if (!lm.is_array() || lm.size() != 468)
      throw Error("perceive helper: malformed answer (face landmarks are not 468 points)");
    for (const auto& p : lm) {
      if (!p.is_array() || p.size() < 2)
        throw Error("perceive helper: malformed answer (a face landmark is not [x, y])");
      d.face_mesh.push_back({number(p[0], "face x"), number(p[1], "face y")});
    }
    d.face_score = f.contains("mesh_score") ? number(f["mesh_score"], "face score") : 1.0;
  }
  return d;
}

}  // namespace ks

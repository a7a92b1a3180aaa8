#include "web/web_export.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "animate/framing.hpp"
#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "web/skinned_ply.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

const char* const kBundleFiles[] = {"index.html", "kinesplat-viewer.js"};

bool is_bundle(const fs::path& dir) {
  std::error_code ec;
  for (const char* f : kBundleFiles)
    if (!fs::is_regular_file(dir / f, ec)) return false;
  return true;
}

fs::path executable_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe.parent_path();
}

double round6(double v) {
  return std::round(v * 1e6) / 1e6;
}

// A file name for a motion: letters, digits, '-', '_' kept, anything else '_'.
std::string file_stem(const std::string& name) {
  std::string s;
  for (char c : name) s += (std::isalnum(static_cast<unsigned char>(c)) || c == '-') ? c : '_';
  return s.empty() ? "motion" : s.substr(0, 64);
}

}  // namespace

std::string find_viewer_bundle() {
  std::vector<fs::path> tried;
  if (const char* env = std::getenv("KINESPLAT_VIEWER_DIR"); env && *env) {
    if (is_bundle(env)) return env;
    throw Error(std::string("KINESPLAT_VIEWER_DIR=") + env +
                " does not hold the built viewer (index.html and kinesplat-viewer.js)");
  }
  const fs::path exe = executable_dir();
  if (!exe.empty()) {
    for (const fs::path& p : {exe / ".." / "viewer" / "dist", exe / "viewer",
                              exe / ".." / "share" / "kinesplat" / "viewer"}) {
      const fs::path n = p.lexically_normal();
      if (is_bundle(n)) return n.string();
      tried.push_back(n);
    }
  }
  std::string where;
  for (const auto& p : tried) where += (where.empty() ? "" : ", ") + p.string();
  throw Error(
      "the browser viewer is not built (looked for index.html and kinesplat-viewer.js in " +
      (where.empty() ? std::string("no folder: the program's location is unknown") : where) +
      "): run `make deps` in the source tree (it installs the pinned npm packages and builds "
      "viewer/dist; needs node and npm), or point KINESPLAT_VIEWER_DIR at a built viewer");
}

std::vector<Motion> web_motions(const std::vector<std::string>& extra, std::string* default_name) {
  std::vector<Motion> out;
  for (const auto& info : builtin_motions()) out.push_back(builtin_motion(info.name));
  std::string first;
  for (const auto& name : extra) {
    Motion m = load_motion(name);
    if (m.frames.empty()) throw Error("motion \"" + name + "\" has no frames");
    const bool builtin = std::any_of(builtin_motions().begin(), builtin_motions().end(),
                                     [&](const MotionInfo& i) { return i.name == name; });
    if (!builtin) {
      // Names stay unique in the page's picker.
      const std::string base = m.name;
      for (int k = 2;
           std::any_of(out.begin(), out.end(), [&](const Motion& o) { return o.name == m.name; });
           ++k)
        m.name = base + " (" + std::to_string(k) + ")";
      out.push_back(std::move(m));
    }
    if (first.empty()) first = builtin ? name : out.back().name;
  }
  if (default_name) *default_name = first.empty() ? "turn" : first;
  return out;
}

nlohmann::json web_skeleton_json(const Avatar& a) {
  nlohmann::json j;
  j["format"] = "kinesplat-skeleton";
  j["version"] = 1;
  j["body_kind"] = a.body_kind;
  j["num_joints"] = a.num_joints();
  j["joint_names"] = a.joint_names;
  j["parents"] = a.parents;
  nlohmann::json rest = nlohmann::json::array();
  for (int r = 0; r < a.rest_joints.rows(); ++r)
    rest.push_back(
        {round6(a.rest_joints(r, 0)), round6(a.rest_joints(r, 1)), round6(a.rest_joints(r, 2))});
  j["rest_joints"] = rest;
  j["num_splats"] = a.num_gaussians();
  j["sh_degree"] = a.gaussians.sh_degree;
  j["pose_correctives"] = a.posedirs.size() > 0 ? "skipped" : "none";
  return j;
}

nlohmann::json web_motion_json(const Avatar& a, const Motion& m) {
  const int J = a.num_joints();
  nlohmann::json transforms = nlohmann::json::array(), poses = nlohmann::json::array(),
                 transl = nlohmann::json::array();
  for (const BodyParams& p : m.frames) {
    const std::vector<Eigen::Matrix4d> A = avatar_joint_transforms(a, p);
    std::vector<double> t(size_t(12) * J);
    for (int jj = 0; jj < J; ++jj)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) t[size_t(12) * jj + 4 * r + c] = round6(A[jj](r, c));
    transforms.push_back(t);
    const Eigen::MatrixXd pose = avatar_full_pose(a, p);
    std::vector<double> aa(size_t(3) * J);
    for (int jj = 0; jj < J; ++jj)
      for (int k = 0; k < 3; ++k) aa[size_t(3) * jj + k] = round6(pose(jj, k));
    poses.push_back(aa);
    transl.push_back({round6(p.transl.x()), round6(p.transl.y()), round6(p.transl.z())});
  }
  // Bounds of the posed Gaussian centres (animate/framing.hpp: opaque ones, up to 16 frames).
  Eigen::Vector3d lo, hi;
  motion_bounds(a, m, lo, hi);
  nlohmann::json j;
  j["format"] = "kinesplat-motion";
  j["version"] = 1;
  j["name"] = m.name;
  j["fps"] = m.fps;
  j["num_frames"] = int(m.frames.size());
  j["num_joints"] = J;
  j["bounds"] = {{"min", {round6(lo.x()), round6(lo.y()), round6(lo.z())}},
                 {"max", {round6(hi.x()), round6(hi.y()), round6(hi.z())}}};
  j["transforms"] = std::move(transforms);
  j["poses"] = std::move(poses);
  j["transl"] = std::move(transl);
  return j;
}

void export_web_site(const Avatar& avatar, const std::vector<Motion>& motions,
                     const std::string& dir, const WebExportOptions& opt) {
  avatar.validate("export --web");
  if (motions.empty()) throw Error("export --web: no motions to export");
  if (avatar.num_joints() > 256)
    throw Error("export --web: the avatar has " + std::to_string(avatar.num_joints()) +
                " joints; the browser viewer takes at most 256");
  const fs::path bundle =
      opt.bundle_dir.empty() ? fs::path(find_viewer_bundle()) : fs::path(opt.bundle_dir);
  if (!is_bundle(bundle))
    throw Error("export --web: " + bundle.string() +
                " does not hold the built viewer (index.html and kinesplat-viewer.js)");
  std::error_code ec;
  if (fs::exists(dir, ec)) {
    const bool empty = fs::is_directory(dir, ec) && fs::is_empty(dir, ec);
    const bool earlier = fs::is_regular_file(fs::path(dir) / "skeleton.json", ec) &&
                         fs::is_regular_file(fs::path(dir) / "motions.json", ec);
    if (!empty && !earlier)
      throw Error("export --web: " + dir +
                  " exists and is not an earlier web export; give a new or empty folder");
  }
  StagedDir staged(dir);
  // The viewer's files.
  for (const auto& e : fs::recursive_directory_iterator(bundle)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = e.path().lexically_relative(bundle);
    fs::create_directories((staged.staging() / rel).parent_path());
    fs::copy_file(e.path(), staged.staging() / rel, fs::copy_options::overwrite_existing, ec);
    if (ec) throw Error("export --web: cannot copy " + e.path().string() + ": " + ec.message());
  }
  write_skinned_ply(staged.path("avatar.ply"), avatar);
  write_json_atomic(staged.path("skeleton.json"), web_skeleton_json(avatar));
  nlohmann::json list = nlohmann::json::array();
  std::string default_motion = opt.default_motion;
  for (size_t k = 0; k < motions.size(); ++k) {
    const Motion& m = motions[k];
    if (m.frames.empty()) throw Error("export --web: motion \"" + m.name + "\" has no frames");
    const std::string file = "motions/" + std::to_string(k) + "_" + file_stem(m.name) + ".json";
    write_text_atomic(staged.path(file), web_motion_json(avatar, m).dump() + "\n");
    list.push_back(
        {{"name", m.name}, {"file", file}, {"fps", m.fps}, {"num_frames", int(m.frames.size())}});
  }
  if (default_motion.empty()) default_motion = motions.front().name;
  if (std::none_of(motions.begin(), motions.end(),
                   [&](const Motion& m) { return m.name == default_motion; }))
    throw Error("export --web: the default motion \"" + default_motion + "\" is not exported");
  write_json_atomic(staged.path("motions.json"), {{"format", "kinesplat-motions"},
                                                  {"version", 1},
                                                  {"default", default_motion},
                                                  {"motions", list}});
  staged.commit();
}

}  // namespace ks

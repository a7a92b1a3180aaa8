// Khronos glTF-Validator (npm `gltf-validator`, pinned in tests/gltf/validator/package-lock.json,
// installed by `make deps`) on an exported avatar: the default body's plain avatar with SH degree
// 1 colours and two motions. The mesh export must have 0 errors and 0 warnings; with the splats,
// the only errors allowed are the validator's own gap (it predates KHR_gaussian_splatting). Skips,
// saying why, where node or the package is missing.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "../temp_dir.hpp"
#include "avatar/from_body.hpp"
#include "body/body_model.hpp"
#include "core/fileio.hpp"
#include "gltf/gltf_export.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

// Runs the validator on `glb` and returns its report.
nlohmann::json validate(const fs::path& dir, const std::string& glb) {
  const std::string report = glb + ".report.json";
  const std::string cmd =
      "node '" + (dir / "validate.mjs").string() + "' '" + glb + "' > '" + report + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  const std::string text = read_file_text(report);
  try {
    return nlohmann::json::parse(text);
  } catch (const std::exception&) {
    ADD_FAILURE() << "the validator did not print a report (exit " << rc << "):\n" << text;
    return {{"issues",
             {{"numErrors", -1}, {"numWarnings", -1}, {"messages", nlohmann::json::array()}}}};
  }
}

std::string messages(const nlohmann::json& r) {
  std::ostringstream list;
  for (const auto& m : r["issues"]["messages"])
    list << "  severity " << m.value("severity", -1) << " " << m.value("code", "") << " "
         << m.value("pointer", "") << ": " << m.value("message", "") << "\n";
  return list.str();
}

std::string summary(const nlohmann::json& r) {
  const auto& i = r["issues"];
  return r.value("validatorVersion", "?") + ": " + i["numErrors"].dump() + " errors, " +
         i["numWarnings"].dump() + " warnings, " + i["numInfos"].dump() + " infos, " +
         i["numHints"].dump() + " hints";
}

TEST(GltfValidator, ExportedAvatarHasNoErrors) {
  const fs::path dir = fs::path(KS_SOURCE_DIR) / "tests" / "gltf" / "validator";
  if (std::system("command -v node >/dev/null 2>&1") != 0)
    GTEST_SKIP() << "node is not installed: `make deps` installs it";
  if (!fs::exists(dir / "node_modules" / "gltf-validator" / "package.json"))
    GTEST_SKIP() << "the glTF validator's npm package is not installed (" << dir / "node_modules"
                 << "): run `make deps`";
  const BodyModel& model = default_body_model();
  PlainAvatarOptions opt;
  opt.posedirs = false;
  Avatar a = avatar_from_body(model, Eigen::VectorXd::Zero(2), opt);
  // Some colour variation and view-dependent terms, so every attribute carries real values.
  Gaussians& g = a.gaussians;
  g.sh_degree = 1;
  const int K = g.coeffs();
  g.sh.assign(size_t(g.size()) * size_t(K) * 3, 0.f);
  for (size_t i = 0; i < g.size(); ++i)
    for (int k = 0; k < K; ++k)
      for (int c = 0; c < 3; ++c)
        g.sh[(i * size_t(K) + size_t(k)) * 3 + size_t(c)] =
            (k == 0 ? 1.0f : 0.1f) * float(std::sin(0.01 * double(i) + c + k));
  test::TempDir tmp("gltf_validator");
  const std::vector<Motion> motions = {builtin_motion("walk", 10), builtin_motion("wave", 6)};
  // The mesh alone: no errors, no warnings.
  GltfExportOptions mesh_only;
  mesh_only.splats = false;
  const std::string mesh_glb = (tmp.path() / "mesh.glb").string();
  export_gltf(mesh_glb, a, motions, mesh_only);
  const nlohmann::json mesh_report = validate(dir, mesh_glb);
  const auto& mi = mesh_report["issues"];
  EXPECT_EQ(mi["numErrors"], 0) << messages(mesh_report);
  EXPECT_EQ(mi["numWarnings"], 0) << messages(mesh_report);
  std::printf("mesh + 2 motions: glTF-Validator %s\n%s", summary(mesh_report).c_str(),
              messages(mesh_report).c_str());
  // Mesh and splats: this validator predates KHR_gaussian_splatting, so it reports each of the
  // extension's attribute names as an invalid attribute (core glTF wants application-specific
  // names to start with '_') and the extension as unsupported (an info). Nothing else may appear.
  const std::string full_glb = (tmp.path() / "full.glb").string();
  export_gltf(full_glb, a, motions);
  const nlohmann::json full = validate(dir, full_glb);
  const auto& fi = full["issues"];
  int splat_attribute_errors = 0;
  for (const auto& m : fi["messages"]) {
    const std::string code = m.value("code", ""), ptr = m.value("pointer", "");
    if (m.value("severity", -1) == 0 && code == "MESH_PRIMITIVE_INVALID_ATTRIBUTE" &&
        ptr.find("/attributes/KHR_gaussian_splatting:") != std::string::npos)
      ++splat_attribute_errors;
    else
      EXPECT_TRUE(code == "UNSUPPORTED_EXTENSION" && m.value("severity", -1) >= 2)
          << "unexpected: " << code << " " << ptr << ": " << m.value("message", "");
  }
  // ROTATION, SCALE, OPACITY and SH degrees 0 and 1 (4 coefficients).
  EXPECT_EQ(splat_attribute_errors, 7) << messages(full);
  EXPECT_EQ(fi["numErrors"], splat_attribute_errors) << messages(full);
  EXPECT_EQ(fi["numWarnings"], 0) << messages(full);
  std::printf("mesh + splats + 2 motions: glTF-Validator %s\n%s", summary(full).c_str(),
              messages(full).c_str());
}

}  // namespace
}  // namespace ks

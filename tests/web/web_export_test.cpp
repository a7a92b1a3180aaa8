// `export --web`: the site's files, their formats against the C++ playback, and the CLI wiring.
// A stand-in viewer bundle is used, so these tests need neither npm nor a browser.
#include "web/web_export.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "avatar/pose.hpp"
#include "avatar/tiny_avatar.hpp"
#include "cli_run.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "temp_dir.hpp"
#include "web/skinned_ply.hpp"

namespace fs = std::filesystem;

namespace ks {
namespace {

std::string fake_bundle(const test::TempDir& dir) {
  const fs::path b = dir.path() / "bundle";
  fs::create_directories(b / "extra");
  std::ofstream(b / "index.html") << "<!doctype html>";
  std::ofstream(b / "kinesplat-viewer.js") << "// viewer";
  std::ofstream(b / "extra" / "note.txt") << "copied too";
  return b.string();
}

TEST(WebExport, WritesTheSiteThePlaybackDefines) {
  test::TempDir dir("web_export");
  const Avatar a = test::tiny_avatar();
  std::string def;
  const std::vector<Motion> motions = web_motions({"wave"}, &def);
  EXPECT_EQ(def, "wave");
  ASSERT_EQ(motions.size(), builtin_motions().size());  // a built-in name is not repeated
  WebExportOptions opt;
  opt.bundle_dir = fake_bundle(dir);
  opt.default_motion = def;
  const std::string site = dir / "site";
  export_web_site(a, motions, site, opt);

  for (const char* f : {"index.html", "kinesplat-viewer.js", "extra/note.txt", "avatar.ply",
                        "skeleton.json", "motions.json"})
    EXPECT_TRUE(fs::is_regular_file(fs::path(site) / f)) << f;
  const SkinnedPly ply = read_skinned_ply(site + "/avatar.ply", a.num_joints());
  EXPECT_EQ(ply.gaussians.means, a.gaussians.means);
  EXPECT_EQ(ply.joints, a.skin_joints);

  const nlohmann::json sk = read_json(site + "/skeleton.json");
  EXPECT_EQ(sk["format"], "kinesplat-skeleton");
  EXPECT_EQ(sk["num_joints"], 3);
  EXPECT_EQ(sk["parents"].get<std::vector<int>>(), a.parents);
  EXPECT_EQ(sk["joint_names"].get<std::vector<std::string>>(), a.joint_names);
  EXPECT_DOUBLE_EQ(sk["rest_joints"][2][1].get<double>(), 1.0);
  EXPECT_EQ(sk["num_splats"], a.num_gaussians());
  EXPECT_EQ(sk["pose_correctives"], "none");

  const nlohmann::json list = read_json(site + "/motions.json");
  EXPECT_EQ(list["default"], "wave");
  ASSERT_EQ(list["motions"].size(), motions.size());
  for (size_t k = 0; k < motions.size(); ++k) {
    const auto& e = list["motions"][k];
    EXPECT_EQ(e["name"], motions[k].name);
    const nlohmann::json m = read_json(site + "/" + e["file"].get<std::string>());
    EXPECT_EQ(m["format"], "kinesplat-motion");
    EXPECT_EQ(m["num_frames"], int(motions[k].frames.size()));
    EXPECT_DOUBLE_EQ(m["fps"].get<double>(), motions[k].fps);
    ASSERT_EQ(m["transforms"].size(), motions[k].frames.size());
    ASSERT_EQ(m["poses"].size(), motions[k].frames.size());
    // Every frame's transforms are the C++ playback's A_j (rounded to 1e-6).
    double worst = 0.0;
    for (size_t f = 0; f < motions[k].frames.size(); ++f) {
      const auto A = avatar_joint_transforms(a, motions[k].frames[f]);
      const std::vector<double> t = m["transforms"][f].get<std::vector<double>>();
      ASSERT_EQ(t.size(), 12u * a.num_joints());
      for (int j = 0; j < a.num_joints(); ++j)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 4; ++c)
            worst = std::max(worst, std::abs(t[12 * j + 4 * r + c] - A[j](r, c)));
    }
    EXPECT_LE(worst, 5.1e-7) << motions[k].name;
    // The bounds hold the posed Gaussians of the first frame.
    const Gaussians g = pose_avatar(a, motions[k].frames[0]);
    for (size_t i = 0; i < g.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        EXPECT_GE(g.means[3 * i + c], m["bounds"]["min"][c].get<double>() - 1e-5);
        EXPECT_LE(g.means[3 * i + c], m["bounds"]["max"][c].get<double>() + 1e-5);
      }
  }
}

TEST(WebExport, ReplacesOnlyAnEarlierExport) {
  test::TempDir dir("web_replace");
  const Avatar a = test::tiny_avatar();
  WebExportOptions opt;
  opt.bundle_dir = fake_bundle(dir);
  const std::vector<Motion> motions = {builtin_motion("wave", 4)};
  const std::string site = dir / "site";
  export_web_site(a, motions, site, opt);
  export_web_site(a, motions, site, opt);  // an earlier export is replaced
  EXPECT_TRUE(fs::exists(site + "/avatar.ply"));
  const std::string other = dir / "other";
  fs::create_directories(other);
  std::ofstream(other + "/mine.txt") << "keep";
  EXPECT_THROW(export_web_site(a, motions, other, opt), Error);
  EXPECT_TRUE(fs::exists(other + "/mine.txt"));
  EXPECT_FALSE(fs::exists(other + "/avatar.ply"));
  // Nothing is left behind when the bundle is missing, the motion list empty or the default
  // motion unknown.
  WebExportOptions bad = opt;
  bad.bundle_dir = dir / "nowhere";
  EXPECT_THROW(export_web_site(a, motions, dir / "s2", bad), Error);
  EXPECT_THROW(export_web_site(a, {}, dir / "s3", opt), Error);
  bad = opt;
  bad.default_motion = "nope";
  EXPECT_THROW(export_web_site(a, motions, dir / "s4", bad), Error);
  for (const auto& e : fs::directory_iterator(dir.path())) {
    const std::string n = e.path().filename().string();
    EXPECT_TRUE(n == "bundle" || n == "site" || n == "other") << n;
  }
  EXPECT_THROW(web_motions({"no-such-motion"}), Error);
}

TEST(WebExport, CommandLine) {
  test::TempDir dir("web_cli");
  const std::string avatar = dir / "a.ksavatar";
  save_avatar(avatar, test::tiny_avatar());
  const std::string bundle = fake_bundle(dir);
  ::setenv("KINESPLAT_VIEWER_DIR", bundle.c_str(), 1);  // the child inherits it
  test::CliRun r =
      test::run_cli("export '" + avatar + "' --web '" + (dir / "site") + "' --motion walk");
  ::unsetenv("KINESPLAT_VIEWER_DIR");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.out.find("wrote a web site"), std::string::npos) << r.output;
  EXPECT_EQ(read_json(dir / "site/motions.json")["default"], "walk");
  r = test::run_cli("export '" + avatar + "'");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("give --out FILE.ply or --web DIR"), std::string::npos) << r.output;
  r = test::run_cli("export '" + avatar + "' --out x.ply --web y");
  EXPECT_EQ(r.status, 1) << r.output;
  r = test::run_cli("export '" + avatar + "' --out '" + (dir / "x.ply") + "' --motion walk");
  EXPECT_EQ(r.status, 1) << r.output;  // --motion needs --web
  // A missing bundle says how to build it.
  ::setenv("KINESPLAT_VIEWER_DIR", (dir / "nowhere").c_str(), 1);
  r = test::run_cli("export '" + avatar + "' --web '" + (dir / "site2") + "'");
  ::unsetenv("KINESPLAT_VIEWER_DIR");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("KINESPLAT_VIEWER_DIR"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "site2"));
}

}  // namespace
}  // namespace ks

// `kinesplat export`: an avatar as a standard 3DGS .ply (rest pose, or a pose
// from PARAMS.json), or as a static web site that plays it (--web, src/web/).
#include <cstdio>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "gaussians/ply.hpp"
#include "web/web_export.hpp"

namespace {

ks::cli::CommandGroup group(80, [](CLI::App& app) {
  struct Args {
    std::string avatar, out, pose, web;
    std::vector<std::string> motions;
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "export", "Write an avatar as a standard 3DGS .ply, or as a web page that plays it (--web)");
  sub->add_option("avatar", args->avatar, "Avatar file (from `reconstruct`)")->required();
  auto* out = sub->add_option("--out", args->out, "Output .ply");
  auto* web = sub->add_option("--web", args->web,
                              "Write a static web site playing the avatar into this folder "
                              "(docs/viewer.md) instead of a .ply");
  out->excludes(web);
  sub->add_option("--motion", args->motions,
                  "With --web: a motion to add and start with, a built-in name or an AMASS .npz "
                  "(repeatable; the built-in motions are always included)")
      ->needs(web);
  sub->add_option("--pose", args->pose,
                  "Pose parameters JSON (global_orient, body_pose, transl, "
                  "...); default: rest");
  sub->callback([args] {
    if (args->out.empty() && args->web.empty())
      throw ks::Error("export: give --out FILE.ply or --web DIR");
    const ks::Avatar avatar = ks::load_avatar(args->avatar);
    if (!args->web.empty()) {
      if (!args->pose.empty()) throw ks::Error("export: --pose applies to --out, not --web");
      ks::WebExportOptions opt;
      const auto motions = ks::web_motions(args->motions, &opt.default_motion);
      ks::export_web_site(avatar, motions, args->web, opt);
      std::printf("export: wrote a web site with %d Gaussians and %zu motions to %s/\n",
                  avatar.num_gaussians(), motions.size(), args->web.c_str());
      return;
    }
    ks::Gaussians g;
    if (args->pose.empty()) {
      g = avatar.gaussians;
    } else {
      try {
        const ks::BodyParams p = ks::avatar_params_from_json(avatar, ks::read_json(args->pose));
        g = ks::pose_avatar(avatar, p);
      } catch (const ks::Error& e) {
        const std::string m = e.what();
        throw ks::Error(m.find(args->pose) == std::string::npos ? args->pose + ": " + m : m);
      }
    }
    ks::write_ply(args->out, g);
    std::printf("export: wrote %zu Gaussians (%s pose, SH degree %d) to %s\n", g.size(),
                args->pose.empty() ? "rest" : args->pose.c_str(), g.sh_degree, args->out.c_str());
  });
});

}  // namespace

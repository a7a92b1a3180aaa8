// `kinesplat export`: an avatar as a standard 3DGS .ply (rest pose, or a pose
// from PARAMS.json).
#include <cstdio>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "gaussians/ply.hpp"

namespace {

ks::cli::CommandGroup group(80, [](CLI::App& app) {
  struct Args {
    std::string avatar, out, pose;
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand("export", "Write an avatar as a standard 3DGS .ply");
  sub->add_option("avatar", args->avatar, "Avatar file (from `reconstruct`)")->required();
  sub->add_option("--out", args->out, "Output .ply")->required();
  sub->add_option("--pose", args->pose,
                  "Pose parameters JSON (global_orient, body_pose, transl, "
                  "...); default: rest");
  sub->callback([args] {
    const ks::Avatar avatar = ks::load_avatar(args->avatar);
    ks::Gaussians g;
    if (args->pose.empty()) {
      g = avatar.gaussians;
    } else {
      const ks::BodyParams p = ks::avatar_params_from_json(avatar, ks::read_json(args->pose));
      g = ks::pose_avatar(avatar, p);
    }
    ks::write_ply(args->out, g);
    std::printf("export: wrote %zu Gaussians (%s pose, SH degree %d) to %s\n", g.size(),
                args->pose.empty() ? "rest" : args->pose.c_str(), g.sh_degree, args->out.c_str());
  });
});

}  // namespace

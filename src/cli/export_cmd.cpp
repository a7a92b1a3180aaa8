// `kinesplat export`: an avatar as a standard 3DGS .ply (rest pose, or a pose
// from PARAMS.json), as a static web site that plays it (--web, src/web/), or as a glTF 2.0
// binary with its skin and motions (--gltf, src/gltf/).
#include <chrono>
#include <cstdio>
#include <string>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "gaussians/ply.hpp"
#include "gltf/avatar_bvh.hpp"
#include "gltf/gltf_export.hpp"
#include "web/web_export.hpp"

namespace {

ks::cli::CommandGroup group(80, [](CLI::App& app) {
  struct Args {
    std::string avatar, out, pose, web, gltf, bvh;
    std::vector<std::string> motions;
    bool only_mesh = false, only_splats = false, both = false, vertex_colors = false,
         template_surface = false;
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "export",
      "Write an avatar as a standard 3DGS .ply, as a web page that plays it (--web) or as glTF "
      "2.0 with its skin and motions (--gltf); or a motion as BVH on its skeleton (--bvh)");
  sub->add_option("avatar", args->avatar, "Avatar file (from `reconstruct`)")->required();
  auto* out = sub->add_option("--out", args->out, "Output .ply");
  auto* web = sub->add_option("--web", args->web,
                              "Write a static web site playing the avatar into this folder "
                              "(docs/viewer.md) instead of a .ply");
  out->excludes(web);
  auto* gltf = sub->add_option("--gltf", args->gltf,
                               "Write a glTF 2.0 binary (.glb): the skinned mesh and the "
                               "KHR_gaussian_splatting splats, with each --motion as an animation "
                               "(docs/export.md)");
  gltf->excludes(out)->excludes(web);
  auto* bvh = sub->add_option("--bvh", args->bvh,
                              "Write the one --motion as BVH on the avatar's skeleton (joint "
                              "names, offsets in metres; docs/export.md)");
  bvh->excludes(out)->excludes(web)->excludes(gltf);
  sub->add_option(
      "--motion", args->motions,
      "With --web: a motion to add and start with (the built-in motions are always "
      "included); with --gltf: a motion to add as an animation; with --bvh: the motion. "
      "A built-in name, an AMASS .npz or a .bvh (repeatable)");
  auto* m = sub->add_flag("--mesh", args->only_mesh, "With --gltf: only the skinned mesh");
  auto* s = sub->add_flag("--splats", args->only_splats, "With --gltf: only the splats");
  auto* both =
      sub->add_flag("--both", args->both, "With --gltf: the mesh and the splats (the default)");
  auto* vc = sub->add_flag("--vertex-colors", args->vertex_colors,
                           "With --gltf: the mesh's colour as COLOR_0 instead of a texture "
                           "(the default: a PNG over the project's UV atlas)");
  auto* ts = sub->add_flag("--template-surface", args->template_surface,
                           "With --gltf: the mesh at the template's own (smooth) vertices instead "
                           "of where the splats are (the default: each vertex at its Gaussians' "
                           "centres, out by their reach; docs/export.md)");
  ts->needs(gltf)->excludes(s);
  m->excludes(s)->excludes(both)->needs(gltf);
  s->excludes(both)->needs(gltf);
  both->needs(gltf);
  vc->needs(gltf)->excludes(s);
  sub->add_option("--pose", args->pose,
                  "Pose parameters JSON (global_orient, body_pose, transl, "
                  "...); default: rest");
  sub->callback([args] {
    if (args->out.empty() && args->web.empty() && args->gltf.empty() && args->bvh.empty())
      throw ks::Error(
          "export: give --out FILE.ply or --web DIR (or --gltf FILE.glb, --bvh FILE.bvh)");
    if (!args->out.empty() && !args->motions.empty())
      throw ks::Error("export: --motion applies to --web and --gltf, not --out (use --pose)");
    const ks::Avatar avatar = ks::load_avatar(args->avatar);
    if (!args->bvh.empty()) {
      if (!args->pose.empty()) throw ks::Error("export: --pose applies to --out, not --bvh");
      if (args->motions.size() != 1)
        throw ks::Error("export: --bvh writes one motion: give exactly one --motion");
      const ks::Motion m = ks::load_motion(args->motions[0]);
      ks::write_bvh(args->bvh, ks::avatar_motion_bvh(avatar, m));
      std::printf("export: wrote motion \"%s\" (%zu frames at %.3g fps, %d joints) as BVH to %s\n",
                  m.name.c_str(), m.frames.size(), m.fps, avatar.num_joints(), args->bvh.c_str());
      return;
    }
    if (!args->gltf.empty()) {
      if (!args->pose.empty()) throw ks::Error("export: --pose applies to --out, not --gltf");
      ks::GltfExportOptions opt;
      if (args->only_mesh) opt.splats = false;
      if (args->only_splats) opt.mesh = false;
      opt.vertex_colors = args->vertex_colors;
      opt.template_surface = args->template_surface;
      std::vector<ks::Motion> motions;
      for (const auto& name : args->motions) motions.push_back(ks::load_motion(name));
      const auto t0 = std::chrono::steady_clock::now();
      ks::export_gltf(args->gltf, avatar, motions, opt);
      const double secs =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf("export: wrote %s%s%s (%d joints, %zu animations) to %s in %.2f s\n",
                  opt.mesh ? "the skinned mesh" : "", opt.mesh && opt.splats ? " and " : "",
                  opt.splats ? (std::to_string(avatar.num_gaussians()) + " splats").c_str() : "",
                  avatar.num_joints(), motions.size(), args->gltf.c_str(), secs);
      return;
    }
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

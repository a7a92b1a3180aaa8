// `kinesplat augment PRIOR`: SVAD's refinement of the generated frames into PRIOR/refined.
#include <cstdio>
#include <filesystem>

#include "augment/augment.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "sample/poses_file.hpp"

namespace {

namespace fs = std::filesystem;

ks::cli::CommandGroup group(28, [](CLI::App& app) {
  struct Args {
    std::string prior, subject, face = "on";
    ks::AugmentOptions opt;
    bool quiet = false;
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "augment",
      "Refine the generated frames (face fusion from the photo, optional restoration) into "
      "PRIOR/refined");
  sub->add_option("prior", args->prior, "Folder with dataset/ (from `generate`)")->required();
  sub->add_option("--subject", args->subject,
                  "Subject folder (image.png, mask.png, fit.json); default: the one poses.json "
                  "names");
  sub->add_option("--face-fusion", args->face,
                  "The photo's face blended into every frame that shows the face")
      ->capture_default_str()
      ->check(CLI::IsMember({"on", "off"}));
  sub->add_option("--face-warp", args->opt.face_warp,
                  "How the photo's face reaches a frame: body (through the fitted body's "
                  "surface, turning with the head) or similarity (2D, from landmarks)")
      ->capture_default_str()
      ->check(CLI::IsMember({"body", "similarity"}));
  sub->add_option("--restore", args->opt.restore_command,
                  "A restoration command run on each frame: {in} and {out} are replaced by PNG "
                  "paths (docs/augment.md)");
  sub->add_flag("--quiet,-q", args->quiet, "No progress");
  sub->callback([args] {
    ks::AugmentOptions o = args->opt;
    o.face_fusion = args->face == "on";
    o.progress = !args->quiet;
    std::string subject = args->subject;
    if (subject.empty()) {
      const std::string poses = (fs::path(args->prior) / "poses.json").string();
      if (!fs::exists(poses)) throw ks::Error(poses + ": missing: give --subject SUBJECT");
      subject = ks::load_poses(poses).subject;
      if (subject.empty())
        throw ks::Error(poses + " does not name its subject: give --subject SUBJECT");
    }
    const ks::AugmentReport r = ks::run_augment(args->prior, subject, o);
    std::printf("augment: %d frames, %d faces fused, %d restored, %.1f s; wrote %s\n", r.frames,
                r.faces_fused, r.restored, r.seconds,
                (fs::path(args->prior) / "refined").string().c_str());
  });
});

}  // namespace

// `kinesplat generate PRIOR --with lift|command|frames`: the sampled poses rendered by a
// generator into PRIOR/dataset/ (the photo as frame 0).
#include <cstdio>
#include <filesystem>

#include "cli/registry.hpp"
#include "core/error.hpp"
#include "generate/generate.hpp"
#include "sample/poses_file.hpp"

namespace {

namespace fs = std::filesystem;

ks::cli::CommandGroup group(27, [](CLI::App& app) {
  struct Args {
    ks::GenerateOptions opt;
    std::string prior, subject, with = ks::to_string(opt.generator);
    bool quiet = false;
  };
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "generate", "Render the sampled poses with a generator into PRIOR/dataset (photo = frame 0)");
  sub->add_option("prior", args->prior, "Folder with poses.json (from `sample`)")->required();
  sub->add_option("--with", args->with,
                  "Generator: lift (built in, no weights), command (an external program, "
                  "--command), frames (frames you have, --frames)")
      ->capture_default_str()
      ->check(CLI::IsMember(ks::generator_names()));
  sub->add_option("--subject", args->subject,
                  "Subject folder (image.png, mask.png, fit.json); default: the one poses.json "
                  "names");
  sub->add_option("--command", args->opt.command,
                  "With --with command: the command line; {ref} {mask} {conditions} {poses} "
                  "{video} {out} {frames} {width} {height} {fps} are replaced (docs/generate.md)");
  sub->add_option("--frames", args->opt.frames_dir,
                  "With --with frames: a folder of NNNN.png, one per pose (masks/NNNN.png "
                  "optional)");
  sub->add_option("--supersample", args->opt.supersample, "lift: S x S samples per pixel")
      ->capture_default_str()
      ->check(CLI::Range(1, 8));
  sub->add_option("--photo-weight", args->opt.photo_weight,
                  "How many frames the photo (frame 0) counts for in a fit")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1000.0));
  sub->add_flag("--quiet,-q", args->quiet, "No progress");
  sub->callback([args] {
    ks::GenerateOptions o = args->opt;
    o.progress = !args->quiet;
    o.generator = ks::parse_generator(args->with);
    if (o.generator != ks::Generator::kCommand && !o.command.empty())
      throw ks::Error("generate: --command is for --with command");
    if (o.generator != ks::Generator::kFrames && !o.frames_dir.empty())
      throw ks::Error("generate: --frames is for --with frames");
    std::string subject = args->subject;
    if (subject.empty()) {
      const std::string poses = (fs::path(args->prior) / "poses.json").string();
      if (!fs::exists(poses)) throw ks::Error(poses + ": missing (run `kinesplat sample` first)");
      subject = ks::load_poses(poses).subject;
      if (subject.empty())
        throw ks::Error(poses + " does not name its subject: give --subject SUBJECT");
    }
    const ks::GenerateReport r = ks::run_generate(args->prior, subject, o);
    if (r.generator == ks::to_string(ks::Generator::kLift))
      std::printf(
          "generate: lift: %d vertices (%.0f%% seen in the photo, %.0f%% from mirrors, %.0f%% "
          "filled); %s\n",
          r.lift.vertices, 100 * r.lift.seen, 100 * r.lift.mirrored, 100 * r.lift.diffused,
          r.lift.garment.c_str());
    std::printf(
        "generate: %s: wrote %d frames (the photo and %d generated%s) to %s in %.1f s\n",
        r.generator.c_str(), r.frames, r.frames - 1,
        r.masks_segmented
            ? (", " + std::to_string(r.masks_segmented) + " masks by perceive's segmenter").c_str()
            : "",
        (fs::path(args->prior) / "dataset").string().c_str(), r.seconds);
  });
});

}  // namespace

// create: the whole pipeline from a small synth photo (its own keypoints and mask, so no detector
// is needed), resuming by outputs and settings, and failures recorded with nothing run before the
// options are checked.
#include <gtest/gtest.h>

#include <filesystem>

#include "cli_run.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "create/create.hpp"
#include "io/video.hpp"
#include "synth/run.hpp"
#include "temp_dir.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

struct Photo {
  test::TempDir tmp{"create"};
  std::string synth;
  Photo() {
    SynthRunConfig cfg;
    cfg.seed = 2;
    cfg.out_dir = tmp / "synth";
    cfg.width = 96;
    cfg.height = 144;
    cfg.frames = 4;
    cfg.progress = false;
    run_synth(cfg);
    synth = cfg.out_dir;
  }
  std::string photo() const { return synth + "/photo.png"; }
  // Tiny settings: the synth's own keypoints and mask, few poses, few steps, small videos.
  CreateOptions options() const {
    CreateOptions o;
    o.perceive.keypoints_path = synth + "/photo_keypoints.json";
    o.perceive.keypoints_pixel_centre = 0.5;
    o.perceive.mask_path = synth + "/photo_mask.png";
    o.perceive.face = false;
    o.fit.fit.keypoints = KeypointConvention::kJoints;
    o.sample.frames = 3;
    o.sample.video = false;
    o.generate.supersample = 1;
    o.generate.lift.subdivision_levels = 1;
    o.reconstruct.train.iterations = 6;
    o.reconstruct.train.subdivide = 0;
    o.reconstruct.density = "off";
    o.motions = {"wave"};
    o.playback.width = 48;
    o.playback.height = 64;
    o.playback.frames = 3;
    o.progress = false;
    return o;
  }
};

int skipped(const CreateReport& r) {
  int n = 0;
  for (const auto& s : r.stages) n += s.skipped;
  return n;
}

}  // namespace

TEST(Create, PhotoToAvatarThenResumes) {
  if (find_ffmpeg().empty()) GTEST_SKIP() << "no ffmpeg: create writes videos";
  Photo p;
  const std::string out = p.tmp / "out";
  CreateOptions o = p.options();
  const CreateReport r = run_create(p.photo(), out, o);
  ASSERT_EQ(r.stages.size(), create_stage_names().size());
  EXPECT_EQ(skipped(r), 0);
  EXPECT_TRUE(fs::is_regular_file(out + "/avatar.ksavatar"));
  EXPECT_TRUE(fs::is_regular_file(out + "/subject/fit.json"));
  EXPECT_TRUE(fs::is_regular_file(out + "/prior/refined/dataset.json"));
  ASSERT_EQ(r.videos.size(), 2u);
  for (const auto& v : r.videos) EXPECT_GT(fs::file_size(v), 0u) << v;
  nlohmann::json j = read_json(out + "/create.json");
  EXPECT_EQ(j["status"], "done");
  EXPECT_TRUE(j["stages"]["reconstruct"]["seconds"].is_number());

  // Everything up to date: nothing runs.
  const CreateReport again = run_create(p.photo(), out, o);
  EXPECT_EQ(skipped(again), int(create_stage_names().size()));

  // Other reconstruct settings: the stages before it are kept.
  o.reconstruct.train.iterations = 4;
  const CreateReport third = run_create(p.photo(), out, o);
  ASSERT_EQ(third.stages.size(), 7u);
  for (int k = 0; k < 5; ++k) EXPECT_TRUE(third.stages[size_t(k)].skipped) << k;
  EXPECT_FALSE(third.stages[5].skipped);
  EXPECT_FALSE(third.stages[6].skipped);

  // An edited fit (newer than what was made from it): from sample on, everything reruns.
  fs::last_write_time(out + "/subject/fit.json", fs::file_time_type::clock::now());
  const CreateReport fourth = run_create(p.photo(), out, o);
  EXPECT_TRUE(fourth.stages[0].skipped);
  EXPECT_TRUE(fourth.stages[1].skipped);
  for (int k = 2; k < 7; ++k) EXPECT_FALSE(fourth.stages[size_t(k)].skipped) << k;

  // --force reruns all.
  o.force = true;
  EXPECT_EQ(skipped(run_create(p.photo(), out, o)), 0);
}

TEST(Create, FailingStageIsRecordedAndResumed) {
  if (find_ffmpeg().empty()) GTEST_SKIP() << "no ffmpeg: create writes videos";
  Photo p;
  const std::string out = p.tmp / "out";
  CreateOptions o = p.options();
  o.generate.generator = Generator::kCommand;
  o.generate.command = "echo the model is not installed >&2; exit 3";
  EXPECT_THROW(run_create(p.photo(), out, o), Error);
  const nlohmann::json j = read_json(out + "/create.json");
  EXPECT_EQ(j["status"], "failed");
  EXPECT_NE(j["error"].get<std::string>().find("not installed"), std::string::npos) << j["error"];
  EXPECT_FALSE(fs::exists(out + "/prior/dataset"));
  EXPECT_FALSE(fs::exists(out + "/avatar.ksavatar"));
  EXPECT_TRUE(fs::is_regular_file(out + "/subject/fit.json"));
  // The built-in generator instead: perceive, fit and sample are kept.
  o.generate.generator = Generator::kLift;
  o.generate.command.clear();
  const CreateReport r = run_create(p.photo(), out, o);
  EXPECT_TRUE(r.stages[0].skipped);
  EXPECT_TRUE(r.stages[1].skipped);
  EXPECT_TRUE(r.stages[2].skipped);
  EXPECT_FALSE(r.stages[3].skipped);
  EXPECT_EQ(read_json(out + "/create.json")["status"], "done");
}

TEST(Create, BadInputsFailBeforeAnythingIsWritten) {
  test::TempDir tmp("create_bad");
  const std::string out = tmp / "out";
  EXPECT_THROW(run_create(tmp / "missing.png", out), Error);
  EXPECT_THROW(run_create(tmp.path().string(), out), Error);  // a folder, not a photo
  EXPECT_FALSE(fs::exists(out));
  write_text_atomic(tmp / "p.png", "not a png");
  CreateOptions o;
  o.generate.generator = Generator::kCommand;  // and no command
  EXPECT_THROW(run_create(tmp / "p.png", out, o), Error);
  o = CreateOptions();
  o.reconstruct.density = "sometimes";
  EXPECT_THROW(run_create(tmp / "p.png", out, o), Error);
  EXPECT_FALSE(fs::exists(out));

  const auto r = test::run_cli("create " + (tmp / "missing.png") + " --out " + out);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("error: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("missing.png"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  const auto r2 = test::run_cli("create " + (tmp / "p.png") + " --out " + out + " --command 'x'");
  EXPECT_EQ(r2.status, 1);
  EXPECT_NE(r2.err.find("--command is for --generator command"), std::string::npos) << r2.err;
}

}  // namespace ks

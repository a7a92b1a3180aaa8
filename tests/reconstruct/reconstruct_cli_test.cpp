// `kinesplat reconstruct` and `kinesplat evaluate` end to end on a tiny dataset written here:
// 3 frames of a coloured Gaussian person rendered by the rasterizer (40 x 56).
#include <gtest/gtest.h>

#include "temp_dir.hpp"

#include <sys/wait.h>
#include <unistd.h>
#include "cli_run.hpp"
#include "reconstruct/tiny_avatar.hpp"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "avatar/avatar.hpp"
#include "avatar/pose.hpp"
#include "core/fileio.hpp"
#include "dataset/dataset.hpp"
#include "io/image_io.hpp"
#include "raster/rasterizer.hpp"
#include "reconstruct/trainer.hpp"

namespace ks {

namespace fs = std::filesystem;

namespace {

using test::run_cli;

// Writes a 3-frame dataset rendered from a short fit recoloured by height.
void write_tiny_dataset(const std::string& dir) {
  const BodyModel& model = default_body_model();
  Dataset ds;
  ds.betas = Eigen::VectorXd::Zero(model.num_betas);
  const TrainOptions opt = test::tiny_train_options(16, 4, 8);
  Avatar truth = test::one_step_avatar(model, ds, opt);
  for (int i = 0; i < truth.num_gaussians(); ++i) {
    const float y = truth.gaussians.means[3 * size_t(i) + 1];
    truth.gaussians.sh[3 * size_t(i)] = std::sin(4.f * y);
    truth.gaussians.opacity_logits[i] = 4.f;
  }
  fs::create_directories(fs::path(dir) / "images");
  RasterSettings rs;
  for (int f = 0; f < 3; ++f) {
    DatasetFrame fr;
    fr.image = "images/" + std::to_string(f) + ".png";
    fr.mask = "images/" + std::to_string(f) + "_mask.png";
    fr.pose.global_orient = Eigen::Vector3d(0, 2.1 * f, 0);
    fr.pose.body_pose = Eigen::VectorXd::Zero(3 * model.num_body_pose_joints());
    fr.camera = Camera::look_at_fov({0, 0, 3.2}, {0, -0.3, 0}, 40, 56, 45.0);
    BodyParams p = fr.pose;
    p.betas = ds.betas;
    RasterResult rr;
    rasterize_forward(pose_avatar(truth, p), fr.camera, rs, rr);
    write_png((fs::path(dir) / fr.image).string(), rr.color);
    write_png((fs::path(dir) / fr.mask).string(), rr.alpha);
    ds.frames.push_back(fr);
  }
  for (int k = 0; k < 3; ++k) ds.background[k] = 0.f;
  ds.save(dir);
}

}  // namespace

TEST(ReconstructCli, TrainsSavesAndEvaluates) {
  const test::TempDir tmp("ks_recon_cli");
  const fs::path dir = tmp.path();
  write_tiny_dataset((dir / "data").string());
  const std::string av = (dir / "a.ksavatar").string();
  test::CliRun r = run_cli("reconstruct " + (dir / "data").string() + " --out " + av +
                           " --iters 4 --subdivide 0 --scale 1 --triplane-res 16 --hidden 8"
                           " --triplane-channels 4 --joint-decoder 1 -q");
  ASSERT_EQ(r.status, 0) << r.output;
  ASSERT_TRUE(fs::exists(av));
  const Avatar a = load_avatar(av);
  EXPECT_EQ(a.num_gaussians(), default_body_model().num_vertices());
  // The decoder's sizes are recorded with the avatar.
  EXPECT_EQ(a.metadata.value("triplane_res", -1), 16);
  EXPECT_EQ(a.metadata.value("triplane_channels", -1), 4);
  EXPECT_EQ(a.metadata.value("hidden", -1), 8);
  EXPECT_TRUE(a.metadata.value("joint_decoder", false));
  // Every step at --scale by default (no coarse-to-fine phase: it starts after the last step).
  EXPECT_EQ(a.metadata.value("fine_from_iteration", -1), 4);
  EXPECT_EQ(a.metadata.value("subdivide", -1), 0);
  {
    // Coarse-to-fine on request: the last quarter (iteration 3 of 4) on the full-size frames.
    const std::string av2 = (dir / "c2f.ksavatar").string();
    test::CliRun r2 = run_cli("reconstruct " + (dir / "data").string() + " --out " + av2 +
                              " --iters 4 --subdivide 0 --scale 0.5 --fine-from 0.75 "
                              "--triplane-res 16 --hidden 8 -q");
    ASSERT_EQ(r2.status, 0) << r2.output;
    EXPECT_EQ(load_avatar(av2).metadata.value("fine_from_iteration", -1), 3);
  }
  const std::string mj = (dir / "m.json").string();
  r = run_cli("evaluate " + av + " " + (dir / "data").string() + " --out " + mj + " -q");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("mean masked SSIM"), std::string::npos);
  const nlohmann::json j = read_json(mj);
  EXPECT_EQ(j["frames"].size(), 3u);
  EXPECT_GT(j["mean"]["psnr"].get<double>(), 10.0);
  EXPECT_LE(j["mean"]["ssim"].get<double>(), 1.0);
  // User errors: a missing dataset, an unknown Laplacian mode.
  r = run_cli("reconstruct " + (dir / "nope").string() + " --out " + av);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("error:"), std::string::npos);
  r = run_cli("reconstruct " + (dir / "data").string() + " --out " + av +
              " --laplacian cotan --iters 1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("cotan"), std::string::npos);
  r = run_cli("reconstruct " + (dir / "data").string() + " --out " + av +
              " --garment sarong --iters 1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("expected none, skirt or auto"), std::string::npos) << r.output;
  {
    // The garment layer on request: the skirt proxy joins the template.
    const std::string av3 = (dir / "skirt.ksavatar").string();
    test::CliRun r3 = run_cli("reconstruct " + (dir / "data").string() + " --out " + av3 +
                              " --garment skirt --iters 2 --subdivide 0 --triplane-res 16 "
                              "--hidden 8 -q");
    ASSERT_EQ(r3.status, 0) << r3.output;
    EXPECT_NE(r3.output.find("skirt proxy of"), std::string::npos) << r3.output;
    const Avatar s3 = load_avatar(av3);
    EXPECT_GT(s3.num_gaussians(), default_body_model().num_vertices());
    EXPECT_EQ(s3.metadata.value("garment", ""), "skirt");
    EXPECT_EQ(s3.metadata.at("garment_follow_profile").size(), 5u);  // the default's knots
    // The profile's knots and the waistband are range-checked; nothing is written.
    for (const char* bad : {" --garment-follow-knots 0", " --garment-waist -0.1"}) {
      const std::string av4 = (dir / "bad.ksavatar").string();
      test::CliRun r4 = run_cli("reconstruct " + (dir / "data").string() + " --out " + av4 +
                                " --garment skirt --iters 1" + bad);
      EXPECT_EQ(r4.status, 1) << bad;
      EXPECT_FALSE(fs::exists(av4)) << bad;
    }
  }
  // Decoder sizes out of range are refused with the range and the value given; nothing is
  // written.
  for (const char* bad : {" --triplane-res 1", " --triplane-channels 0", " --hidden 0"}) {
    const std::string av6 = (dir / "size.ksavatar").string();
    test::CliRun r6 = run_cli("reconstruct " + (dir / "data").string() + " --out " + av6 +
                              " --iters 1 --subdivide 0" + bad);
    EXPECT_EQ(r6.status, 1) << bad;
    const std::string value = std::string(bad).substr(std::string(bad).rfind(' ') + 1);
    EXPECT_NE(r6.output.find(" must be in ["), std::string::npos) << r6.output;
    EXPECT_NE(r6.output.find("got " + value), std::string::npos) << r6.output;
    EXPECT_FALSE(fs::exists(av6)) << bad;
  }
  // Options that would be ignored in the combination given are refused; nothing is written.
  for (const char* bad : {" --eval-out m.json", " --eval-scale 0.5", " --fine-scale 0.5",
                          " --garment none --garment-hem 0.5", " --skin-from 0.5"}) {
    const std::string av5 = (dir / "ignored.ksavatar").string();
    test::CliRun r5 = run_cli("reconstruct " + (dir / "data").string() + " --out " + av5 +
                              " --iters 1 --subdivide 0" + bad);
    EXPECT_EQ(r5.status, 1) << bad;
    const std::string flag = std::string(bad).substr(1, std::string(bad).find(' ', 1) - 1);
    EXPECT_NE(r5.output.find(std::string(bad).find("--garment none") != std::string::npos
                                 ? "--garment-hem"
                                 : flag),
              std::string::npos)
        << r5.output;
    EXPECT_FALSE(fs::exists(av5)) << bad;
  }
}

// The trained avatar renders the held-out views better than the untrained start (one step).
TEST(ReconstructCli, TrainingImprovesOnTheUntrainedStart) {
  const test::TempDir tmp("ks_recon_cli_start");
  const fs::path dir = tmp.path();
  write_tiny_dataset((dir / "data").string());
  auto fit = [&](int iters) {
    const std::string name = "it" + std::to_string(iters);
    const std::string metrics = (dir / (name + ".json")).string();
    test::CliRun r =
        run_cli("reconstruct " + (dir / "data").string() + " --out " +
                (dir / (name + ".ksavatar")).string() + " --iters " + std::to_string(iters) +
                " --subdivide 0 --triplane-res 16 --hidden 8 --eval " + (dir / "data").string() +
                " --eval-out " + metrics + " -q");
    EXPECT_EQ(r.status, 0) << r.output;
    return read_json(metrics)["mean"];
  };
  const nlohmann::json start = fit(1), trained = fit(60);
  const double p0 = start["psnr_masked"].get<double>(), p1 = trained["psnr_masked"].get<double>();
  EXPECT_GT(p1, p0 + 3.0) << "masked PSNR " << p0 << " dB at the start, " << p1 << " trained";
  EXPECT_GT(trained["psnr"].get<double>(), start["psnr"].get<double>());
  EXPECT_GT(trained["ssim_masked"].get<double>(), start["ssim_masked"].get<double>());
}

}  // namespace ks

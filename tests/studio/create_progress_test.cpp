// The studio reads create's progress from its output: stage lines, progress lines, skipped stages,
// the end and the error line.
#include "studio/create_progress.hpp"

#include <gtest/gtest.h>

namespace ks {
namespace {

TEST(CreateProgress, FollowsARunFromItsOutput) {
  CreateProgress p;
  ASSERT_EQ(p.stages().size(), 8u);  // create's seven, then the studio's export
  EXPECT_EQ(p.stages().back().name, "export");
  EXPECT_EQ(p.percent(), 0);
  EXPECT_LT(p.remaining(10), 0);  // unknown at first
  double last = 0;
  for (const char* line :
       {"create [1/7     0s] perceive", "perceive: 512x768, keypoints detector (19 of 25)",
        "create [2/7     2s] fit", "create [3/7     4s] sample",
        "sample  10% (1/8)  elapsed 0.1s eta 1s", "sample 100% (8/8)  elapsed 0.4s eta 0s",
        "create [4/7     4s] generate", "create [5/7     7s] augment",
        "create [6/7     7s] reconstruct",
        "reconstruct   0% (1/20) loss 0.0446 psnr 20.36 N 195274 elapsed 0.7s eta 14s",
        "reconstruct  40% (8/20) loss 0.0541 psnr 19.76 N 195274 elapsed 3.3s eta 5s"}) {
    p.feed(line);
    EXPECT_GE(p.percent(), last) << line;
    last = p.percent();
  }
  EXPECT_EQ(p.current_name(), "reconstruct");
  EXPECT_EQ(p.stages()[5].status, "running");
  EXPECT_NEAR(p.stages()[5].fraction, 0.4, 1e-9);
  EXPECT_EQ(p.stages()[5].eta_seconds, 5);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(p.stages()[size_t(k)].status, "done") << k;
  EXPECT_GT(p.percent(), 30);
  EXPECT_LT(p.percent(), 50);
  EXPECT_GT(p.remaining(10), 0);
  p.feed("create [7/7    18s] videos");
  p.feed("animate  50% (32/64)  elapsed 0.8s eta 1s");
  p.feed("animate  10% (7/96)  elapsed 0.3s eta 2s");  // the next video: the stage never goes back
  EXPECT_NEAR(p.stages()[6].fraction, 0.5, 1e-9);
  p.feed("create: done in 20 s (peak memory 1358 MB)");
  EXPECT_EQ(p.current(), -1);
  EXPECT_EQ(p.stages()[6].status, "done");
  p.begin_export();
  EXPECT_EQ(p.current_name(), "export");
  p.export_fraction(0.5);
  p.finish(true);
  EXPECT_NEAR(p.percent(), 100, 1e-9);
  const nlohmann::json j = p.to_json(21);
  EXPECT_EQ(j["stages"].size(), 8u);
  EXPECT_EQ(j["elapsed"], 21);
  EXPECT_EQ(j["remaining"], 0);
}

TEST(CreateProgress, SkippedStagesAndAFailure) {
  CreateProgress p;
  p.feed("create [1/7     0s] perceive: up to date, skipped");
  p.feed("create [2/7     0s] fit: up to date, skipped");
  p.feed("create [3/7     0s] sample");
  EXPECT_EQ(p.stages()[0].status, "skipped");
  EXPECT_EQ(p.stages()[1].status, "skipped");
  EXPECT_EQ(p.current_name(), "sample");
  EXPECT_LT(p.remaining(1), 0);  // skipped stages do not count as work done
  p.feed("error: sample: the fit camera is degenerate");
  p.finish(false);
  EXPECT_EQ(p.error(), "sample: the fit camera is degenerate");
  EXPECT_EQ(p.stages()[2].status, "failed");
  EXPECT_EQ(p.current_name(), "sample");
  p.feed("");  // blank lines and unknown stages change nothing
  p.feed("create [9/9     1s] nonsense");
  EXPECT_EQ(p.current_name(), "sample");
}

}  // namespace
}  // namespace ks

#pragma once
// The progress of one studio job, read from what `kinesplat create` prints (src/create/create.cpp,
// src/core/progress.cpp), then the studio's own export step:
//   "create [4/7     6s] generate"                     a stage begins
//   "create [1/7     0s] perceive: up to date, skipped" a stage is skipped (resumed run)
//   "reconstruct  40% (8/20) loss ... elapsed 3.3s eta 5s"   a stage's own progress (every 10 %,
//                                                              when its output is not a terminal)
//   "create: done in 20 s ..."                          the end
//   "error: ..."                                        the failure (main's one line)
// The overall percentage weighs each stage by its usual share of a create's time (reconstruct
// most: docs/create.md's measured runs); the remaining time is the elapsed time scaled by what is
// left of that, once 5 % is done.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace ks {

struct JobStage {
  std::string name;
  std::string status = "pending";  // pending | running | done | skipped | failed
  double fraction = 0;             // of this stage, 0..1 (only grows)
  double eta_seconds = -1;         // this stage's own estimate, -1 when none
  double weight = 1;
};

class CreateProgress {
 public:
  CreateProgress();  // create's stages, then "export"
  // One line of create's output at `elapsed` seconds since the job began.
  void feed(const std::string& line);
  // The studio's steps after create.
  void begin_export();
  void export_fraction(double f);
  // The end: the running stage becomes done, or failed.
  void finish(bool ok);

  const std::vector<JobStage>& stages() const { return stages_; }
  int current() const { return current_; }  // index of the running (or failed) stage, -1 none
  std::string current_name() const;
  double percent() const;  // 0..100
  // Seconds left, -1 while unknown.
  double remaining(double elapsed_seconds) const;
  const std::string& error() const { return error_; }  // the "error: ..." line's message
  const std::string& last_line() const { return last_; }
  nlohmann::json to_json(double elapsed_seconds) const;

 private:
  void begin(int k, bool skipped);
  std::vector<JobStage> stages_;
  int current_ = -1;
  std::string error_, last_;
};

}  // namespace ks

#include "studio/create_progress.hpp"

#include <algorithm>
#include <cstdio>
#include <regex>

#include "create/create.hpp"

namespace ks {

namespace {

// Shares of a create's time at the defaults (docs/create.md, synth seeds 0-2: perceive 2 s, fit
// 2 s, sample 3.5 s, generate 4.5 s, augment 1.3 s, reconstruct 140 s, videos 12 s), with the
// export step (web site, .ply, GLB, zip) a few seconds.
double usual_weight(const std::string& stage) {
  if (stage == "perceive" || stage == "fit") return 2;
  if (stage == "sample") return 3.5;
  if (stage == "generate") return 4.5;
  if (stage == "augment") return 1.5;
  if (stage == "reconstruct") return 140;
  if (stage == "videos") return 12;
  if (stage == "export") return 6;
  return 2;
}

}  // namespace

CreateProgress::CreateProgress() {
  for (const auto& n : create_stage_names())
    stages_.push_back({n, "pending", 0, -1, usual_weight(n)});
  stages_.push_back({"export", "pending", 0, -1, usual_weight("export")});
}

std::string CreateProgress::current_name() const {
  return current_ >= 0 ? stages_[size_t(current_)].name : "";
}

void CreateProgress::begin(int k, bool skipped) {
  if (k < 0 || k >= int(stages_.size())) return;
  // Stages before it are over (done, unless they were skipped).
  for (int i = 0; i < k; ++i) {
    JobStage& s = stages_[size_t(i)];
    if (s.status == "running" || s.status == "pending") {
      s.status = "done";
      s.fraction = 1;
      s.eta_seconds = -1;
    }
  }
  JobStage& s = stages_[size_t(k)];
  s.status = skipped ? "skipped" : "running";
  s.fraction = skipped ? 1 : 0;
  s.eta_seconds = -1;
  current_ = skipped ? -1 : k;
}

void CreateProgress::feed(const std::string& line) {
  if (line.empty()) return;
  last_ = line;
  static const std::regex stage_re(R"(^create \[(\d+)/(\d+)\s+\d+s\] ([a-z]+)(: up to date.*)?$)");
  static const std::regex bar_re(
      R"(^[a-z][a-z_ -]*\s+(\d+)% \(\d+/\d+\).* elapsed [0-9.]+s eta ([0-9]+)s\s*$)");
  std::smatch m;
  if (std::regex_match(line, m, stage_re)) {
    const std::string name = m[3];
    for (int k = 0; k < int(stages_.size()); ++k)
      if (stages_[size_t(k)].name == name) begin(k, m[4].matched);
    return;
  }
  if (std::regex_match(line, m, bar_re)) {
    if (current_ < 0) return;
    JobStage& s = stages_[size_t(current_)];
    s.fraction = std::max(s.fraction, std::stoi(m[1]) / 100.0);
    s.eta_seconds = std::stod(m[2]);
    return;
  }
  if (line.rfind("error: ", 0) == 0) {
    error_ = line.substr(7);
    return;
  }
  if (line.rfind("create: done in", 0) == 0) {
    for (auto& s : stages_)
      if (s.name != "export" && (s.status == "running" || s.status == "pending")) {
        s.status = "done";
        s.fraction = 1;
      }
    current_ = -1;
  }
}

void CreateProgress::begin_export() {
  const int k = int(stages_.size()) - 1;
  begin(k, false);
}

void CreateProgress::export_fraction(double f) {
  JobStage& s = stages_.back();
  s.fraction = std::clamp(std::max(s.fraction, f), 0.0, 1.0);
}

void CreateProgress::finish(bool ok) {
  if (ok) {
    for (auto& s : stages_)
      if (s.status != "skipped") {
        s.status = "done";
        s.fraction = 1;
        s.eta_seconds = -1;
      }
    current_ = -1;
    return;
  }
  if (current_ >= 0) stages_[size_t(current_)].status = "failed";
}

double CreateProgress::percent() const {
  double total = 0, done = 0;
  for (const auto& s : stages_) {
    total += s.weight;
    done += s.weight * (s.status == "done" || s.status == "skipped" ? 1.0 : s.fraction);
  }
  return total > 0 ? 100.0 * done / total : 0;
}

double CreateProgress::remaining(double elapsed) const {
  // Skipped stages took no time: leave them out of the rate.
  double total = 0, done = 0, later = 0;
  for (int k = 0; k < int(stages_.size()); ++k) {
    const JobStage& s = stages_[size_t(k)];
    if (s.status == "skipped") continue;
    total += s.weight;
    done += s.weight * (s.status == "done" ? 1.0 : s.fraction);
    if (k > current_ && current_ >= 0) later += s.weight;
  }
  if (total <= 0 || done / total < 0.05 || elapsed <= 0) return -1;
  const double rate = elapsed / done;  // seconds per unit of the usual weights
  // The running stage's own estimate, where it printed one (its share of a run varies most:
  // reconstruct's with --iters), then the later stages at the rate so far.
  if (current_ >= 0 && stages_[size_t(current_)].eta_seconds >= 0)
    return stages_[size_t(current_)].eta_seconds + rate * later;
  return rate * (total - done);
}

nlohmann::json CreateProgress::to_json(double elapsed) const {
  nlohmann::json st = nlohmann::json::array();
  for (const auto& s : stages_) {
    nlohmann::json j = {{"name", s.name}, {"status", s.status}, {"percent", 100 * s.fraction}};
    if (s.eta_seconds >= 0) j["eta"] = s.eta_seconds;
    st.push_back(j);
  }
  nlohmann::json j = {{"stages", st},
                      {"stage", current_name()},
                      {"percent", percent()},
                      {"elapsed", elapsed},
                      {"last_line", last_}};
  const double r = remaining(elapsed);
  j["remaining"] = r >= 0 ? nlohmann::json(r) : nlohmann::json(nullptr);
  if (!error_.empty()) j["error"] = error_;
  return j;
}

}  // namespace ks

#pragma once
// A one-line progress bar on stderr: "label [=====>    ] 42/100 loss 0.0123 eta 12s".
// Prints only when stderr is a terminal, or every ~10% otherwise (so CI logs stay short).
#include <chrono>
#include <string>

namespace ks {

class Progress {
 public:
  Progress(std::string label, long total);
  // Advances to `done` (absolute); `extra` is appended (e.g. "loss 0.0123").
  void update(long done, const std::string& extra = "");
  void finish(const std::string& extra = "");
  double elapsed_seconds() const;

 private:
  std::string label_;
  long total_;
  bool tty_;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_, last_print_;
};

}  // namespace ks

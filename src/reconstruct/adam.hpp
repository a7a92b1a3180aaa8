#pragma once
// Adam over named parameter groups (flat float arrays), each with its own learning rate, and a
// cosine-decayed schedule: lr(t) = lr_min + (lr0 - lr_min) * 0.5 * (1 + cos(pi * t / T)), with
// lr_min = final_fraction * lr0. Groups can be resized (new entries get zero moments) or remapped
// (e.g. after density control removed or reordered per-vertex entries).
#include <string>
#include <vector>

namespace ks {

struct AdamGroup {
  std::string name;
  std::vector<float>* params = nullptr;  // not owned
  float lr = 1e-3f;
  std::vector<float> m, v;
};

class Adam {
 public:
  float beta1 = 0.9f, beta2 = 0.999f, eps = 1e-15f;
  int total_steps = 1;          // T of the cosine schedule
  float final_fraction = 0.1f;  // lr at the end relative to the start

  // Returns the group index.
  int add_group(const std::string& name, std::vector<float>* params, float lr);
  // One step with gradients grads[g] (same size as the group's parameters).
  void step(const std::vector<const std::vector<float>*>& grads);
  float lr_scale() const;  // the cosine factor at the current step
  int steps_done() const { return t_; }
  AdamGroup& group(int g) { return groups_[size_t(g)]; }
  int num_groups() const { return int(groups_.size()); }
  // After a group's parameter array changed size: keeps the first min(old, new) moments, zeroes
  // the rest.
  void resize_group(int g);
  // New entry i takes the moments of old entry src[i] (-1: zero); `stride` values per entry.
  void remap_group(int g, const std::vector<int>& src, int stride);

 private:
  std::vector<AdamGroup> groups_;
  int t_ = 0;
};

}  // namespace ks

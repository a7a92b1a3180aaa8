#pragma once
// Adam over named parameter groups (flat float arrays), each with its own learning rate and its
// own gradient buffer, and a cosine-decayed schedule: lr(t) = lr_min + (lr0 - lr_min) * 0.5 *
// (1 + cos(pi * t / T)), with lr_min = final_fraction * lr0. A group's optimiser state follows its
// parameters when their set changes (density control): remap_group carries the moments of the
// entries that survive and starts new entries at zero (as gsplat's strategy ops do).
#include <Eigen/SparseCore>
#include <string>
#include <utility>
#include <vector>

namespace ks {

struct AdamGroup {
  std::string name;
  std::vector<float>* params = nullptr;       // not owned
  const std::vector<float>* grads = nullptr;  // not owned; the same size as params at step()
  float lr = 1e-3f;
  std::vector<float> m, v;
  // Not owned; null or empty: every entry steps. Otherwise only the entries in these ranges
  // [begin, end) step: the owner promises that every other entry has had a zero gradient at
  // every step so far (its moments are zero), so Adam would leave it unchanged anyway (the
  // triplane: texels no anchor's lookup reads).
  const std::vector<std::pair<size_t, size_t>>* active = nullptr;
};

class Adam {
 public:
  float beta1 = 0.9f, beta2 = 0.999f, eps = 1e-15f;
  int total_steps = 1;          // T of the cosine schedule
  float final_fraction = 0.1f;  // lr at the end relative to the start

  // Adds a group (names are unique; throws ks::Error for a repeated one).
  void add_group(const std::string& name, std::vector<float>* params,
                 const std::vector<float>* grads, float lr,
                 const std::vector<std::pair<size_t, size_t>>* active = nullptr);
  // One step of every group with its gradient buffer.
  void step();
  float lr_scale() const;  // the cosine factor at the current step
  int steps_done() const { return t_; }
  bool has_group(const std::string& name) const;
  AdamGroup& group(const std::string& name);  // throws ks::Error for an unknown name
  const std::vector<AdamGroup>& groups() const { return groups_; }
  // After a group's parameter array changed size: keeps the first min(old, new) moments, zeroes
  // the rest.
  void resize_group(const std::string& name);
  // New entry i takes the moments of old entry src[i] (-1: zero); `stride` values per entry.
  void remap_group(const std::string& name, const std::vector<int>& src, int stride);
  // The same through a density-control stencil (new entry r = sum_s S_rs old s, stride =
  // parameters per entry): a row that is one old entry with weight 1 keeps that entry's moments,
  // any other row (a new or merged vertex) starts at zero.
  void remap_group(const std::string& name, const Eigen::SparseMatrix<double, Eigen::RowMajor>& S);

 private:
  std::vector<AdamGroup> groups_;
  int t_ = 0;
};

}  // namespace ks

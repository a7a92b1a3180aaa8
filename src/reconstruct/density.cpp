// The trainer-facing density control modes (gpdc, vertex, naive, off) on top of density_ops.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>

#include "core/error.hpp"
#include "core/names.hpp"
#include "reconstruct/density.hpp"
#include "reconstruct/density_ops.hpp"

namespace ks {

namespace {

class ControlBase : public DensityControl {
 public:
  explicit ControlBase(const DensityOptions& o) : opt_(o) {
    if (std::getenv("KS_DENSITY_VERBOSE")) opt_.verbose = true;
  }
  DensityStats stats;

  bool acts_at(int iteration, int total_iterations) const override {
    return due(iteration, total_iterations);
  }

  void step(int iteration, TrainerState& state) override {
    if (!due(iteration, state.total_iterations)) return;
    if (state.num_vertices() == 0) return;
    if (opt_.verbose) print_grad_stats(iteration, state);
    act(iteration, state);
    ++stats.steps;
    state.reset_stats();
  }

 protected:
  virtual void act(int iteration, TrainerState& state) = 0;

  bool due(int it, int total) const {
    const int done = it + 1;  // iterations finished
    const int T = std::max(total, 1);
    const int start = opt_.start > 0 ? opt_.start : std::max(1, T / 4);
    const int stop = opt_.stop > 0 ? opt_.stop : std::max(start + 1, (3 * T) / 4);
    const int interval = opt_.interval > 0 ? opt_.interval : std::max(1, T / 10);
    return done >= start && done < stop && (done - start) % interval == 0;
  }

  void print_grad_stats(int it, const TrainerState& s) const {
    auto g = mean_grad(s);
    if (g.empty()) return;
    std::sort(g.begin(), g.end());
    auto q = [&](double p) { return g[std::min(g.size() - 1, size_t(p * double(g.size())))]; };
    std::fprintf(stderr,
                 "density it %d: mean view-space gradient p50 %.3g p90 %.3g p99 %.3g max %.3g "
                 "(tau %.3g)\n",
                 it + 1, q(0.5), q(0.9), q(0.99), g.back(), opt_.grad_threshold);
  }

  // Mean view-space gradient per vertex, in NDC units (see DensityOptions::image_width).
  std::vector<float> mean_grad(const TrainerState& s) const {
    const int N = s.num_vertices();
    const float to_ndc = 0.5f * float(opt_.image_width > 0 ? opt_.image_width : 256);
    std::vector<float> g(N, 0.f);
    for (int i = 0; i < N; ++i)
      if (i < int(s.grad2d_count.size()) && s.grad2d_count[i] > 0)
        g[i] = to_ndc * s.grad2d_accum[i] / float(s.grad2d_count[i]);
    return g;
  }

  // Keeps at most `cap` of the selected items, the highest scores.
  static void cap_selection(std::vector<uint8_t>& sel, const std::vector<float>& score,
                            size_t cap) {
    std::vector<int> idx;
    for (size_t i = 0; i < sel.size(); ++i)
      if (sel[i]) idx.push_back(int(i));
    if (idx.size() <= cap) return;
    std::nth_element(idx.begin(), idx.begin() + cap, idx.end(),
                     [&](int a, int b) { return score[a] > score[b]; });
    for (size_t k = cap; k < idx.size(); ++k) sel[idx[k]] = 0;
  }

  // Keeps state.canonical row-aligned with the vertices (each new row copies its largest-weight
  // source) so that later reads in the same step stay valid.
  static void remap_canonical(TrainerState& s, const Stencil& S) {
    Gaussians& g = s.canonical;
    if (int(g.size()) != int(S.cols())) return;
    Gaussians out;
    out.sh_degree = g.sh_degree;
    out.resize(size_t(S.rows()));
    const int K = g.coeffs();
    for (int r = 0; r < int(S.rows()); ++r) {
      int best = -1;
      double bw = -1;
      for (Stencil::InnerIterator it(S, r); it; ++it)
        if (it.value() > bw) bw = it.value(), best = int(it.col());
      if (best < 0) continue;
      std::copy_n(&g.means[3 * size_t(best)], 3, &out.means[3 * size_t(r)]);
      std::copy_n(&g.log_scales[3 * size_t(best)], 3, &out.log_scales[3 * size_t(r)]);
      std::copy_n(&g.quats[4 * size_t(best)], 4, &out.quats[4 * size_t(r)]);
      out.opacity_logits[r] = g.opacity_logits[best];
      std::copy_n(&g.sh[size_t(best) * K * 3], K * 3, &out.sh[size_t(r) * K * 3]);
    }
    g = std::move(out);
  }

  void apply(TrainerState& s, const MeshEdit& e) {
    s.apply_stencil(e.S, e.faces);
    remap_canonical(s, e.S);
  }

  // Mean log-size (mean of the three log-scales) per vertex, from the decoded Gaussians.
  static std::vector<float> log_sizes(const TrainerState& s) {
    const int N = s.num_vertices();
    std::vector<float> out(N, 0.f);
    if (int(s.canonical.size()) != N) return out;
    for (int i = 0; i < N; ++i)
      out[i] = (s.canonical.log_scales[3 * size_t(i)] + s.canonical.log_scales[3 * size_t(i) + 1] +
                s.canonical.log_scales[3 * size_t(i) + 2]) /
               3.f;
    return out;
  }

  // Splits faces selected by `face_sel`, returns the edit applied.
  MeshEdit split(TrainerState& s, std::vector<uint8_t> face_sel, const std::vector<float>& fscore) {
    const size_t cap = size_t(opt_.max_split_fraction * float(s.faces.rows()));
    cap_selection(face_sel, fscore, std::max<size_t>(cap, 1));
    MeshEdit e = split_faces(s.faces, s.num_vertices(), face_sel);
    if (e.num_vertices() > opt_.max_vertices) return MeshEdit{};
    apply(s, e);
    stats.added += int(e.new_rows.size());
    return e;
  }

  DensityOptions opt_;
};

class OffControl : public ControlBase {
 public:
  using ControlBase::ControlBase;
  bool acts_at(int, int) const override { return false; }
  void step(int, TrainerState&) override {}

 protected:
  void act(int, TrainerState&) override {}
};

// SIAvatar: faces around vertices with mean view-space gradient > tau, split 1->4.
class VertexControl : public ControlBase {
 public:
  using ControlBase::ControlBase;

 protected:
  void act(int it, TrainerState& s) override {
    if (s.num_vertices() >= opt_.max_vertices) return;
    const auto g = mean_grad(s);
    std::vector<uint8_t> vsel(g.size(), 0);
    for (size_t i = 0; i < g.size(); ++i) vsel[i] = g[i] > opt_.grad_threshold;
    const size_t nsel = size_t(std::count(vsel.begin(), vsel.end(), 1));
    if (nsel == 0) return;
    auto fsel = faces_around_vertices(s.faces, vsel);
    std::vector<float> fscore(s.faces.rows(), 0.f);
    for (Eigen::Index f = 0; f < s.faces.rows(); ++f)
      for (int k = 0; k < 3; ++k) fscore[f] = std::max(fscore[f], g[s.faces(f, k)]);
    const MeshEdit e = split(s, fsel, fscore);
    if (opt_.verbose)
      std::fprintf(stderr, "density[vertex] it %d: %zu vertices over tau, +%zu -> %d\n", it + 1,
                   nsel, e.new_rows.size(), s.num_vertices());
  }
};

// SinGS GPDC: collapse near-transparent, split high-gradient faces, rescale new + oversized.
class GpdcControl : public ControlBase {
 public:
  using ControlBase::ControlBase;

 protected:
  void act(int it, TrainerState& s) override {
    const int N0 = s.num_vertices();
    // 1. Collapse edges of near-transparent Gaussians (if the decoded opacities are at hand).
    int removed = 0;
    if (int(s.canonical.size()) == N0) {
      std::vector<uint8_t> cand(N0, 0);
      const float logit_thr = std::log(opt_.transparent_opacity / (1.f - opt_.transparent_opacity));
      for (int i = 0; i < N0; ++i) cand[i] = s.canonical.opacity_logits[i] < logit_thr;
      if (std::count(cand.begin(), cand.end(), 1) > 0) {
        CollapseOptions co;
        co.max_collapses = std::max(1, int(opt_.max_collapse_fraction * float(N0)));
        const MeshEdit c = collapse_vertices(s.anchors, s.faces, cand, co);
        removed = N0 - c.num_vertices();
        if (removed > 0) apply(s, c);
        stats.removed += removed;
      }
    }
    // 2. Split faces whose vertices' mean gradient is high.
    const auto g = mean_grad(s);
    const auto size_before = log_sizes(s);
    std::vector<uint8_t> fsel(s.faces.rows(), 0);
    std::vector<float> fscore(s.faces.rows(), 0.f);
    for (Eigen::Index f = 0; f < s.faces.rows(); ++f) {
      fscore[f] = (g[s.faces(f, 0)] + g[s.faces(f, 1)] + g[s.faces(f, 2)]) / 3.f;
      fsel[f] = fscore[f] > opt_.grad_threshold;
    }
    MeshEdit e;
    if (s.num_vertices() < opt_.max_vertices && std::count(fsel.begin(), fsel.end(), 1) > 0)
      e = split(s, fsel, fscore);
    // 3. Rescale new and oversized Gaussians to the mean size (log-size bias).
    int rescaled = 0;
    if (int(size_before.size()) > 0 && int(s.log_scale_bias.size()) == s.num_vertices()) {
      const double mean =
          std::accumulate(size_before.begin(), size_before.end(), 0.0) / double(size_before.size());
      const float over = float(mean) + std::log(opt_.oversize_factor);
      for (size_t i = 0; i < size_before.size(); ++i)
        if (size_before[i] > over) {
          s.log_scale_bias[i] += float(mean) - size_before[i];
          ++rescaled;
        }
      for (int r : e.new_rows) {
        double pred = 0;  // predicted decoded size: the stencil average of the parents
        for (Stencil::InnerIterator itr(e.S, r); itr; ++itr)
          pred += itr.value() * size_before[itr.col()];
        s.log_scale_bias[r] += float(mean - pred);
        ++rescaled;
      }
      if (int(s.canonical.size()) == s.num_vertices()) {
        // Keep the decoded copy consistent with the new biases.
        for (size_t i = 0; i < size_before.size(); ++i)
          if (size_before[i] > over)
            for (int k = 0; k < 3; ++k)
              s.canonical.log_scales[3 * i + k] += float(mean) - size_before[i];
      }
    }
    stats.rescaled += rescaled;
    if (opt_.verbose)
      std::fprintf(stderr, "density[gpdc] it %d: -%d collapsed, +%zu split, %d rescaled -> %d\n",
                   it + 1, removed, e.new_rows.size(), rescaled, s.num_vertices());
  }
};

// Original 3DGS clone/split/prune, mesh ignored (ablation).
class NaiveControl : public ControlBase {
 public:
  using ControlBase::ControlBase;

 protected:
  void act(int it, TrainerState& s) override {
    if (int(s.canonical.size()) != s.num_vertices()) return;
    NaiveOptions no = opt_.naive;
    no.grad_threshold = opt_.grad_threshold;
    no.seed = opt_.naive.seed + uint64_t(it);
    if (s.num_vertices() >= opt_.max_vertices) no.grad_threshold = INFINITY;  // prune only
    const NaiveEdit ne = naive_densify(s.anchors, s.faces, mean_grad(s), s.canonical, no);
    if (ne.cloned + ne.split + ne.pruned == 0) return;
    apply(s, ne.edit);
    for (size_t k = 0; k < ne.moved_rows.size(); ++k)
      s.anchors.row(ne.moved_rows[k]) = ne.positions[k].transpose();
    if (s.log_scale_bias.size() == ne.log_scale_delta.size())
      for (size_t i = 0; i < ne.log_scale_delta.size(); ++i)
        s.log_scale_bias[i] += ne.log_scale_delta[i];
    stats.added += ne.cloned + ne.split;
    stats.removed += ne.pruned;
    if (opt_.verbose)
      std::fprintf(stderr, "density[naive] it %d: +%d cloned, +%d split, -%d pruned -> %d\n",
                   it + 1, ne.cloned, ne.split, ne.pruned, s.num_vertices());
  }
};

}  // namespace

const std::vector<std::string>& density_control_names() {
  static const std::vector<std::string> names = {"gpdc", "vertex", "naive", "off"};
  return names;
}

void require_density_name(const std::string& name) {
  (void)parse_name<int>(density_control_names(), name, "density control");
}

std::unique_ptr<DensityControl> make_density_control(const std::string& name,
                                                     const DensityOptions& o) {
  if (name == "gpdc") return std::make_unique<GpdcControl>(o);
  if (name == "vertex") return std::make_unique<VertexControl>(o);
  if (name == "naive") return std::make_unique<NaiveControl>(o);
  if (name == "off" || name == "none") return std::make_unique<OffControl>(o);
  throw Error("unknown density control \"" + name + "\" (expected gpdc, vertex, naive or off)");
}

const DensityStats* density_stats(const DensityControl& c) {
  const auto* b = dynamic_cast<const ControlBase*>(&c);
  return b ? &b->stats : nullptr;
}

}  // namespace ks

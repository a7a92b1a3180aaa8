// The avatar fit as the algorithm's steps: setup (template, components, decoder, optimiser),
// then per iteration: pick a frame, decode, pose, render, losses, backward, optimiser, density
// control; at the end, bake the avatar.
#include "reconstruct/trainer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>
#include <random>

#include "body/lbs.hpp"
#include "body/skin_weights.hpp"
#include "core/error.hpp"
#include "core/math.hpp"
#include "core/parallel_copy.hpp"
#include "core/parallel_sum.hpp"
#include "core/progress.hpp"
#include "mesh/morton.hpp"
#include "mesh/trimesh.hpp"
#include "raster/rasterizer.hpp"
#include "raster/sh.hpp"
#include "raster_cuda/rasterizer_cuda.hpp"
#include "reconstruct/components/garment.hpp"
#include "reconstruct/components/learned_skin.hpp"
#include "reconstruct/components/vertex_color.hpp"
#include "reconstruct/decoder.hpp"
#include "reconstruct/density.hpp"
#include "reconstruct/losses.hpp"

namespace ks {

namespace {

constexpr float kSH0 = float(sh::kC0);  // the SH band-0 basis, in the colours' precision

void check_options(const std::vector<LoadedFrame>& frames, const TrainOptions& opt) {
  if (frames.empty()) throw Error("reconstruct: no training frames");
  if (opt.iterations < 1)
    throw Error("reconstruct: the step count must be >= 1, got " + std::to_string(opt.iterations));
  if (opt.fine_frames && opt.fine_from < 1.f && opt.fine_frames->size() != frames.size())
    throw Error("reconstruct: the fine frames must be the same frames as the coarse ones");
  if (opt.subdivide < 0 || opt.subdivide > 4)
    throw Error("reconstruct: the subdivision level must be in [0, 4], got " +
                std::to_string(opt.subdivide));
  const DecoderOptions& d = opt.decoder;
  if (d.triplane_res < 2 || d.triplane_res > 4096)
    throw Error("reconstruct: the triplane resolution must be in [2, 4096], got " +
                std::to_string(d.triplane_res));
  if (d.triplane_channels < 1 || d.triplane_channels > 256)
    throw Error("reconstruct: the triplane channels must be in [1, 256], got " +
                std::to_string(d.triplane_channels));
  if (d.hidden < 1 || d.hidden > 1024)
    throw Error("reconstruct: the MLPs' hidden width must be in [1, 1024], got " +
                std::to_string(d.hidden));
  const VisibilityOptions& v = opt.visibility;
  if (!(v.start >= 0.f && v.start <= 1.f))
    throw Error("reconstruct: the visibility test's start must be in [0, 1] of the steps, got " +
                std::to_string(v.start));
  if (!(v.depth_margin >= 0.f))
    throw Error("reconstruct: the visibility depth margin must be >= 0, got " +
                std::to_string(v.depth_margin));
  if (v.whole_every < 0)
    throw Error("reconstruct: the visibility test's whole-frame period must be >= 0, got " +
                std::to_string(v.whole_every));
  if (v.cell < 1 || v.reach < 0)
    throw Error("reconstruct: the visibility cell must be >= 1 pixel and its reach >= 0");
}

// The optional features, in the order they set up: the garment extends the template, learned
// skin weights start from the template's (the garment's where it set them), the colour residual
// is one per final vertex.
std::vector<std::unique_ptr<TrainComponent>> make_components(const TrainOptions& opt) {
  std::vector<std::unique_ptr<TrainComponent>> c;
  const bool learn_skin = opt.skin.lr > 0;
  if (opt.garment.mode != GarmentMode::kNone)
    c.push_back(
        std::make_unique<GarmentComponent>(opt.garment, opt.garment.lr_follow > 0 && !learn_skin));
  if (learn_skin) c.push_back(std::make_unique<LearnedSkinComponent>(opt.skin, opt.iterations));
  if (opt.vertex_color.lr > 0)
    c.push_back(std::make_unique<VertexColorComponent>(opt.vertex_color));
  return c;
}

const char* laplacian_name(LaplacianMode m) {
  return m == LaplacianMode::kSemantic  ? "semantic"
         : m == LaplacianMode::kUniform ? "uniform"
                                        : "none";
}

}  // namespace

struct Trainer::Impl {
  const BodyModel& model;
  const Dataset& ds;
  const std::vector<LoadedFrame>& frames;
  TrainOptions opt;

  // The template: the body at the dataset's betas in rest pose, subdivided, plus what the
  // components add; everything per vertex lives in `st` (density control's state) or in the
  // components, and follows density control through on_resize.
  BodyState rest_state;
  TrainerState st;
  Stencil body_stencil;  // template vertex <- body-model vertex (pose correctives)
  int body_vertices = 0;
  std::vector<float> xs, ys, zs;  // the anchors as float arrays (the triplane's input)
  Laplacian lap;
  std::vector<std::unique_ptr<TrainComponent>> components;
  Decoder decoder;
  Adam adam;
  double pixel_world = 0;  // world size of one training pixel at the body's root (median)

  // Per-step buffers, reused.
  Gaussians canon, posed;
  std::vector<float> offsets, pose_off, dmeans_c, dquats_c, doff, dsh, xcanon;
  LbsCache lbs_cache;
  RasterSettings rs;
  RasterResult rr;
  RasterGrads rg;
  std::unique_ptr<cuda::RasterizerCuda> gpu;  // TrainOptions::cuda_raster
  Image dcolor, dalpha;
  // Visibility (reconstruct/visibility.hpp): the Gaussians the frame can see, the last decode
  // posed for the frame, and whether a whole decode of this vertex set has run.
  std::vector<int> visible;
  Gaussians vis_posed;
  std::vector<float> vis_sigmas;
  bool whole_decoded = false;
  long visible_sum = 0, visible_steps = 0;

  // Schedule and log.
  std::mt19937_64 rng;
  std::vector<int> order;
  size_t order_pos = 0;
  int fine_start = 0;
  int it = 0;
  std::unique_ptr<Progress> progress;
  double loss_ema = 0, psnr_ema = 0;
  float last_loss = 0;

  Impl(const BodyModel& m, const Dataset& d, const std::vector<LoadedFrame>& f,
       const TrainOptions& o)
      : model(m), ds(d), frames(f), opt(o), rng(o.seed) {
    check_options(frames, opt);
    build_template();
    setup_components();
    setup_decoder();
    setup_optimizer();
    for (int k = 0; k < 3; ++k) rs.background[k] = ds.background[k];
    if (opt.cuda_raster) gpu = std::make_unique<cuda::RasterizerCuda>();  // throws without one
    // One pass over the frames: each frame round(weight) times (the dataset's per-frame weight).
    order.clear();
    for (size_t i = 0; i < frames.size(); ++i) {
      const double w = i < ds.frames.size() ? ds.frames[i].weight : 1.0;
      for (long k = 0; k < std::max(1L, std::lround(w)); ++k) order.push_back(int(i));
    }
    order_pos = order.size();
    fine_start = opt.iterations;
    if (opt.fine_frames && opt.fine_from < 1.f)
      fine_start =
          std::clamp(int(std::lround(double(opt.fine_from) * opt.iterations)), 0, opt.iterations);
    progress = std::make_unique<Progress>("reconstruct", opt.iterations);
  }

  // ---- setup

  // The body at its betas in rest pose, Loop-subdivided; top-4 skin weights and part labels
  // through the subdivision stencil.
  void build_template() {
    BodyParams rest;
    rest.betas = ds.betas;
    rest_state = body_forward(model, rest);
    TriMesh base{rest_state.rest_vertices, model.faces};
    if (opt.subdivide > 0) {
      Subdivision sub = subdivide(base, opt.subdivide, true);
      st.anchors = sub.mesh.V;
      st.faces = sub.mesh.F;
      body_stencil = sub.S;
    } else {
      st.anchors = base.V;
      st.faces = base.F;
      body_stencil = Stencil(base.V.rows(), base.V.rows());
      body_stencil.setIdentity();
    }
    number_along_curve();
    body_vertices = st.num_vertices();
    const Eigen::MatrixXd W = body_stencil * model.weights;
    top_k_skin_weights(W, 4, st.skin_joints, st.skin_weights);
    if (int(model.part_labels.size()) == model.num_vertices())
      st.part_labels = carry_labels(body_stencil, model.part_labels);
    else
      st.part_labels.assign(body_vertices, 0);
    st.log_scale_bias.assign(body_vertices, 0.f);
  }

  // Renumbers the template's vertices along a Morton curve (mesh/morton.hpp): anchors, the
  // stencil's rows and the faces (the skin weights and part labels follow through the stencil).
  // The subdivision numbers new vertices edge by edge, so that neighbours in space lie far apart
  // in the per-vertex arrays; in this order the decoder's triplane lookups and scatter find
  // their texels in cache (docs/reconstruct.md, "Time and memory"). Each vertex's arithmetic is
  // the same; sums over vertices (weight gradients, the scatter) add in another order.
  void number_along_curve() {
    const std::vector<int> ord = morton_order(st.anchors);
    const int n = int(ord.size());
    std::vector<int> renumbered(ord.size());
    Eigen::MatrixXd anchors(n, 3);
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(size_t(body_stencil.nonZeros()));
    for (int k = 0; k < n; ++k) {
      const int i = ord[size_t(k)];
      renumbered[size_t(i)] = k;
      anchors.row(k) = st.anchors.row(i);
      for (Stencil::InnerIterator it(body_stencil, i); it; ++it)
        entries.emplace_back(k, int(it.col()), it.value());
    }
    Stencil S(body_stencil.rows(), body_stencil.cols());
    S.setFromTriplets(entries.begin(), entries.end());
    body_stencil = std::move(S);
    st.anchors = std::move(anchors);
    for (long f = 0; f < st.faces.rows(); ++f)
      for (int c = 0; c < 3; ++c) st.faces(f, c) = renumbered[size_t(st.faces(f, c))];
  }

  void setup_components() {
    components = make_components(opt);
    FitTemplate t;
    t.model = &model;
    t.rest = &rest_state;
    t.state = &st;
    t.body_stencil = &body_stencil;
    t.body_vertices = body_vertices;
    t.mean_edge = mean_face_edge_length(st.anchors, st.faces);
    t.progress = opt.progress;
    for (auto& c : components) c->setup(t, frames);
    const int n = st.num_vertices();
    st.grad2d_accum.assign(n, 0.f);
    st.grad2d_count.assign(n, 0);
    st.max_radius.assign(n, 0);
    st.total_iterations = opt.iterations;
    st.on_resize = &Impl::on_resize;
    st.on_resize_ctx = this;
    rebuild();
  }

  // The 3D filter's variance from the finest frames the fit sees, the starting colour from the
  // frames' mean foreground colour.
  void setup_decoder() {
    float filter_var = 0;
    if (opt.decoder.filter3d > 0) {
      std::vector<double> px;
      const bool use_fine = opt.fine_frames && opt.fine_from < 1.f && !opt.fine_frames->empty();
      for (const auto& fr : use_fine ? *opt.fine_frames : frames) {
        const BodyState bs = body_forward(model, fr.pose);
        const double z = fr.camera.to_camera(bs.joints.row(0).transpose()).z();
        if (z > 0) px.push_back(z / fr.camera.fx);
      }
      pixel_world = median(px);  // 0 without frames in front of the camera
      filter_var = float(opt.decoder.filter3d * pixel_world * pixel_world);
    }
    float sh_init[3];
    double c[3] = {0, 0, 0}, wsum = 0;
    for (const auto& fr : frames)
      for (size_t p = 0; p < fr.mask.pixel_count(); ++p) {
        const double m = fr.mask.data[p];
        for (int k = 0; k < 3; ++k) c[k] += m * fr.image.data[3 * p + k];
        wsum += m;
      }
    for (int k = 0; k < 3; ++k) sh_init[k] = wsum > 0 ? float((c[k] / wsum - 0.5) / kSH0) : 0.f;
    decoder.init(opt.decoder, opt.seed, st.anchors, st.faces, filter_var, sh_init);
  }

  void setup_optimizer() {
    adam.total_steps = opt.iterations;
    adam.final_fraction = opt.optimizer.final_fraction;
    decoder.add_parameters(adam, opt.optimizer);
    for (auto& c : components) c->add_parameters(adam);
  }

  // The per-vertex pieces derived from the template: float anchors, the Laplacian.
  void rebuild() {
    const int n = st.num_vertices();
    xs.resize(n), ys.resize(n), zs.resize(n);
    for (int i = 0; i < n; ++i) {
      xs[i] = float(st.anchors(i, 0));
      ys[i] = float(st.anchors(i, 1));
      zs[i] = float(st.anchors(i, 2));
    }
    if (opt.loss.laplacian != LaplacianMode::kNone) {
      const auto adj = vertex_adjacency(st.faces, n);
      lap = build_laplacian(adj, st.part_labels, opt.loss.laplacian, opt.loss.part_strength);
    } else {
      lap = Laplacian{};
    }
  }

  // Density control replaced the vertex set (TrainerState::apply_stencil remapped its own arrays):
  // the body stencil, the components' parameters and their Adam state follow.
  static void on_resize(void* ctx, const Stencil& S) {
    Impl* t = static_cast<Impl*>(ctx);
    t->body_stencil = Stencil(S * t->body_stencil);
    t->whole_decoded = false;
    for (auto& c : t->components) c->remap(S, t->adam);
    t->rebuild();
  }

  // ---- one step

  StepLosses forward_backward(const LoadedFrame& fr) {
    const int n = st.num_vertices();
    StepContext ctx;
    ctx.iteration = it;
    ctx.canonical = &canon;
    ctx.state = &st;
    ctx.pose_offsets = &pose_off;
    ctx.laplacian = opt.loss.laplacian != LaplacianMode::kNone ? &lap : nullptr;

    // Pose: the frame's skinning transforms and the anchors' pose correctives.
    const BodyState bs = body_forward(model, fr.pose);
    ctx.body = &bs;
    pose_off.assign(3 * size_t(n), 0.f);
    if (bs.pose_offsets.size() > 0 && bs.pose_offsets.cwiseAbs().maxCoeff() > 0) {
      const Eigen::MatrixXd po = body_stencil * bs.pose_offsets;
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) pose_off[3 * size_t(i) + k] = float(po(i, k));
    }
    // Decode the canonical Gaussians: all of them, or those the frame can see.
    const std::vector<int>* subset = select_visible(fr, bs);
    decoder.decode(st.anchors, xs, ys, zs, st.log_scale_bias, canon, offsets, subset);
    if (!subset) whole_decoded = true;
    for (auto& c : components) c->forward(ctx);
    // Skin (the template's weights, or a component's) and render.
    const std::vector<int>* sj = &st.skin_joints;
    const std::vector<float>* sw = &st.skin_weights;
    for (auto& c : components)
      if (c->skinning(&sj, &sw)) break;
    lbs_forward(canon, pose_off.data(), *sj, *sw, bs.transforms, posed, &lbs_cache);
    if (subset) {
      // The hidden ones (not decoded this step) drop out before the rasterizer sorts.
      size_t j = 0;  // the subset is increasing
      for (int i = 0; i < n; ++i)
        if (j < subset->size() && (*subset)[j] == i)
          ++j;
        else
          posed.opacity_logits[size_t(i)] = kCulledOpacityLogit;
    }
    if (gpu) {
      gpu->upload(posed);
      gpu->forward(fr.camera, rs);
      gpu->download(rr);
    } else {
      rasterize_forward(posed, fr.camera, rs, rr);
    }

    // Image and mask losses.
    StepLosses L;
    const int W = fr.camera.width, H = fr.camera.height;
    if (rr.color.width != W || rr.color.height != H || fr.image.width != W)
      throw Error("reconstruct: render and frame sizes differ");
    // The gradient images, zeroed over the threads in the buffers of the last step.
    for (auto [img, ch] : {std::pair{&dcolor, 3}, std::pair{&dalpha, 1}}) {
      img->width = W, img->height = H, img->channels = ch;
      img->data.resize(size_t(W) * H * size_t(ch));
      parallel_fill(img->data.data(), img->data.size(), 0.f);
    }
    const size_t P = size_t(W) * H;
    const LossOptions& lo = opt.loss;
    L.l1 = l1_loss<float>(rr.color.data.data(), fr.image.data.data(), 3 * P, lo.w_l1,
                          dcolor.data.data());
    L.ssim = ssim<float>(rr.color.data.data(), fr.image.data.data(), W, H, 3, nullptr, -lo.w_ssim,
                         dcolor.data.data());
    if (lo.w_mask > 0)
      L.mask = l1_loss<float>(rr.alpha.data.data(), fr.mask.data.data(), P, lo.w_mask,
                              dalpha.data.data());
    const float* rc = rr.color.data.data();
    const float* fc = fr.image.data.data();
    L.mse = chunked_sum(3 * P,
                        [&](size_t b, size_t e) {
                          double s = 0;
                          for (size_t p = b; p < e; ++p) {
                            const double d = rc[p] - fc[p];
                            s += d * d;
                          }
                          return s;
                        }) /
            double(3 * P);

    // Backward through the rasterizer and LBS.
    if (gpu) {
      gpu->backward(dcolor, dalpha);
      gpu->download_grads(rg);
    } else {
      rasterize_backward(posed, fr.camera, rs, rr, dcolor, dalpha, rg);
    }
    lbs_backward(lbs_cache, rg.means, rg.quats, dmeans_c, dquats_c);

    // Regularisers on offsets and colours.
    doff.resize(3 * size_t(n));
    double off_l2 = chunked_sum(3 * size_t(n), [&](size_t b, size_t e) {
      double s = 0;
      for (size_t i = b; i < e; ++i) {
        s += double(offsets[i]) * offsets[i];
        doff[i] = 2.f * lo.w_offset * offsets[i] / float(n);
      }
      return s;
    });
    off_l2 /= n;
    parallel_assign(dsh, rg.sh);
    float lap_pos = 0, lap_col = 0;
    if (lo.laplacian != LaplacianMode::kNone) {
      // Position Laplacian of the anchors' displacement (the template's own differential
      // coordinates are kept), colour Laplacian of the SH0 colours.
      lap_pos = laplacian_loss<float>(lap, offsets.data(), 3, lo.w_lap_position, doff.data());
      lap_col = laplacian_loss<float>(lap, canon.sh.data(), 3, lo.w_lap_color, dsh.data());
    }

    // The components' gradients and regularisers.
    xcanon.resize(3 * size_t(n));
#pragma omp parallel for schedule(static) if (n > 16384)
    for (long q = 0; q < 3 * long(n); ++q) xcanon[q] = canon.means[q] + pose_off[q];
    ctx.raster = &rg;
    ctx.canonical_points = &xcanon;
    ctx.dsh = &dsh;
    for (auto& c : components) c->backward(ctx);
    L.total = lo.w_l1 * L.l1 + lo.w_ssim * (1.f - L.ssim) + lo.w_mask * L.mask +
              lo.w_offset * float(off_l2) + lo.w_lap_position * lap_pos + lo.w_lap_color * lap_col +
              ctx.regularizer;

    // Back to the decoder's parameters.
    decoder.backward(xs, ys, zs, dmeans_c, doff, rg.log_scales, dquats_c, rg.opacity_logits, dsh);
    return L;
  }

  // The Gaussians the frame can see (by their centres at the last decode, posed for it with the
  // template's skin weights), or nullptr for all: before opt.visibility.start, and until a whole
  // decode of the current vertex set has run.
  const std::vector<int>* select_visible(const LoadedFrame& fr, const BodyState& bs) {
    const VisibilityOptions& vo = opt.visibility;
    const int n = st.num_vertices();
    if (!vo.enabled || !whole_decoded || it < int(vo.start * float(opt.iterations)) ||
        int(canon.size()) != n || (vo.whole_every > 0 && it % vo.whole_every == 0))
      return nullptr;
    // The last decode's Gaussians posed for the frame (the one LBS, with the template's weights).
    lbs_forward(canon, pose_off.data(), st.skin_joints, st.skin_weights, bs.transforms, vis_posed);
    // With the footprint: each Gaussian's largest standard deviation at its last decode.
    if (vo.footprint) {
      vis_sigmas.resize(size_t(n));
      for (int i = 0; i < n; ++i) {
        const float* ls = &canon.log_scales[3 * size_t(i)];
        vis_sigmas[size_t(i)] = std::exp(std::max(ls[0], std::max(ls[1], ls[2])));
      }
    }
    const int m = visible_points(vis_posed.means.data(), vo.footprint ? vis_sigmas.data() : nullptr,
                                 n, fr.camera, vo, &visible);
    if (m < n) visible_sum += m, ++visible_steps;
    return m < n ? &visible : nullptr;
  }

  // Density-control statistics, then its hook (which may replace the vertex set).
  void density_control() {
    const int n = st.num_vertices();
    for (int i = 0; i < n; ++i) {
      if (rr.radii[i] <= 0) continue;
      const float gx = rg.means2d[2 * size_t(i)], gy = rg.means2d[2 * size_t(i) + 1];
      st.grad2d_accum[i] += std::sqrt(gx * gx + gy * gy);
      st.grad2d_count[i] += 1;
      st.max_radius[i] = std::max(st.max_radius[i], rr.radii[i]);
    }
    if (opt.density_control) {
      st.iteration = it;
      if (opt.density_control->acts_at(it, st.total_iterations)) st.canonical = canon;
      opt.density_control->step(it, st);
    }
  }

  void log(const StepLosses& L) {
    const double psnr = 10.0 * std::log10(1.0 / std::max(L.mse, 1e-12));
    loss_ema = it == 0 ? L.total : 0.9 * loss_ema + 0.1 * L.total;
    psnr_ema = it == 0 ? psnr : 0.9 * psnr_ema + 0.1 * psnr;
    if (opt.progress) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "loss %.4f psnr %.2f N %d", loss_ema, psnr_ema,
                    st.num_vertices());
      progress->update(it + 1, buf);
    }
    if (opt.log_every > 0 && (it % opt.log_every == 0 || it + 1 == opt.iterations)) {
      std::string extra;
      for (auto& c : components) extra += c->log_text();
      std::fprintf(stderr, "it %d loss %.5f l1 %.4f ssim %.4f mask %.4f psnr %.2f%s\n", it, L.total,
                   L.l1, L.ssim, L.mask, psnr, extra.c_str());
    }
  }

  StepLosses step() {
    if (it >= opt.iterations) throw Error("reconstruct: every iteration has run");
    if (order_pos >= order.size()) {
      std::shuffle(order.begin(), order.end(), rng);
      order_pos = 0;
    }
    const bool fine = opt.fine_frames && it >= fine_start;
    const LoadedFrame& fr = (fine ? *opt.fine_frames : frames)[size_t(order[order_pos++])];
    const StepLosses L = forward_backward(fr);
    last_loss = L.total;
    adam.step();
    density_control();
    log(L);
    ++it;
    return L;
  }

  // ---- bake

  Avatar bake(TrainReport* report) {
    if (opt.progress) progress->finish();
    // The final canonical Gaussians and skinning, as a step decodes them.
    decoder.decode(st.anchors, xs, ys, zs, st.log_scale_bias, canon, offsets);
    StepContext ctx;
    ctx.iteration = it;
    ctx.canonical = &canon;
    ctx.state = &st;
    ctx.laplacian = opt.loss.laplacian != LaplacianMode::kNone ? &lap : nullptr;
    for (auto& c : components) c->forward(ctx);
    const int n = st.num_vertices();
    Avatar av;
    av.body_kind = model.kind_name();
    av.body_model = ds.body_model;
    av.betas = ds.betas;
    av.parents = model.parents;
    av.joint_names = model.joint_names;
    av.rest_joints = rest_state.rest_joints;
    av.template_vertices = st.anchors;
    av.template_faces = st.faces;
    av.gaussians = canon;
    // Normalise quaternions for playback.
    for (int i = 0; i < n; ++i) {
      float* q = av.gaussians.quats.data() + 4 * size_t(i);
      const float l = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      if (l > 0)
        for (int k = 0; k < 4; ++k) q[k] /= l;
    }
    av.anchors.resize(3 * size_t(n));
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) av.anchors[3 * size_t(i) + k] = float(st.anchors(i, k));
    av.skin_joints.assign(st.skin_joints.begin(), st.skin_joints.end());
    av.skin_weights = st.skin_weights;
    av.part_labels.assign(st.part_labels.begin(), st.part_labels.end());
    if (model.posedirs.size() > 0 && model.posedirs.cwiseAbs().maxCoeff() > 0) {
      const int Pd = int(model.posedirs.cols());
      const int V = model.num_vertices();
      av.posedirs.resize(3 * size_t(n), Pd);
      for (int k = 0; k < 3; ++k) {
        Eigen::MatrixXd Pk(V, Pd);
        for (int v = 0; v < V; ++v) Pk.row(v) = model.posedirs.row(3 * v + k);
        const Eigen::MatrixXd Qk = body_stencil * Pk;
        for (int i = 0; i < n; ++i) av.posedirs.row(3 * i + k) = Qk.row(i).cast<float>();
      }
    }
    // The settings, with the optional components' keys at their values for "component off";
    // each component's bake below overwrites its own keys (learned_skin, garment...).
    av.metadata = nlohmann::json{
        {"trainer", "kinesplat reconstruct"},
        {"iterations", opt.iterations},
        {"scale", opt.scale},
        {"fine_from_iteration", fine_start},
        {"filter3d", opt.decoder.filter3d},
        {"filter3d_pixel_m", pixel_world},
        {"subdivide", opt.subdivide},
        {"triplane_res", opt.decoder.triplane_res},
        {"triplane_channels", opt.decoder.triplane_channels},
        {"hidden", opt.decoder.hidden},
        {"joint_decoder", opt.decoder.joint},
        {"laplacian", laplacian_name(opt.loss.laplacian)},
        {"perturb", opt.perturb.enabled},
        {"learned_skin", false},
        {"garment", "none"},
        {"garment_follow", 0.0},
        {"garment_follow_profile", std::vector<double>{}},
        {"seed", opt.seed},
        {"frames", frames.size()},
    };
    TrainReport rep;
    rep.iterations = opt.iterations;
    rep.seconds = progress->elapsed_seconds();
    rep.ms_per_iteration = 1000.0 * rep.seconds / opt.iterations;
    rep.final_loss = last_loss;
    rep.final_psnr = float(psnr_ema);
    rep.num_gaussians = n;
    rep.visible_steps = int(visible_steps);
    if (visible_steps > 0) rep.visible_share = double(visible_sum) / double(visible_steps) / n;
    for (auto& c : components) c->bake(av, rep);
    if (report) *report = rep;
    return av;
  }
};

Trainer::Trainer(const BodyModel& model, const Dataset& ds, const std::vector<LoadedFrame>& frames,
                 const TrainOptions& opt)
    : impl_(std::make_unique<Impl>(model, ds, frames, opt)) {}

Trainer::~Trainer() = default;

StepLosses Trainer::step() {
  return impl_->step();
}

StepLosses Trainer::forward_backward(const LoadedFrame& frame) {
  return impl_->forward_backward(frame);
}

Adam& Trainer::optimizer() {
  return impl_->adam;
}

Avatar Trainer::bake(TrainReport* report) {
  return impl_->bake(report);
}

Avatar train_avatar(const BodyModel& model, const Dataset& ds,
                    const std::vector<LoadedFrame>& frames, const TrainOptions& opt,
                    TrainReport* report) {
  Trainer trainer(model, ds, frames, opt);
  for (int it = 0; it < opt.iterations; ++it) trainer.step();
  return trainer.bake(report);
}

}  // namespace ks

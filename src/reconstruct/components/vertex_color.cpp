#include "reconstruct/components/vertex_color.hpp"

#include "core/parallel_copy.hpp"

namespace ks {

void VertexColorComponent::setup(FitTemplate& t, const std::vector<LoadedFrame>&) {
  values_.assign(3 * size_t(t.state->num_vertices()), 0.f);
  grads_.assign(values_.size(), 0.f);
}

void VertexColorComponent::add_parameters(Adam& adam) {
  adam.add_group(name(), &values_, &grads_, opt_.lr);
}

void VertexColorComponent::forward(StepContext& ctx) {
  float* __restrict sh = ctx.canonical->sh.data();
  const float* __restrict v = values_.data();
  const long n = long(values_.size());
#pragma omp parallel for schedule(static) if (n > 65536)
  for (long q = 0; q < n; ++q) sh[q] += v[q];
}

void VertexColorComponent::backward(StepContext& ctx) {
  parallel_assign(grads_, *ctx.dsh);
}

void VertexColorComponent::remap(const Stencil& S, Adam& adam) {
  Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> old(values_.data(),
                                                                                 S.cols(), 3);
  const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor> now =
      (S * old.cast<double>()).cast<float>();
  values_.assign(now.data(), now.data() + now.size());
  grads_.assign(values_.size(), 0.f);
  adam.remap_group(name(), S);
}

}  // namespace ks

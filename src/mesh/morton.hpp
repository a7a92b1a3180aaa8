#pragma once
// Points in the order of a Morton (Z-order) curve through their bounding box: points next to each
// other in this order are close in space (on every axis-aligned projection too). The avatar fit
// numbers its template's vertices this way (reconstruct/trainer.cpp), so that the per-vertex
// passes of a training step (the triplane's texel lookups and scatter above all) walk memory in
// order instead of at the subdivision's numbering.
#include <Eigen/Core>
#include <vector>

namespace ks {

// P: n x 3. Returns a permutation of 0..n-1: the points sorted by the Morton code of their cell
// in a 2^bits per axis grid over their bounding box (bits in [1, 10]), ties by index.
std::vector<int> morton_order(const Eigen::MatrixXd& P, int bits = 10);

}  // namespace ks

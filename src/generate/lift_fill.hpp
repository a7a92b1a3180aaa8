#pragma once
// The lift's step 4 (generate/lift.hpp): what no photo pixel and no mirror coloured, filled by
// propagation over the surface, then smoothed where the photo did not see it well (no seams at the
// fills' edges).
#include <Eigen/Core>
#include <vector>

namespace ks::lift {

// Propagation ring by ring from the vertices whose weight is known_weight or more: each unknown
// vertex next to a known one takes the mean of its known neighbours' colours, then counts as
// known. `adj`: vertex adjacency. Returns how many vertices it coloured (a vertex no known one
// reaches keeps its colour).
int fill_by_propagation(const std::vector<std::vector<int>>& adj, const Eigen::VectorXd& weight,
                        double known_weight, Eigen::MatrixXd& colour);

// `passes` smoothing passes: each moves every vertex towards its neighbours' mean colour by 1 -
// min(1, keep), but for vertices of keep 0.99 or more (they keep theirs).
void smooth_unseen(const std::vector<std::vector<int>>& adj, const Eigen::VectorXd& keep,
                   int passes, Eigen::MatrixXd& colour);

}  // namespace ks::lift

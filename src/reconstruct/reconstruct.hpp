#pragma once
// The reconstruct stage as a whole: a dataset folder -> an avatar file. Loads the frames (and the
// fine phase's), builds the density control by name, trains, records the settings in the avatar's
// metadata and writes it atomically. What `kinesplat reconstruct` and `create` run.
#include <string>

#include "avatar/avatar.hpp"
#include "reconstruct/options.hpp"
#include "reconstruct/trainer.hpp"

namespace ks {

struct ReconstructOptions {
  TrainOptions train;  // its `density_control` and `fine_frames` are set here, not by callers
  // The density control's name: gpdc | vertex | naive | off (reconstruct/density_ops.hpp).
  std::string density = "off";
};

// Throws ks::Error for an unreadable dataset or an unknown density control; nothing is written
// unless training finished. `avatar` (optional) receives the avatar written.
TrainReport reconstruct_avatar(const std::string& dataset_dir, const std::string& out,
                               const ReconstructOptions& options = {}, Avatar* avatar = nullptr);

}  // namespace ks

#pragma once
// The state of a batch item, read from the item's own outputs in DIR/items/ID/ (docs/batch.md):
//   create.json, avatar.ksavatar  written by the item command (`kinesplat create`)
//   submitted                     written by `batch` when it hands the item to a scheduler
//   started, exit_status          written by the item's task script (start; exit status at the end)
//   resources                     "SECONDS PEAK_KB" from /usr/bin/time, where the node has it
//   create.log                    the item command's output
#include <string>
#include <vector>

namespace ks {

enum class ItemState {
  kDone,     // create.json says done and the avatar exists
  kFailed,   // the task ended without an avatar (error from create.json or the log)
  kRunning,  // the task started and has not ended (or its node died: see the log)
  kQueued,   // handed to a scheduler, not started yet
  kPending,  // never handed to a scheduler or run
};

const char* item_state_name(ItemState s);

struct ItemStatus {
  ItemState state = ItemState::kPending;
  std::string error;         // kFailed: the one-line reason
  std::string submitted_by;  // the scheduler named in `submitted` ("local", "slurm"), if any
  std::string job;           // the scheduler's job id from `submitted`, if any
  double seconds = -1;       // wall time of the last finished attempt (resources), -1 unknown
  long long peak_kb = -1;    // peak resident memory of the last attempt, -1 unknown
};

// The layout of an item's folder.
std::string item_dir(const std::string& batch_dir, const std::string& id);
inline const char* const kItemAvatar = "avatar.ksavatar";
inline const char* const kItemLog = "create.log";

ItemStatus read_item_status(const std::string& item_dir);

// The last line of `log_path` that starts with "error:" (without the prefix), "" if none.
std::string last_error_line(const std::string& log_path);

}  // namespace ks

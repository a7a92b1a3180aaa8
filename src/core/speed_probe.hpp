#pragma once
// How fast the machine runs right now, apart from any code of ours: a fixed arithmetic load
// (multiply-adds on a few registers, no memory traffic) on every OpenMP thread at once, timed.
// A shared host's neighbours and its clock changes show here as a larger figure, so that a
// benchmark printed beside it can be read against the machine's state at the time
// (bench/speed_rounds.sh sorts its rounds by it).
#include <cstdint>

namespace ks {

struct SpeedProbe {
  double ms = 0;        // the repetitions' median wall time
  int threads = 0;      // threads that ran the load at once
  double checksum = 0;  // the load's result (the same on every run: proof the work was done)
};

// `reps` repetitions of `iterations` steps on each thread; their median time (ks::median).
SpeedProbe speed_probe(int64_t iterations = 4000000, int reps = 5);

// The load's result for one thread, computed step by step in scalar float arithmetic (what
// speed_probe's checksum must equal per thread).
double speed_probe_reference(int64_t iterations);

}  // namespace ks

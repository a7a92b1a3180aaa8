#pragma once
// A sum over many elements, in parallel and independent of the thread count: the range is cut
// into chunks of a fixed size, each chunk summed by one thread, and the chunk sums added in
// chunk order.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace ks {

// The sum of f(b, e) (a double: the sum over the elements [b, e)) over the chunks of [0, n).
template <class F>
double chunked_sum(size_t n, F&& f, size_t chunk = size_t(1) << 16) {
  const size_t m = (n + chunk - 1) / chunk;
  if (m <= 1) return n ? f(size_t(0), n) : 0.0;
  std::vector<double> part(m);
#pragma omp parallel for schedule(static)
  for (long c = 0; c < long(m); ++c)
    part[size_t(c)] = f(size_t(c) * chunk, std::min(n, size_t(c + 1) * chunk));
  double s = 0;
  for (double p : part) s += p;
  return s;
}

}  // namespace ks

#include "core/progress.hpp"

#include <unistd.h>
#include <algorithm>
#include <cstdio>

namespace ks {

Progress::Progress(std::string label, long total)
    : label_(std::move(label)),
      total_(std::max(1L, total)),
      tty_(::isatty(2)),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

double Progress::elapsed_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::update(long done, const std::string& extra) {
  const auto now = std::chrono::steady_clock::now();
  const double el = elapsed_seconds();
  const double frac = std::clamp(double(done) / total_, 0.0, 1.0);
  const double eta = frac > 0 ? el * (1 - frac) / frac : 0;
  if (tty_) {
    if (done < total_ && std::chrono::duration<double>(now - last_print_).count() < 0.1) return;
    last_print_ = now;
    const int width = 30, fill = int(frac * width);
    std::string bar(fill, '=');
    if (fill < width) bar += '>' + std::string(width - fill - 1, ' ');
    std::fprintf(stderr, "\r%s [%s] %ld/%ld %s eta %.0fs   ", label_.c_str(), bar.c_str(), done,
                 total_, extra.c_str(), eta);
  } else {
    const int decile = int(frac * 10);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    std::fprintf(stderr, "%s %3d%% (%ld/%ld) %s elapsed %.1fs eta %.0fs\n", label_.c_str(),
                 decile * 10, done, total_, extra.c_str(), el, eta);
  }
  std::fflush(stderr);
}

void Progress::finish(const std::string& extra) {
  update(total_, extra);
  if (tty_) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

}  // namespace ks

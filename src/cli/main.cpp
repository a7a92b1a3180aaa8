// kinesplat — one photo in, an animatable Gaussian-splat avatar out.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <utility>
#include <vector>

#include "cli/registry.hpp"
#include "core/error.hpp"

namespace ks::cli {

namespace {
std::vector<std::pair<int, Register>>& groups() {
  static std::vector<std::pair<int, Register>> g;
  return g;
}
}  // namespace

CommandGroup::CommandGroup(int order, Register reg) {
  groups().emplace_back(order, std::move(reg));
}

namespace {
// Every floating-point option of `app` and its subcommands refuses NaN and infinities (CLI11 takes
// "nan", "inf" and "1e999", and a range check lets NaN through).
void require_finite_floats(CLI::App& app) {
  static const CLI::Validator finite(
      [](std::string& v) -> std::string {
        char* end = nullptr;
        const double d = std::strtod(v.c_str(), &end);
        if (end != v.c_str() && *end == '\0' && !std::isfinite(d))
          return "must be a finite number, got " + v;
        return "";
      },
      "", "finite");
  for (CLI::Option* o : app.get_options())
    if (o->get_type_name().rfind("FLOAT", 0) == 0) o->check(finite);
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; }))
    require_finite_floats(*sub);
}
}  // namespace

void register_all(CLI::App& app) {
  auto& g = groups();
  std::stable_sort(g.begin(), g.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (auto& [order, reg] : g) reg(app);
  require_finite_floats(app);
}

}  // namespace ks::cli

int main(int argc, char** argv) {
  CLI::App app{"kinesplat: one photo of a person in, an animatable 3D Gaussian-splat avatar out."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "kinesplat 0.1.0");
  ks::cli::register_all(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message (or the help); a bad command line exits 1 like every other error,
    // not with CLI11's own codes (105 for a value out of range, ...).
    return app.exit(e) == 0 ? 0 : 1;
  } catch (const ks::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}

#pragma once
// Each src/cli/*_cmd.cpp registers its subcommands with a static CommandGroup object:
//   static ks::cli::CommandGroup group(20, [](CLI::App& app) { ... app.add_subcommand(...) ... });
// main.cpp adds the groups in `order`, so `kinesplat --help` lists them in pipeline order.
// A subcommand's callback throws ks::Error for user errors; main prints "error: ..." and exits 1.
#include <CLI/CLI.hpp>
#include <functional>

namespace ks::cli {

using Register = std::function<void(CLI::App&)>;

struct CommandGroup {
  CommandGroup(int order, Register reg);
};

void register_all(CLI::App& app);

}  // namespace ks::cli

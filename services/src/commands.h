#pragma once
// Each CLI subcommand registers itself on the app; main() only parses and reports errors.
#include <CLI/CLI.hpp>

namespace cpgait::services {

void add_ik_commands(CLI::App& app);     // ik, run-tool, demo
void add_model_commands(CLI::App& app);  // model, synth

}  // namespace cpgait::services

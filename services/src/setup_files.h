#pragma once
// Shared by the subcommands that read OpenSim setups: where the files a setup names are, and how
// warnings reach the user.
#include <string>
#include <vector>

namespace cpgait::services {

// A file named by a setup: relative to the setup's folder, as OpenSim resolves it. OpenSim's
// published pipelines keep their models in OutputReference/ beside the setup, so that is tried
// next. Empty stays empty; a missing file throws InputError naming the setup and field.
std::string resolve_setup_file(const std::string& setup_dir, const std::string& name, const std::string& setup_path,
                               const char* field);

void print_warnings(const std::vector<std::string>& warnings);

}  // namespace cpgait::services

// cpgait: motion capture -> musculoskeletal model -> muscle activity -> CPG -> reproduced gait.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "commands.h"
#include "cpgait/capture/input_error.h"

int main(int argc, char** argv) {
  CLI::App app{
      "cpgait: fits an OpenSim musculoskeletal model to recorded walking trials.\n"
      "Units: SI inside (m, rad, s, N); files follow OpenSim's conventions (TRC in its Units, .mot angles in degrees).",
      "cpgait"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "cpgait 0.1.0");
  cpgait::services::add_ik_commands(app);
  cpgait::services::add_dynamics_commands(app);
  cpgait::services::add_activation_commands(app);
  cpgait::services::add_model_commands(app);
  cpgait::services::add_run_tool_command(app);
  cpgait::services::add_scale_command(app);
  cpgait::services::add_run_command(app);
  cpgait::services::add_serve_command(app);
  cpgait::services::add_video_commands(app);
  cpgait::services::add_cpg_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const cpgait::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}

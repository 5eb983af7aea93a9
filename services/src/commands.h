#pragma once
// Each CLI subcommand registers itself on the app; main() only parses and reports errors.
#include <CLI/CLI.hpp>
#include <string>

namespace cpgait::services {

void add_ik_commands(CLI::App& app);        // ik, convert, demo
void add_dynamics_commands(CLI::App& app);  // id
void add_activation_commands(CLI::App& app);  // so, cmc, forward
void add_model_commands(CLI::App& app);     // model, synth
void add_run_tool_command(CLI::App& app);   // run-tool: dispatches on the setup's tool
void add_run_command(CLI::App& app);        // run: the whole pipeline on one trial
void add_serve_command(CLI::App& app);      // serve: the REST service
void add_video_commands(CLI::App& app);     // detect, calibrate, register-tags, capture: AprilTag footage
void add_cpg_commands(CLI::App& app);       // cpg fit, cpg run
void add_scale_command(CLI::App& app);      // scale: OpenSim's ScaleTool setups

struct ToolOverrides;  // setup_files.h

// Runners for OpenSim setups, with the command line's overrides.
void run_ik_setup(const std::string& setup_path, const ToolOverrides& o);
void run_id_setup(const std::string& setup_path, const ToolOverrides& o);
// An AnalyzeTool setup's InverseDynamics analysis: <results>/<name>_InverseDynamics.sto.
void run_id_analysis(const std::string& setup_path, const ToolOverrides& o);
void run_analyze_setup(const std::string& setup_path, const ToolOverrides& o);  // AnalyzeTool: SO and MuscleAnalysis
void run_so_setup(const std::string& setup_path, const ToolOverrides& o);       // AnalyzeTool + StaticOptimization
void run_cmc_setup(const std::string& setup_path, const ToolOverrides& o);      // CMCTool
void run_forward_setup(const std::string& setup_path, const ToolOverrides& o);  // ForwardTool
void run_scale_setup(const std::string& setup_path, const ToolOverrides& o);    // ScaleTool

}  // namespace cpgait::services

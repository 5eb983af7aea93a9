// run-tool: runs an OpenSim tool setup file as OpenSim would.
#include "commands.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/xml_document.h"
#include "setup_files.h"

namespace cpgait::services {

void add_run_tool_command(CLI::App& app) {
  auto* rt = app.add_subcommand("run-tool",
                                "Run an OpenSim tool setup file as OpenSim would: files resolved relative to the setup,\n"
                                "results where the setup says (or in --results).\n"
                                "Supported: InverseKinematicsTool, InverseDynamicsTool, AnalyzeTool (StaticOptimization, InverseDynamics, MuscleAnalysis), CMCTool, ForwardTool, ScaleTool.");
  struct Args {
    std::string setup;
    ToolOverrides o;
  };
  auto a = std::make_shared<Args>();
  rt->add_option("setup", a->setup, "the tool's setup .xml")->required()->check(CLI::ExistingFile);
  rt->add_option("--results", a->o.results, "write results here instead of the setup's results_directory");
  rt->add_option("--model", a->o.model, "use this .osim instead of the setup's model_file")->check(CLI::ExistingFile);
  rt->add_option("--scale-muscles-from", a->o.generic_model,
                 "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  rt->add_option("--bounds", a->o.bounds, "IK coordinate bounds: clamped, all, none")
      ->check(CLI::IsMember({"clamped", "all", "none"}));
  rt->callback([a] {
    const auto d = xml::Document::load_file(a->setup);
    auto root = d.doc().document_element();
    if (std::string(root.name()) == "OpenSimDocument") root = xml::first_element(root);
    const std::string tool(xml::tool_alias(root.name()));
    if (tool == "InverseKinematicsTool") return run_ik_setup(a->setup, a->o);
    if (tool == "InverseDynamicsTool") return run_id_setup(a->setup, a->o);
    if (tool == "AnalyzeTool") return run_analyze_setup(a->setup, a->o);
    if (tool == "CMCTool") return run_cmc_setup(a->setup, a->o);
    if (tool == "ForwardTool") return run_forward_setup(a->setup, a->o);
    if (tool == "ScaleTool") return run_scale_setup(a->setup, a->o);
    throw InputError(a->setup, d.line_of(root), tool,
                     "this tool is not supported yet (supported: InverseKinematicsTool, InverseDynamicsTool, AnalyzeTool with StaticOptimization, InverseDynamics or MuscleAnalysis, CMCTool, ForwardTool, ScaleTool)");
  });
}

}  // namespace cpgait::services

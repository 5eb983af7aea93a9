// ik, run-tool and demo: marker IK from the command line, OpenSim setups, and a self-contained demo.
#include <cstdio>
#include <filesystem>
#include <string>

#include "commands.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

C3dVertical parse_c3d_vertical(const std::string& s) {
  return s == "z" ? C3dVertical::kZ : s == "y" ? C3dVertical::kY : C3dVertical::kAuto;
}

IkOptions::Bounds parse_bounds(const std::string& s) {
  if (s == "clamped") return IkOptions::Bounds::kClampedOnly;
  if (s == "all") return IkOptions::Bounds::kAllRanges;
  return IkOptions::Bounds::kNone;
}

struct IkRun {
  std::string motion_path;
  std::string errors_path;
  IkResult result;
};

IkRun run_ik_and_write(const Model& model, const MarkerTrial& trial, const IkTaskSet& tasks, const IkOptions& options,
                       const Storage* coordinate_reference, const std::string& out_dir, const std::string& motion_file,
                       const std::string& errors_file, bool report_errors) {
  IkRun run;
  run.result = inverse_kinematics(model, trial, tasks, options, coordinate_reference);
  ensure_directory(out_dir);
  run.motion_path = (fs::path(out_dir) / motion_file).string();
  write_storage_atomic(ik_coordinates_table(model, run.result), run.motion_path);
  if (report_errors) {
    run.errors_path = (fs::path(out_dir) / errors_file).string();
    write_storage_atomic(ik_marker_errors_table(run.result), run.errors_path);
  }
  print_warnings(run.result.summary.warnings);
  std::printf("%s\nwrote %s%s%s\n", run.result.summary.BriefReport().c_str(), run.motion_path.c_str(),
              report_errors ? "\nwrote " : "", report_errors ? run.errors_path.c_str() : "");
  return run;
}

}  // namespace

void run_ik_setup(const std::string& setup_path, const ToolOverrides& o) {
  const IkSetup s = read_ik_setup(setup_path);
  const std::string model_path = o.model_file(s.setup_dir, s.model_file, setup_path);
  const OsimReadResult mr = read_osim(model_path);
  print_warnings(mr.warnings);
  const MarkerTrial trial = read_marker_file(resolve_setup_file(s.setup_dir, s.marker_file, setup_path, "marker_file"));
  print_warnings(trial.warnings);
  Storage reference;
  const bool have_reference = !s.coordinate_file.empty();
  if (have_reference)
    reference = read_storage(resolve_setup_file(s.setup_dir, s.coordinate_file, setup_path, "coordinate_file"));
  IkOptions options;
  options.time_range_s = s.time_range_s;
  options.bounds = parse_bounds(o.bounds);
  const std::string out_dir = o.results_dir(s.setup_dir, s.results_directory);
  const std::string name = s.name.empty() ? "ik" : s.name;
  const std::string motion = s.output_motion_file.empty() ? name + "_ik.mot" : s.output_motion_file;
  run_ik_and_write(mr.model, trial, s.tasks, options, have_reference ? &reference : nullptr, out_dir, motion,
                   name + "_ik_marker_errors.sto", s.report_errors);
}

namespace {
// convert: a C3D trial for OpenSim.
void add_convert_command(CLI::App& app) {
  auto* convert = app.add_subcommand(
      "convert",
      "Convert a C3D trial for OpenSim, in its Y-up frame (the lab's vertical from the force plates or POINT:Y_SCREEN, or\n"
      "--c3d-vertical): DIR/<name>.trc (mm); with force plates, DIR/<name>_grf.mot (per plate and foot: force N,\n"
      "centre of pressure m, free torque N m, on the subject) and DIR/<name>_grf.xml, the ExternalLoads applying each\n"
      "to the foot whose heel marker is nearest (or --plate-foot). Its EVENTs are listed.");
  struct ConvertArgs {
    std::string input, out, c3d_vertical = "auto";
    std::vector<std::string> plate_foot;
    GroundReactionOptions grf;
  };
  auto c = std::make_shared<ConvertArgs>();
  convert->add_option("input", c->input, "the trial (.c3d)")->required()->check(CLI::ExistingFile);
  convert->add_option("--c3d-vertical", c->c3d_vertical, "the file's vertical axis: auto, z or y")
      ->check(CLI::IsMember({"auto", "z", "y"}))
      ->capture_default_str();
  convert->add_option("--threshold", c->grf.threshold_N, "vertical force (N) below which a plate is unloaded")->capture_default_str();
  convert->add_option("--lowpass", c->grf.lowpass_hz, "low-pass the plates' forces and moments at this cutoff (Hz) before the COP; 0: none")
      ->capture_default_str();
  convert->add_option("--plate-foot", c->plate_foot, "a plate's foot instead of the nearest heel marker's: N=r or N=l");
  convert->add_option("--right-body", c->grf.right_body, "the body the right foot's loads act on")->capture_default_str();
  convert->add_option("--left-body", c->grf.left_body, "the body the left foot's loads act on")->capture_default_str();
  convert->add_option("-o,--output", c->out, "output folder")->required();
  convert->callback([c] {
    for (const std::string& pf : c->plate_foot) {
      const auto eq = pf.find('=');
      if (eq == std::string::npos || eq + 2 != pf.size() || (pf.back() != 'r' && pf.back() != 'l'))
        throw InputError("cpgait convert", 0, "--plate-foot", "expected N=r or N=l, got '" + pf + "'");
      c->grf.plate_foot[std::stoi(pf.substr(0, eq))] = pf.back();
    }
    const C3dFile file = read_c3d(c->input);
    const Eigen::Matrix3d to_opensim = c3d_to_opensim(file, parse_c3d_vertical(c->c3d_vertical));
    MarkerTrial trial = file.markers;
    trial.positions_m = to_opensim * trial.positions_m;
    print_warnings(trial.warnings);
    ensure_directory(c->out);
    const std::string stem = fs::path(c->input).stem().string();
    const std::string trc = (fs::path(c->out) / (stem + ".trc")).string();
    write_text_atomic(trc, format_trc(trial, "mm"));
    std::printf("wrote %s (%d markers x %d frames at %g Hz, %zu gaps)\n", trc.c_str(), trial.num_markers(), trial.num_frames(),
                trial.data_rate_hz, trial.gaps().size());
    for (const auto& e : file.events) std::printf("event %s %s at %.4f s\n", e.context.c_str(), e.label.c_str(), e.time_s);
    GroundReactions g = ground_reactions(file, to_opensim, c->grf);
    g.grf.name = stem + "_grf";
    print_warnings(g.warnings);
    if (g.loads.empty()) return;
    for (const auto& st : g.stances)
      std::printf("plate %d: %s foot, %.3f-%.3f s, peak %.0f N\n", st.plate, st.foot == 'r' ? "right" : st.foot == 'l' ? "left" : "unknown",
                  st.begin_s, st.end_s, st.peak_vertical_N);
    const std::string mot = (fs::path(c->out) / (stem + "_grf.mot")).string(), xml = (fs::path(c->out) / (stem + "_grf.xml")).string();
    write_storage_atomic(g.grf, mot);
    write_text_atomic(xml, external_loads_document(g, stem + "_grf.mot"));
    std::printf("wrote %s (%zu loads x %d samples at %g Hz)\nwrote %s\n", mot.c_str(), g.loads.size(), g.grf.num_rows(),
                file.analog.rate_hz, xml.c_str());
  });
}

}  // namespace

void add_ik_commands(CLI::App& app) {
  // ---- ik
  auto* ik = app.add_subcommand("ik",
                                "Inverse kinematics: fit the model's coordinates to measured markers, frame by frame.\n"
                                "Inputs: an .osim model, a .trc (mm, cm or m) or .c3d marker file, optional weights.\n"
                                "Outputs in DIR: <name>_ik.mot (angles in degrees, translations in m) and\n"
                                "<name>_ik_marker_errors.sto (per frame: total squared error m^2, RMS and max error m, the\n"
                                "worst marker's column position, then each tracked marker's error m).");
  struct IkArgs {
    std::string model, markers, setup, tasks, marker_set, out, name, bounds = "clamped", c3d_vertical = "auto";
    std::vector<double> time;
  };
  auto a = std::make_shared<IkArgs>();
  ik->add_option("--model", a->model, "OpenSim model (.osim), 3.x or 4.x")->required()->check(CLI::ExistingFile);
  ik->add_option("--markers", a->markers, "marker trajectories (.trc or .c3d)")->required()->check(CLI::ExistingFile);
  ik->add_option("--c3d-vertical", a->c3d_vertical, "a .c3d's vertical axis: auto (from the file), z (turned to OpenSim's Y-up) or y (as recorded)")
      ->check(CLI::IsMember({"auto", "z", "y"}))
      ->capture_default_str();
  ik->add_option("--setup", a->setup, "OpenSim IK setup (.xml) whose IKTaskSet and time range are used")
      ->check(CLI::ExistingFile);
  ik->add_option("--tasks", a->tasks, "IK task weights: an IKTaskSet .xml or the .json equivalent")
      ->check(CLI::ExistingFile);
  ik->add_option("--marker-set", a->marker_set, "marker-set XML that replaces/adds model markers")
      ->check(CLI::ExistingFile);
  ik->add_option("--time", a->time, "first and last time to solve, seconds")->expected(2);
  ik->add_option("--bounds", a->bounds, "coordinate ranges as bounds: clamped (OpenSim: only clamped coordinates), all, none")
      ->check(CLI::IsMember({"clamped", "all", "none"}));
  ik->add_option("--name", a->name, "output file prefix (default: the marker file's name)");
  ik->add_option("-o,--output", a->out, "output folder")->required();
  ik->callback([a] {
    OsimReadOptions ro;
    ro.marker_set_file = a->marker_set;
    const OsimReadResult mr = read_osim(a->model, ro);
    print_warnings(mr.warnings);
    const MarkerTrial trial = read_marker_file(a->markers, parse_c3d_vertical(a->c3d_vertical));
    print_warnings(trial.warnings);
    IkOptions options;
    options.bounds = parse_bounds(a->bounds);
    IkTaskSet tasks;
    if (!a->setup.empty()) {
      const IkSetup s = read_ik_setup(a->setup);
      tasks = s.tasks;
      options.time_range_s = s.time_range_s;
    }
    if (!a->tasks.empty()) tasks = read_ik_tasks(a->tasks);
    if (a->time.size() == 2) options.time_range_s = std::make_pair(a->time[0], a->time[1]);
    const std::string name = a->name.empty() ? fs::path(a->markers).stem().string() : a->name;
    run_ik_and_write(mr.model, trial, tasks, options, nullptr, a->out, name + "_ik.mot", name + "_ik_marker_errors.sto",
                     true);
  });

  add_convert_command(app);

  // ---- demo
  auto* demo = app.add_subcommand("demo",
                                  "Self-contained run: synthesizes a walking trial from cpgait's fixture model\n"
                                  "(1 mm marker noise, gaps), runs IK on it and reports the error against the truth.\n"
                                  "Writes DIR/synthetic.trc and the IK results.");
  auto demo_out = std::make_shared<std::string>("demo-output");
  demo->add_option("-o,--output", *demo_out, "output folder (default ./demo-output)");
  demo->callback([demo_out] {
    const std::string model_path = std::string(fixtures::fixtures_dir()) + "/models/walker.osim";
    const OsimReadResult mr = read_osim(model_path);
    fixtures::SyntheticTrialOptions so;
    so.noise_m = 0.001;
    so.gap_fraction = 0.2;
    const auto synth = fixtures::synthesize_trial(mr.model, so);
    ensure_directory(*demo_out);
    const std::string trc = (fs::path(*demo_out) / "synthetic.trc").string();
    write_text_atomic(trc, format_trc(synth.markers, "mm"));
    std::printf("model %s: %zu bodies, %d coordinates, %zu markers, %zu muscles\n", model_path.c_str(),
                mr.model.bodies.size() - 1, mr.model.num_coordinates(), mr.model.markers.size(), mr.model.muscles.size());
    std::printf("wrote %s (%d frames, %d markers, %zu gaps)\n", trc.c_str(), synth.markers.num_frames(),
                synth.markers.num_markers(), synth.markers.gaps().size());
    const MarkerTrial trial = read_trc(trc);
    const IkRun run = run_ik_and_write(mr.model, trial, {}, {}, nullptr, *demo_out, "synthetic_ik.mot",
                                       "synthetic_ik_marker_errors.sto", true);
    double worst_deg = 0;
    std::string worst;
    for (int c = 0; c < mr.model.num_coordinates(); ++c) {
      if (!mr.model.coordinates[c].is_angle()) continue;
      const double rms = std::sqrt((run.result.q.col(c) - synth.q.col(c)).array().square().mean()) * 180 / M_PI;
      if (rms > worst_deg) worst_deg = rms, worst = mr.model.coordinates[c].name;
    }
    std::printf("largest coordinate RMS error against the truth: %.3f deg (%s)\n", worst_deg, worst.c_str());
  });
}

}  // namespace cpgait::services

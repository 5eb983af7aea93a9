// model (inspect an .osim) and synth (write a synthetic trial).
#include <cstdio>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "output_files.h"

namespace cpgait::services {

void add_model_commands(CLI::App& app) {
  auto* model = app.add_subcommand("model",
                                   "Read an OpenSim model and print what cpgait understood as JSON: bodies (kg), coordinates\n"
                                   "(ranges in rad or m), markers, muscles and every warning about what it does not use.");
  struct ModelArgs {
    std::string path, marker_set;
  };
  auto a = std::make_shared<ModelArgs>();
  model->add_option("model", a->path, "the .osim file")->required()->check(CLI::ExistingFile);
  model->add_option("--marker-set", a->marker_set, "marker-set XML to apply")->check(CLI::ExistingFile);
  model->callback([a] {
    OsimReadOptions ro;
    ro.marker_set_file = a->marker_set;
    const OsimReadResult r = read_osim(a->path, ro);
    const Model& m = r.model;
    nlohmann::json j;
    j["name"] = m.name;
    j["mass_kg"] = m.total_mass_kg();
    for (std::size_t b = 1; b < m.bodies.size(); ++b)
      j["bodies"].push_back({{"name", m.bodies[b].name}, {"mass_kg", m.bodies[b].mass_kg}});
    for (const auto& c : m.coordinates)
      j["coordinates"].push_back({{"name", c.name},
                                  {"joint", m.joints[c.joint].name},
                                  {"unit", c.is_angle() ? "rad" : "m"},
                                  {"range", {c.range_min, c.range_max}},
                                  {"default", c.default_value},
                                  {"clamped", c.clamped},
                                  {"locked", c.locked}});
    for (const auto& mk : m.markers) j["markers"].push_back({{"name", mk.name}, {"body", m.bodies[mk.body].name}});
    const std::vector<double> fiber = normalized_fiber_lengths_at_default_pose(m);
    for (std::size_t k = 0; k < m.muscles.size(); ++k) {
      const Muscle& mu = m.muscles[k];
      j["muscles"].push_back({{"name", mu.name}, {"type", mu.type}, {"max_isometric_force_N", mu.max_isometric_force_N},
                              {"path_points", mu.path.size()}, {"fiber_length_at_default_pose_normalized", fiber[k]}});
    }
    j["warnings"] = r.warnings;
    if (const std::string w = unscaled_muscles_warning(m); !w.empty()) j["warnings"].push_back(w);
    std::printf("%s\n", json_text(j, 2).c_str());
  });

  auto* synth = app.add_subcommand("synth",
                                   "Write a synthetic walking trial (.trc) from a model: smooth periodic coordinates,\n"
                                   "markers by forward kinematics, optional Gaussian noise (mm) and gaps; the true\n"
                                   "coordinates go to <output>.truth.mot (degrees).");
  struct SynthArgs {
    std::string model, out, units = "mm";
    fixtures::SyntheticTrialOptions o;
    double noise_mm = 0;
  };
  auto s = std::make_shared<SynthArgs>();
  synth->add_option("--model", s->model, "the .osim file")->required()->check(CLI::ExistingFile);
  synth->add_option("-o,--output", s->out, "the .trc to write")->required();
  synth->add_option("--duration", s->o.duration_s, "seconds")->capture_default_str();
  synth->add_option("--rate", s->o.rate_hz, "frames per second")->capture_default_str();
  synth->add_option("--noise-mm", s->noise_mm, "marker noise standard deviation, mm")->capture_default_str();
  synth->add_option("--gaps", s->o.gap_fraction, "fraction of markers given one gap")->capture_default_str();
  synth->add_option("--units", s->units, "TRC units")->check(CLI::IsMember({"mm", "cm", "m"}));
  synth->add_option("--seed", s->o.seed, "random seed")->capture_default_str();
  synth->callback([s] {
    const OsimReadResult r = read_osim(s->model);
    s->o.noise_m = s->noise_mm * 1e-3;
    const auto t = fixtures::synthesize_trial(r.model, s->o);
    write_text_atomic(s->out, format_trc(t.markers, s->units));
    const Storage truth = make_storage("synthetic truth", coordinate_names(r.model), t.markers.time_s,
                                       coordinates_in_file_units(r.model, t.q), true);
    write_storage_atomic(truth, s->out + ".truth.mot");
    std::printf("wrote %s and %s.truth.mot (%d frames)\n", s->out.c_str(), s->out.c_str(), t.markers.num_frames());
  });
}

}  // namespace cpgait::services

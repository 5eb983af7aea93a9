#pragma once
// A pipeline stage: its name, the stages it needs, the files it writes, its options (described once
// in options_fields.h: reader, writer and schema) and a run over the trial. The pipeline
// (pipeline.h) is a table of stages in run order and knows none of them by name.
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <typeindex>
#include <utility>
#include <vector>

#include "cpgait/capture/storage.h"
#include "cpgait/capture/trc.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/model/model.h"
#include "cpgait/progress.h"
#include "options_fields.h"
#include "trial_inputs.h"

namespace cpgait::services {

// What earlier stages produced for later ones, one value per type.
class StageProducts {
 public:
  template <class T>
  void put(T value) {
    items_[typeid(T)] = std::make_shared<const T>(std::move(value));
  }
  template <class T>
  const T* find() const {
    const auto it = items_.find(typeid(T));
    return it == items_.end() ? nullptr : static_cast<const T*>(it->second.get());
  }

 private:
  std::map<std::type_index, std::shared_ptr<const void>> items_;
};

// The trial as the stages see it.
struct StageContext {
  const TrialInputs& inputs;
  std::string out_dir;
  Model model;                          // the capture stage adds the tag markers
  MarkerTrial markers;                  // from the TRC, or made by the capture stage
  std::unique_ptr<AppliedLoads> loads;  // null without GRF
  std::optional<std::pair<double, double>> time_range_s;
  StageProducts products;
  std::vector<std::string> files;  // written so far, relative to out_dir
  Progress* progress = nullptr;    // the running stage's
  // Options a stage computed that job.json records so that it reproduces the run (the scale
  // factors): stage -> {key: value}.
  std::map<std::string, nlohmann::json> recorded_options;

  // Writes <trial name><suffix> into out_dir atomically (digits: write_storage_atomic's) and records it.
  void write(const Storage& table, const std::string& suffix, int digits = 12);
  void write_text(const std::string& text, const std::string& suffix);
};

class Stage {
 public:
  virtual ~Stage() = default;
  virtual std::string name() const = 0;
  virtual std::string description() const = 0;
  virtual std::vector<std::string> needs() const { return {}; }
  // Suffixes after the trial's name: every file written, and the tables the results endpoint serves.
  virtual std::vector<std::string> writes() const = 0;
  virtual std::vector<std::string> tables() const = 0;
  // Whether the trial's inputs call for the stage (capture: footage only). A selectable stage runs
  // when "stages" lists it; one that is not runs whenever it applies.
  virtual bool applies(const TrialInputs&) const { return true; }
  virtual bool selectable() const { return true; }
  // An activation stage (static optimization, CMC) names its method: the options' "activation" picks
  // the one that runs, and a stage that needs "activation" builds on it. Other stages: empty.
  virtual std::string activation_method() const { return ""; }

  // The stage's options object, complete (defaults filled in); errors name "<stage>.<field>".
  virtual nlohmann::json normalize_options(const nlohmann::json& given, const std::string& source) const = 0;
  virtual nlohmann::json options_schema() const = 0;
  // What can be checked before anything runs, so that an upload is refused at once.
  virtual void validate(const StageContext& trial, const nlohmann::json& options) const = 0;
  // Runs the stage and returns its summary; a stage that cannot run on this trial says why in it.
  virtual nlohmann::json run(StageContext& trial, const nlohmann::json& options) const = 0;
};

// A stage whose options are a described struct (options_fields.h).
template <DescribedOptions Options>
class StageWithOptions : public Stage {
 public:
  nlohmann::json normalize_options(const nlohmann::json& given, const std::string& source) const final {
    return Options::fields().write(read(given, source));
  }
  nlohmann::json options_schema() const final { return Options::fields().schema(); }
  void validate(const StageContext& trial, const nlohmann::json& options) const final { check(trial, read(options, "options")); }
  nlohmann::json run(StageContext& trial, const nlohmann::json& options) const final { return execute(trial, read(options, "options")); }

 protected:
  Options read(const nlohmann::json& j, const std::string& source) const {
    Options o;
    Options::fields().read(j, o, OptionPath{source, name() + "."});
    return o;
  }
  virtual void check(const StageContext&, const Options&) const {}
  virtual nlohmann::json execute(StageContext& trial, const Options& options) const = 0;
};

// Stages in run order.
using StageTable = std::vector<const Stage*>;

// cpgait's pipeline (stages/stage_table.cpp).
const StageTable& pipeline_stages();

}  // namespace cpgait::services

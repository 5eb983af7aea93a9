// The options document: top-level fields, then one object per stage, read, written and published as
// JSON Schema from one description (options_fields.h).
#include <algorithm>

#include "cpgait/capture/json_input.h"
#include "pipeline.h"
#include "output_files.h"

namespace cpgait::services {
using nlohmann::json;

namespace {

std::vector<std::string> activation_methods(const StageTable& table) {
  std::vector<std::string> names;
  for (const Stage* s : table)
    if (!s->activation_method().empty()) names.push_back(s->activation_method());
  return names;
}

std::vector<std::string> selectable_stages(const StageTable& table) {
  std::vector<std::string> names;
  for (const Stage* s : table)
    if (s->selectable()) names.push_back(s->name());
  return names;
}

json stages_field_schema(const StageTable& table) {
  return {{"type", "array"},
          {"items", {{"type", "string"}, {"enum", selectable_stages(table)}}},
          {"minItems", 1},
          {"description", "the stages to run; each needs the stages it builds on (GET /api/v1/stages)"}};
}

void read_stages(const json& v, PipelineOptions& o, const OptionPath& p) {
  const std::vector<std::string> known = selectable_stages(o.table());
  std::string list;
  for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
  if (!v.is_array() || v.empty()) p.fail("stages", "expected a non-empty array of stage names");
  o.stages.clear();
  for (const auto& s : v) {
    if (!s.is_string() || std::find(known.begin(), known.end(), s.get<std::string>()) == known.end())
      p.fail("stages", "unknown stage " + json_text(s) + " (stages: " + list + ")");
    o.stages.push_back(s.get<std::string>());
  }
  for (const std::string& name : o.stages)
    for (const std::string& named : find_stage(name, o.table())->needs()) {
      const std::string need = o.resolve_need(named);
      if (const Stage* n = find_stage(need, o.table()); !n || (n->selectable() && !o.wants(need)))
        p.fail("stages", "stage '" + name + "' needs '" + need + "'" + (named == need ? "" : " (the activation)"));
    }
}

void read_time_range(const json& t, PipelineOptions& o, const OptionPath& p) {
  if (!t.is_array() || t.size() != 2 || !t[0].is_number() || !t[1].is_number() || !(t[0].get<double>() <= t[1].get<double>()))
    p.fail("time_range", "expected [first, last] in seconds with first <= last");
  o.time_range_s = std::make_pair(t[0].get<double>(), t[1].get<double>());
}

OptionFields<PipelineOptions> top_level_fields(const StageTable& table) {
  using P = PipelineOptions;
  OptionFields<P> f("cpgait pipeline options (job.json): which stages run and each stage's options; every key optional.");
  f.text("model", &P::model_id, "server only: the uploaded model's id (POST /api/v1/models); `walker` is built in");
  f.text("scale_muscles_from", &P::scale_muscles_from_id,
         "server only: the uploaded generic model the trial's model was scaled from; fibre and tendon lengths are then "
         "scaled by each path's length ratio, as OpenSim's ScaleTool does (cpgait run --scale-muscles-from)");
  // Read before "stages" (keys are read in order), which checks needs against it.
  f.choice("activation", &P::activation, activation_methods(table),
           "how muscle activity is estimated for the CPG: static optimization's activations (so) or computed muscle "
           "control's excitations (cmc, as the seed method; the reproduced gait then uses compliant tendons)");
  f.add({"stages", stages_field_schema(table), read_stages, [](const P& o, json& j) { j["stages"] = o.stages; }});
  f.add({"time_range",
         {{"type", "array"}, {"items", {{"type", "number"}}}, {"minItems", 2}, {"maxItems", 2}, {"x-unit", "s"},
          {"description", "[first, last] frame times to process; absent: the whole trial"}},
         read_time_range,
         [](const P& o, json& j) {
           if (o.time_range_s) j["time_range"] = {o.time_range_s->first, o.time_range_s->second};
         }});
  for (const Stage* stage : table) {
    const std::string name = stage->name();
    json schema = stage->options_schema();
    schema["description"] = stage->description() + ". " + schema.value("description", "");
    f.add({name, schema,
           [stage, name](const json& v, P& o, const OptionPath& p) { o.stage_options[name] = stage->normalize_options(v, p.source); },
           [name](const P& o, json& j) { j[name] = o.stage_options.at(name); }});
  }
  f.add({"inputs",
         {{"type", "object"}, {"description", "cpgait run only: the input files it ran on (model, generic_model, markers, grf, loads, videos, calibration, tags, name)"}},
         [](const json& v, P& o, const OptionPath& p) {
           if (!v.is_object()) p.fail("inputs", "expected an object of file paths");
           o.inputs = v;
         },
         [](const P& o, json& j) {
           if (!o.inputs.empty()) j["inputs"] = o.inputs;
         }});
  return f;
}

}  // namespace

PipelineOptions::PipelineOptions(const StageTable& table) : stages(selectable_stages(table)), table_(&table) {
  for (const Stage* s : table) stage_options[s->name()] = s->normalize_options(json::object(), "options");
}

bool PipelineOptions::wants(const std::string& stage) const {
  return std::find(stages.begin(), stages.end(), stage) != stages.end();
}

bool PipelineOptions::runs(const Stage& stage, const TrialInputs& in) const {
  const std::string method = stage.activation_method();
  return stage.applies(in) && (!stage.selectable() || wants(stage.name())) && (method.empty() || method == activation);
}

void PipelineOptions::set_stage_option(const std::string& stage, const std::string& key, const json& value, const std::string& source) {
  json o = stage_options.at(stage);
  o[key] = value;
  stage_options[stage] = find_stage(stage, table())->normalize_options(o, source);
}

PipelineOptions PipelineOptions::parse(const std::string& text, const std::string& source, const StageTable& table) {
  return from_json(text.empty() ? json::object() : parse_json_input(text, source), source, table);
}

PipelineOptions PipelineOptions::from_json(const json& j, const std::string& source, const StageTable& table) {
  PipelineOptions o(table);
  top_level_fields(table).read(j, o, OptionPath{source, ""});
  return o;
}

json PipelineOptions::to_json() const { return top_level_fields(table()).write(*this); }

json pipeline_options_schema(const StageTable& table) {
  json s = top_level_fields(table).schema(PipelineOptions(table));
  s["$schema"] = "https://json-schema.org/draft/2020-12/schema";
  s["title"] = "cpgait pipeline options";
  return s;
}

json pipeline_stages_json(const StageTable& table) {
  json out = json::array();
  for (const Stage* s : table)
    out.push_back({{"name", s->name()},
                   {"description", s->description()},
                   {"needs", s->needs()},
                   {"writes", s->writes()},
                   {"tables", s->tables()},
                   {"selectable", s->selectable()}});
  return out;
}

const Stage* find_stage(const std::string& name, const StageTable& table) {
  for (const Stage* s : table)
    if (s->name() == name) return s;
  return nullptr;
}

}  // namespace cpgait::services

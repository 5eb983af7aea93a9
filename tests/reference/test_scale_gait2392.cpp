// OpenSim's Scale tool on gait2392's subject01 setup: the ModelScaler's per-body scale factors from
// the setup's measurements on the static trial, against the scale set OpenSim 4.1 applied here
// (../shared/reference/opensim41-here/Scale/subject01_scaleSet_applied.xml, printed to 6 digits).
#include <gtest/gtest.h>

#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/trc.h"
#include "cpgait/capture/xml_document.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "test_support.h"

namespace cpgait {
namespace {

TEST(ScaleGait2392, MeasurementScaleFactorsMatchOpenSim41) {
  const std::string pipeline = refdata::shared_path("opensim/gait2392/pipeline/");
  const std::string generic = refdata::shared_path("opensim/gait2392/model/gait2392_simbody.osim");
  const std::string applied = refdata::shared_path("opensim41-here/Scale/subject01_scaleSet_applied.xml");
  for (const auto& f : {pipeline + "subject01_Setup_Scale.xml", pipeline + "gait2392_Scale_MarkerSet.xml",
                        pipeline + "subject01_static.trc", generic, applied})
    REQUIRE_REFERENCE(f);
  const ScaleSetup setup = read_scale_setup(pipeline + "subject01_Setup_Scale.xml");
  EXPECT_EQ(setup.model_file, "gait2392_simbody.osim");
  EXPECT_DOUBLE_EQ(setup.mass_kg, 72.6);
  ASSERT_EQ(setup.scaling_order.size(), 2u);
  EXPECT_TRUE(setup.preserve_mass_distribution);
  OsimReadOptions o;
  o.marker_set_file = pipeline + setup.marker_set_file;
  const Model model = read_osim(generic, o).model;
  const MarkerTrial trial = read_trc(pipeline + setup.marker_file);
  const ModelScaleFactors f = model_scale_factors(model, setup, &trial);
  // The setup scales the patellae, which gait2392_simbody does not have (OpenSim ignores them too).
  for (const auto& w : f.warnings) EXPECT_NE(w.find("patella"), std::string::npos) << w;

  // OpenSim's applied scale set, body by body.
  const auto d = xml::Document::load_file(applied);
  int compared = 0;
  double worst = 0;
  for (const auto& sc : d.doc().document_element().child("ScaleSet").child("objects").children("Scale")) {
    const std::string body = d.text(sc, "segment");
    const auto v = d.numbers(sc, "scales");
    const int b = model.body_index(body);
    if (b < 0) continue;  // OpenSim lists every frame; the model's bodies are what we scale
    for (int k = 0; k < 3; ++k) {
      const double rel = std::abs(f.body[b][k] - v[k]) / v[k];
      worst = std::max(worst, rel);
      EXPECT_LT(rel, 5e-6) << body << " axis " << k << ": ours " << f.body[b][k] << ", OpenSim's " << v[k];
    }
    ++compared;
  }
  std::printf("%d bodies' scale factors, largest relative difference from OpenSim 4.1's %.1e (it prints 6 digits)\n", compared,
              worst);
  EXPECT_EQ(compared, static_cast<int>(model.bodies.size()));
}

}  // namespace
}  // namespace cpgait

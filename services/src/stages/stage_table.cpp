// cpgait's pipeline: its stages in run order. A new stage is its own file and one line here.
#include "stage.h"

namespace cpgait::services {

const Stage& scale_stage();
const Stage& capture_stage();
const Stage& ik_stage();
const Stage& id_stage();
const Stage& so_stage();
const Stage& cmc_stage();
const Stage& cpg_stage();
const Stage& gait_stage();

const StageTable& pipeline_stages() {
  static const StageTable table = {
      &scale_stage(), &capture_stage(), &ik_stage(), &id_stage(), &so_stage(), &cmc_stage(), &cpg_stage(), &gait_stage(),
  };
  return table;
}

}  // namespace cpgait::services

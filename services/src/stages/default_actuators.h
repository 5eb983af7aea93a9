#pragma once
// The ideal actuators the activation stages add when the trial brings none: residuals on the root
// joint's coordinates and reserves on the others, all weak (optimal force 1 N or N m), so that static
// optimization and CMC are always feasible and prefer the muscles.
#include <vector>

#include "cpgait/capture/actuator_set.h"
#include "cpgait/model/model.h"

namespace cpgait::services {

inline std::vector<ActuatorSpec> default_actuators(const Model& model) {
  std::vector<ActuatorSpec> out;
  for (const Joint& j : model.joints)
    for (int c : j.coordinates) {
      ActuatorSpec a;
      a.coordinate = model.coordinates[c].name;
      a.name = a.coordinate + (j.parent_body == 0 ? "_residual" : "_reserve");
      a.optimal_force = 1.0;
      out.push_back(a);
    }
  return out;
}

}  // namespace cpgait::services

#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

std::vector<int> ancestor_coordinates(const Model& model, int body) {
  std::vector<int> out;
  while (body > 0) {
    const Joint& j = model.joints[model.bodies[body].joint];
    out.insert(out.begin(), j.coordinates.begin(), j.coordinates.end());
    body = j.parent_body;
  }
  return out;
}

}  // namespace cpgait

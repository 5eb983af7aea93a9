#include "cpgait/scaling/scale_model.h"

#include <cmath>
#include <stdexcept>

#include "cpgait/muscles/scale_muscle_parameters.h"

namespace cpgait {
namespace {

// Body::scaleInertialProperties: uniform factors scale the inertia by s^2 (and the mass's change);
// otherwise the body is seen as a cylinder along its smallest principal moment, stretched.
void scale_inertia(Body& b, const Eigen::Vector3d& s, bool scale_mass) {
  const double unscaled_mass = b.mass_kg, volume = std::abs(s[0] * s[1] * s[2]);
  if (scale_mass) b.mass_kg *= volume;
  Eigen::Matrix3d I = b.inertia_kg_m2;
  if (b.mass_kg <= 2.2e-16) {
    I.setZero();
  } else if (std::abs(s[0] - s[1]) <= 1e-12 * std::abs(s[0]) && std::abs(s[1] - s[2]) <= 1e-12 * std::abs(s[1])) {
    if (scale_mass) I *= volume;
    I *= s[0] * s[0];
  } else {
    const int axis = I(0, 0) <= I(1, 1) ? (I(0, 0) <= I(2, 2) ? 0 : 2) : (I(1, 1) <= I(2, 2) ? 1 : 2);
    const double term = 2.0 * I(axis, axis) / unscaled_mass;
    const double radius = term < 0 ? 0.0 : std::sqrt(term);
    const int oa = axis == 0 ? 1 : 0;
    const double lterm = 12.0 * (I(oa, oa) - 0.25 * unscaled_mass * radius * radius) / unscaled_mass;
    const double length = (lterm < 0 ? 0.0 : std::sqrt(lterm)) * s[axis];
    const int a1 = axis == 0 ? 1 : 0, a2 = axis == 2 ? 1 : 2;
    const double rad_sqr = radius * s[a1] * radius * s[a2];
    const double m = b.mass_kg;
    for (int k = 0; k < 3; ++k) I(k, k) = k == axis ? 0.5 * m * rad_sqr : m * (length * length / 12.0 + 0.25 * rad_sqr);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (i != j) I(i, j) *= s[i] * s[j] * (scale_mass ? volume : 1.0);
  }
  b.inertia_kg_m2 = I;
}

// WrapObject::extendScale and its shapes': the shape's axes (columns of its rotation) stretched by the
// body's factors give its own: a cylinder's radius by the mean of x and y, its length by z; a sphere's
// radius by the mean factor; an ellipsoid's radii each by its axis's.
void scale_wrap_object(WrapObject& w, const Eigen::Vector3d& s) {
  w.pose.translation_m = w.pose.translation_m.cwiseProduct(s);
  Eigen::Vector3d axis;
  for (int k = 0; k < 3; ++k) axis[k] = w.pose.rotation.col(k).cwiseProduct(s).norm();
  switch (w.shape) {
    case WrapObject::Shape::kCylinder:
      w.radius_m *= 0.5 * (axis[0] + axis[1]);
      w.length_m *= axis[2];
      break;
    case WrapObject::Shape::kSphere:
      w.radius_m *= s.sum() / 3.0;
      break;
    case WrapObject::Shape::kEllipsoid:
      w.dimensions_m = w.dimensions_m.cwiseProduct(axis);
      break;
    case WrapObject::Shape::kTorus:  // OpenSim's WrapTorus::extendScale: both radii by the xy average
      w.inner_radius_m *= 0.5 * (axis[0] + axis[1]);
      w.outer_radius_m *= 0.5 * (axis[0] + axis[1]);
      break;
  }
}

}  // namespace

Model scale_model(const Model& generic, const std::vector<Eigen::Vector3d>& factors, bool preserve_mass_distribution,
                  double subject_mass_kg) {
  if (factors.size() != generic.bodies.size()) throw std::invalid_argument("scale_model: one factor triple per body is needed");
  Model m = generic;
  auto f = [&](int body) { return factors[static_cast<std::size_t>(body)]; };
  for (std::size_t b = 1; b < m.bodies.size(); ++b) {
    const Eigen::Vector3d s = f(static_cast<int>(b));
    m.bodies[b].com_m = m.bodies[b].com_m.cwiseProduct(s);
    // Display meshes grow with their bodies, as OpenSim's Frame::scaleAttachedGeometry.
    for (auto& mesh : m.bodies[b].meshes) {
      mesh.scale = mesh.scale.cwiseProduct(s);
      mesh.pose.translation_m = mesh.pose.translation_m.cwiseProduct(s);
    }
  }
  for (auto& j : m.joints) {
    j.parent_offset.translation_m = j.parent_offset.translation_m.cwiseProduct(f(j.parent_body));
    j.child_offset.translation_m = j.child_offset.translation_m.cwiseProduct(f(j.child_body));
    for (int k = 3; k < 6; ++k) {
      TransformAxis& a = j.axes[k];
      if (a.function.is_identity()) continue;
      a.function = a.function.scaled(a.axis.dot(f(j.parent_body)));
    }
  }
  for (auto& mk : m.markers) mk.location_m = mk.location_m.cwiseProduct(f(mk.body));
  auto scale_path = [&](std::vector<PathPoint>& path) {
    for (auto& p : path) {
      p.location_m = p.location_m.cwiseProduct(f(p.body));
      if (p.kind == PathPoint::Kind::kMoving)
        for (int k = 0; k < 3; ++k) p.moving_functions[k] = p.moving_functions[k].scaled(f(p.body)[k]);
    }
  };
  for (auto& mu : m.muscles) scale_path(mu.path);
  for (auto& ps : m.path_springs) scale_path(ps.path);
  for (auto& pa : m.path_actuators) scale_path(pa.path);
  for (auto& w : m.wrap_objects) scale_wrap_object(w, f(w.body));
  for (std::size_t b = 1; b < m.bodies.size(); ++b) scale_inertia(m.bodies[b], f(static_cast<int>(b)), !preserve_mass_distribution);
  if (subject_mass_kg > 0) {
    const double total = m.total_mass_kg();
    if (total > 0)
      for (auto& b : m.bodies) {
        b.mass_kg *= subject_mass_kg / total;
        b.inertia_kg_m2 *= subject_mass_kg / total;
      }
  }
  return scale_muscle_parameters(m, generic);
}

}  // namespace cpgait

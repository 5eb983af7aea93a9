#include "cpgait/model/model.h"

namespace cpgait {

template <typename Container>
static int find_named(const Container& c, std::string_view name) {
  for (int i = 0; i < static_cast<int>(c.size()); ++i)
    if (c[i].name == name) return i;
  return -1;
}

int Model::body_index(std::string_view n) const { return find_named(bodies, n); }
int Model::coordinate_index(std::string_view n) const { return find_named(coordinates, n); }
int Model::marker_index(std::string_view n) const { return find_named(markers, n); }
int Model::joint_index(std::string_view n) const { return find_named(joints, n); }
int Model::muscle_index(std::string_view n) const { return find_named(muscles, n); }
int Model::wrap_object_index(std::string_view n) const { return find_named(wrap_objects, n); }

Eigen::VectorXd Model::default_coordinates() const {
  Eigen::VectorXd q(num_coordinates());
  for (int i = 0; i < num_coordinates(); ++i) q[i] = coordinates[i].default_value;
  return q;
}

double Model::total_mass_kg() const {
  double m = 0;
  for (const auto& b : bodies) m += b.mass_kg;
  return m;
}

Eigen::MatrixXd coordinates_in_file_units(const Model& model, const Eigen::MatrixXd& q) {
  Eigen::MatrixXd out = q;
  for (int c = 0; c < model.num_coordinates(); ++c)
    if (model.coordinates[c].is_angle()) out.col(c) *= 180.0 / 3.14159265358979323846;
  return out;
}

std::vector<std::string> coordinate_names(const Model& model) {
  std::vector<std::string> names;
  for (const auto& c : model.coordinates) names.push_back(c.name);
  return names;
}

}  // namespace cpgait

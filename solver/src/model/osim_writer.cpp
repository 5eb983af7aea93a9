#include "cpgait/model/osim_writer.h"

#include <pugixml.hpp>

#include <cstdio>
#include <sstream>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/model/osim_reader.h"

namespace cpgait {
namespace {

using pugi::xml_node;

bool is(const xml_node& n, const char* name) { return std::string_view(n.name()) == name; }

std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string vec3_text(const Eigen::Vector3d& v) {
  return number_text(v[0]) + " " + number_text(v[1]) + " " + number_text(v[2]);
}

void set_child_text(xml_node parent, const char* child, const std::string& text) {
  xml_node c = parent.child(child);
  if (!c) c = parent.append_child(child);
  c.text().set(text.c_str());
}

xml_node first_element(const xml_node& parent) {
  for (xml_node c = parent.first_child(); c; c = c.next_sibling())
    if (c.type() == pugi::node_element) return c;
  return {};
}

// A marker's body and location, 4.x (socket_parent_frame) or older (<body>).
void write_marker(xml_node n, const Model& m, const Marker& mk, bool v4) {
  const std::string& body = m.bodies[static_cast<std::size_t>(mk.body)].name;
  if (v4) {
    set_child_text(n, "socket_parent_frame", mk.body == 0 ? "/ground" : "/bodyset/" + body);
  } else {
    n.remove_child("socket_parent_frame");
    set_child_text(n, "body", body);
  }
  set_child_text(n, "location", vec3_text(mk.location_m));
  set_child_text(n, "fixed", mk.fixed ? "true" : "false");
}

// The document is edited where the written Model (model) differs from the document as read (generic,
// the same document read again, so indices match element for element).
class Writer {
 public:
  Writer(const Model& model, const Model& generic, int version) : m_(model), g_(generic), version_(version) {}

  void write(xml_node root) {
    write_bodies(root);
    write_joints(root);
    write_forces(root);
    write_markers(root);
  }

 private:
  const Model& m_;
  const Model& g_;
  int version_;

  [[noreturn]] void fail(const xml_node& n, const std::string& message) const {
    std::string field = n.name();
    if (n.attribute("name")) field += std::string(" '") + n.attribute("name").value() + "'";
    throw InputError(m_.source, 0, field, message);
  }

  void write_bodies(const xml_node& root) {
    write_wrap_objects(root.child("Ground"));
    for (const auto& n : root.child("BodySet").child("objects").children("Body")) {
      const std::string name = n.attribute("name").value();
      write_wrap_objects(n);
      if (name == "ground") continue;
      const int i = m_.body_index(name), gi = g_.body_index(name);
      if (i < 0 || gi < 0) fail(n, "the model has no body of this name");
      const Body &b = m_.bodies[i], &gb = g_.bodies[gi];
      if (b.mass_kg != gb.mass_kg) set_child_text(n, "mass", number_text(b.mass_kg));
      if (b.com_m != gb.com_m) set_child_text(n, "mass_center", vec3_text(b.com_m));
      write_mesh_scales(n, b, gb);
      if (b.inertia_kg_m2 == gb.inertia_kg_m2) continue;
      const Eigen::Matrix3d& I = b.inertia_kg_m2;
      if (n.child("inertia") || (version_ >= 40000 && !n.child("inertia_xx"))) {
        set_child_text(n, "inertia", number_text(I(0, 0)) + " " + number_text(I(1, 1)) + " " + number_text(I(2, 2)) + " " +
                                         number_text(I(0, 1)) + " " + number_text(I(0, 2)) + " " + number_text(I(1, 2)));
      } else {
        const char* names[6] = {"inertia_xx", "inertia_yy", "inertia_zz", "inertia_xy", "inertia_xz", "inertia_yz"};
        const double values[6] = {I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2)};
        for (int k = 0; k < 6; ++k) set_child_text(n, names[k], number_text(values[k]));
      }
    }
  }

  // The body's own meshes, in the order the reader took them (4.x Meshes, or the 3.x VisibleObject's scale).
  void write_mesh_scales(const xml_node& n, const Body& b, const Body& gb) {
    std::size_t k = 0;
    for (const auto& g : n.child("attached_geometry").children("Mesh")) {
      if (!g.child("mesh_file") || k >= b.meshes.size()) continue;
      if (b.meshes[k].scale != gb.meshes[k].scale) set_child_text(g, "scale_factors", vec3_text(b.meshes[k].scale));
      ++k;
    }
    const xml_node v = n.child("VisibleObject");
    if (!v || k >= b.meshes.size() || b.meshes[k].scale == gb.meshes[k].scale) return;
    // The body's factors onto the VisibleObject's own scale (its geometries' scales are relative to it).
    const Eigen::Vector3d factor = b.meshes[k].scale.cwiseQuotient(gb.meshes[k].scale);
    Eigen::Vector3d own = Eigen::Vector3d::Ones();
    if (v.child("scale_factors")) std::istringstream(v.child_value("scale_factors")) >> own[0] >> own[1] >> own[2];
    set_child_text(v, "scale_factors", vec3_text(own.cwiseProduct(factor)));
  }

  void write_wrap_objects(const xml_node& body) {
    for (const auto& w : body.child("WrapObjectSet").child("objects").children()) {
      if (w.type() != pugi::node_element) continue;
      const int i = m_.wrap_object_index(w.attribute("name").value());
      const int gi = g_.wrap_object_index(w.attribute("name").value());
      if (i < 0 || gi < 0) fail(w, "the model has no wrap object of this name");
      const WrapObject &o = m_.wrap_objects[i], &go = g_.wrap_objects[gi];
      if (o.pose.translation_m != go.pose.translation_m) set_child_text(w, "translation", vec3_text(o.pose.translation_m));
      if (o.radius_m != go.radius_m) set_child_text(w, "radius", number_text(o.radius_m));
      if (o.length_m != go.length_m) set_child_text(w, "length", number_text(o.length_m));
      if (o.dimensions_m != go.dimensions_m) set_child_text(w, "dimensions", vec3_text(o.dimensions_m));
      if (o.inner_radius_m != go.inner_radius_m) set_child_text(w, "inner_radius", number_text(o.inner_radius_m));
      if (o.outer_radius_m != go.outer_radius_m) set_child_text(w, "outer_radius", number_text(o.outer_radius_m));
    }
  }

  // A joint frame's translation: the joint's own PhysicalOffsetFrame on the body (4.x), or the body
  // itself, which must then stay at the joint.
  void write_joint_frame(const xml_node& joint, const char* socket, const Pose& pose, const Pose& generic_pose) {
    if (pose.translation_m == generic_pose.translation_m) return;
    std::string path = joint.child(socket).text().get();
    while (!path.empty() && (path.back() == '/' || path.back() == ' ')) path.pop_back();
    const std::string frame = path.substr(path.find_last_of('/') + 1);
    for (const auto& f : joint.child("frames").children("PhysicalOffsetFrame")) {
      if (frame != f.attribute("name").value()) continue;
      std::string parent = f.child("socket_parent").text().get();
      const std::string parent_name = parent.substr(parent.find_last_of('/') + 1);
      if (parent_name != "ground" && m_.body_index(parent_name) < 0)
        fail(f, "an offset frame on another offset frame cannot be written yet");
      set_child_text(f, "translation", vec3_text(pose.translation_m));
      return;
    }
    fail(joint.child(socket), "the joint's frame moved but the document attaches the joint to '" + path + "' directly");
  }

  // Scales the function element `f` by `ratio`, as OpenSim's scaling does: a MultiplierFunction's
  // scale is multiplied; anything else is wrapped in one.
  void scale_function(xml_node f, double ratio) {
    if (ratio == 1.0) return;
    if (is(f, "MultiplierFunction")) {
      const double s = f.child("scale") ? f.child("scale").text().as_double(1.0) : 1.0;
      set_child_text(f, "scale", number_text(s * ratio));
      return;
    }
    xml_node parent = f.parent();
    xml_node mf = parent.insert_child_before("MultiplierFunction", f);
    if (f.attribute("name")) mf.append_attribute("name") = f.attribute("name").value();
    mf.append_child("function").append_move(f);
    set_child_text(mf, "scale", number_text(ratio));
  }

  // OpenSim 4 names the function element name="function"; 3.x wraps it in <function>.
  static xml_node axis_function(const xml_node& ax) {
    if (const xml_node w = ax.child("function")) return first_element(w);
    for (const auto& c : ax.children())
      if (c.type() == pugi::node_element && std::string_view(c.attribute("name").value()) == "function") return c;
    return {};
  }

  void write_axis(const xml_node& ax, const TransformAxis& a, const TransformAxis& ga) {
    if (a.function.scale() == ga.function.scale()) return;
    xml_node f = axis_function(ax);
    if (!f) {
      if (a.function.is_constant() && a.function.value(0.0) == 0.0) return;  // an absent function is zero
      fail(ax, "the axis's function changed but the document has none to scale");
    }
    scale_function(f, a.function.scale() / ga.function.scale());
  }

  void write_joint(const xml_node& n, const std::string& name) {
    const int i = m_.joint_index(name), gi = g_.joint_index(name);
    if (i < 0 || gi < 0) fail(n, "the model has no joint of this name");
    const Joint &j = m_.joints[i], &gj = g_.joints[gi];
    if (n.child("socket_parent_frame") || n.child("socket_child_frame")) {
      write_joint_frame(n, "socket_parent_frame", j.parent_offset, gj.parent_offset);
      write_joint_frame(n, "socket_child_frame", j.child_offset, gj.child_offset);
    } else {
      if (j.parent_offset.translation_m != gj.parent_offset.translation_m)
        set_child_text(n, "location_in_parent", vec3_text(j.parent_offset.translation_m));
      if (j.child_offset.translation_m != gj.child_offset.translation_m)
        set_child_text(n, "location", vec3_text(j.child_offset.translation_m));
    }
    if (const xml_node st = n.child("SpatialTransform")) {
      static const char* kSlots[3] = {"translation1", "translation2", "translation3"};
      for (int k = 0; k < 3; ++k)
        if (const xml_node ax = st.find_child_by_attribute("TransformAxis", "name", kSlots[k]))
          write_axis(ax, j.axes[3 + k], gj.axes[3 + k]);
    } else if (const xml_node set = n.child("TransformAxisSet")) {
      // Before 10901: translations, in file order, are translation1.. (as the reader takes them).
      int slot = 3;
      for (const auto& ax : set.child("objects").children("TransformAxis")) {
        const std::string rotation = ax.child("is_rotation").text().get();
        if (rotation.find("true") != std::string::npos) continue;
        if (slot < 6) write_axis(ax, j.axes[slot], gj.axes[slot]);
        ++slot;
      }
    }
  }

  void write_joints(const xml_node& root) {
    for (const auto& n : root.child("JointSet").child("objects").children())
      if (n.type() == pugi::node_element) write_joint(n, n.attribute("name").value());
    for (const auto& b : root.child("BodySet").child("objects").children("Body"))
      for (const char* wrapper : {"Joint", "joint"})
        for (const auto& n : b.child(wrapper).children())
          if (n.type() == pugi::node_element) write_joint(n, n.attribute("name").value());
  }

  template <typename PathOwner>
  void write_path(const xml_node& muscle, const PathOwner& mu, const PathOwner& gmu) {
    const bool legacy = !muscle.child("GeometryPath") && muscle.child("MusclePointSet");
    const xml_node gp = legacy ? muscle : muscle.child("GeometryPath");
    std::size_t k = 0;
    for (const auto& p : gp.child(legacy ? "MusclePointSet" : "PathPointSet").child("objects").children()) {
      if (p.type() != pugi::node_element) continue;
      if (k >= mu.path.size() || mu.path[k].name != p.attribute("name").value())
        fail(p, "the model's path of '" + mu.name + "' does not list this point here");
      const PathPoint &pp = mu.path[k], &gpp = gmu.path[k];
      ++k;
      if (pp.location_m != gpp.location_m && p.child("location")) write_point_location(p, pp, gpp);
      if (pp.kind != PathPoint::Kind::kMoving) continue;
      static const char* kLoc[3] = {"x_location", "y_location", "z_location"};
      for (int a = 0; a < 3; ++a) {
        const xml_node f = first_element(p.child(kLoc[a]));
        if (!f) continue;
        scale_function(f, pp.moving_functions[a].scale() / gpp.moving_functions[a].scale());
      }
    }
  }

  // The model keeps points in their body's frame: a point the document puts on an offset frame (read
  // as a different body-frame location) would need mapping back.
  void write_point_location(const xml_node& p, const PathPoint& pp, const PathPoint& gpp) {
    std::istringstream in(p.child("location").text().get());
    Eigen::Vector3d raw;
    in >> raw[0] >> raw[1] >> raw[2];
    if (!in || (raw - gpp.location_m).norm() > 1e-12 * (1.0 + raw.norm()))
      fail(p, "a point on an offset frame cannot be written yet");
    set_child_text(p, "location", vec3_text(pp.location_m));
  }

  void write_forces(const xml_node& root) {
    for (const auto& n : root.child("ForceSet").child("objects").children()) {
      if (n.type() != pugi::node_element) continue;
      if (std::string(n.name()) == "PathSpring") {
        write_path_spring(n);
        continue;
      }
      if (std::string(n.name()) == "PathActuator") {
        const PathActuator *pa = named(m_.path_actuators, n), *gpa = named(g_.path_actuators, n);
        if (!gpa) continue;
        if (!pa) fail(n, "the model has no path actuator of this name");
        write_path(n, *pa, *gpa);
        continue;
      }
      const int i = m_.muscle_index(n.attribute("name").value()), gi = g_.muscle_index(n.attribute("name").value());
      if (gi < 0) continue;  // a force cpgait does not model; copied as it is
      if (i < 0) fail(n, "the model has no muscle of this name");
      const Muscle &mu = m_.muscles[i], &gmu = g_.muscles[gi];
      if (mu.optimal_fiber_length_m != gmu.optimal_fiber_length_m)
        set_child_text(n, "optimal_fiber_length", number_text(mu.optimal_fiber_length_m));
      if (mu.tendon_slack_length_m != gmu.tendon_slack_length_m)
        set_child_text(n, "tendon_slack_length", number_text(mu.tendon_slack_length_m));
      write_path(n, mu, gmu);
    }
  }

  // The element of `items` named as the document's force n, or nullptr.
  template <typename T>
  static const T* named(const std::vector<T>& items, const xml_node& n) {
    for (const T& x : items)
      if (x.name == n.attribute("name").value()) return &x;
    return nullptr;
  }

  void write_path_spring(const xml_node& n) {
    const PathSpring *ps = named(m_.path_springs, n), *gps = named(g_.path_springs, n);
    if (!gps) return;
    if (!ps) fail(n, "the model has no path spring of this name");
    if (ps->resting_length_m != gps->resting_length_m) set_child_text(n, "resting_length", number_text(ps->resting_length_m));
    write_path(n, *ps, *gps);
  }

  bool markers_unchanged() const {
    if (m_.markers.size() != g_.markers.size()) return false;
    for (std::size_t i = 0; i < m_.markers.size(); ++i) {
      const Marker &a = m_.markers[i], &b = g_.markers[i];
      if (a.name != b.name || a.body != b.body || a.location_m != b.location_m || a.fixed != b.fixed) return false;
    }
    return true;
  }

  // Markers of the model's names are updated in place (keeping whatever else they hold), others
  // removed, and the model's new ones added.
  void write_markers(xml_node root) {
    if (markers_unchanged()) return;
    xml_node set = root.child("MarkerSet");
    if (!set) {
      set = root.append_child("MarkerSet");
      set.append_attribute("name") = "markerset";
    }
    xml_node objects = set.child("objects");
    if (!objects) objects = set.prepend_child("objects");
    std::vector<bool> written(m_.markers.size(), false);
    for (xml_node n = objects.first_child(); n;) {
      const xml_node next = n.next_sibling();
      const int i = n.type() == pugi::node_element ? m_.marker_index(n.attribute("name").value()) : -1;
      if (i < 0 || written[static_cast<std::size_t>(i)]) {
        objects.remove_child(n);
      } else {
        write_marker(n, m_, m_.markers[static_cast<std::size_t>(i)], version_ >= 40000);
        written[static_cast<std::size_t>(i)] = true;
      }
      n = next;
    }
    for (std::size_t i = 0; i < m_.markers.size(); ++i) {
      if (written[i]) continue;
      xml_node n = objects.append_child("Marker");
      n.append_attribute("name") = m_.markers[i].name.c_str();
      write_marker(n, m_, m_.markers[i], version_ >= 40000);
    }
  }

};

}  // namespace

std::string osim_document(const Model& model, const OsimWriteOptions& options) {
  if (model.source.empty() && options.source_document.empty())
    throw InputError("", 0, "model", "the model was not read from a document, so there is none to write it into");
  std::string content = options.source_document.empty() ? text::read_file(model.source) : options.source_document;
  const Model generic = parse_osim(content, model.source).model;
  pugi::xml_document doc;
  const auto parsed = doc.load_buffer(content.data(), content.size(),
                                      pugi::parse_default | pugi::parse_declaration | pugi::parse_comments);
  if (!parsed) throw InputError(model.source, 0, "", std::string("cannot parse the model again: ") + parsed.description());
  xml_node root = doc.document_element();
  int version = 40000;
  if (is(root, "OpenSimDocument")) {
    version = root.attribute("Version").as_int(40000);
    root = root.child("Model");
  }
  if (!options.model_name.empty()) {
    if (!root.attribute("name")) root.append_attribute("name");
    root.attribute("name") = options.model_name.c_str();
  }
  Writer(model, generic, version).write(root);
  std::ostringstream out;
  doc.save(out, "\t", pugi::format_default);
  return out.str();
}

std::string marker_set_document(const Model& model) {
  pugi::xml_document doc;
  xml_node decl = doc.append_child(pugi::node_declaration);
  decl.append_attribute("version") = "1.0";
  decl.append_attribute("encoding") = "UTF-8";
  xml_node root = doc.append_child("OpenSimDocument");
  root.append_attribute("Version") = "40000";
  xml_node set = root.append_child("MarkerSet");
  set.append_attribute("name") = "markerset";
  xml_node objects = set.append_child("objects");
  for (const auto& mk : model.markers) {
    xml_node n = objects.append_child("Marker");
    n.append_attribute("name") = mk.name.c_str();
    write_marker(n, model, mk, true);
  }
  set.append_child("groups");
  std::ostringstream out;
  doc.save(out, "\t", pugi::format_default);
  return out.str();
}

}  // namespace cpgait

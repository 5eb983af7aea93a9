#pragma once
// Display meshes as OpenSim models name them: VTK XML PolyData (.vtp: ascii, or binary in base64,
// zlib-compressed or not), STL (ASCII or binary) and Wavefront OBJ. Read into triangles for the
// dashboard; polygons are split into fans, triangle strips into triangles.
#include <string>
#include <vector>

namespace cpgait::services {

struct TriangleMesh {
  std::vector<float> positions;     // x y z per vertex, in the file's units (OpenSim's: m)
  std::vector<unsigned> triangles;  // three vertex indices each
};

// Throws InputError naming the file and, where it can, the line or the element.
TriangleMesh read_mesh_file(const std::string& path);
TriangleMesh parse_mesh(const std::string& content, const std::string& name);  // the kind from the name's extension
bool is_mesh_file_name(const std::string& name);  // .vtp, .stl or .obj, in any case

}  // namespace cpgait::services

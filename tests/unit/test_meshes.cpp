// Display meshes: the readers of .vtp (ascii, binary, zlib-compressed), .stl and .obj, and the
// meshes an .osim attaches to its bodies (4.x Mesh, 3.x VisibleObject), scaled with their bodies.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/model/osim_writer.h"
#include "cpgait/scaling/scale_model.h"
#include "mesh_files.h"
#include "test_support.h"

using cpgait::services::parse_mesh;
using cpgait::services::TriangleMesh;

namespace {

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const unsigned n = static_cast<unsigned char>(in[i]) << 16 | (i + 1 < in.size() ? static_cast<unsigned char>(in[i + 1]) << 8 : 0) |
                       (i + 2 < in.size() ? static_cast<unsigned char>(in[i + 2]) : 0);
    out += t[(n >> 18) & 63];
    out += t[(n >> 12) & 63];
    out += i + 1 < in.size() ? t[(n >> 6) & 63] : '=';
    out += i + 2 < in.size() ? t[n & 63] : '=';
  }
  return out;
}

template <typename T>
std::string bytes_of(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

// A unit square as one four-sided polygon plus a triangle above it, in each of VTK's encodings.
const std::vector<float> kPoints = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5f, 0.5f, 1};
const std::vector<std::int32_t> kConnectivity = {0, 1, 2, 3, 0, 1, 4}, kOffsets = {4, 7};

std::string vtp(const std::string& compressor, const std::function<std::string(const std::string&)>& encode, const char* format) {
  auto array = [&](const char* type, const char* name, int components, const std::string& bytes, const std::string& ascii) {
    return std::string("<DataArray type=\"") + type + "\" Name=\"" + name + "\" NumberOfComponents=\"" + std::to_string(components) +
           "\" format=\"" + format + "\">" + (std::string(format) == "ascii" ? ascii : encode(bytes)) + "</DataArray>";
  };
  return "<?xml version=\"1.0\"?><VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\"" +
         (compressor.empty() ? std::string() : " compressor=\"" + compressor + "\"") + "><PolyData><Piece NumberOfPoints=\"5\" NumberOfPolys=\"2\"><Points>" +
         array("Float32", "Points", 3, bytes_of(kPoints), "0 0 0\n 1 0 0\n 1 1 0\n 0 1 0\n 0.5 0.5 1") + "</Points><Polys>" +
         array("Int32", "connectivity", 1, bytes_of(kConnectivity), "0 1 2 3\n0 1 4") +
         array("Int32", "offsets", 1, bytes_of(kOffsets), "4 7") + "</Polys></Piece></PolyData></VTKFile>";
}

std::string raw_binary(const std::string& bytes) {
  const std::uint32_t n = static_cast<std::uint32_t>(bytes.size());
  return base64(std::string(reinterpret_cast<const char*>(&n), 4) + bytes);
}

// VTK's zlib layout: a header of block count, block size, last block size, compressed sizes, then
// the compressed blocks.
std::pair<std::string, std::string> zlib_parts(const std::string& bytes) {
  uLongf size = compressBound(static_cast<uLong>(bytes.size()));
  std::string packed(size, '\0');
  compress2(reinterpret_cast<Bytef*>(packed.data()), &size, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uLong>(bytes.size()), 9);
  packed.resize(size);
  const std::uint32_t header[4] = {1, static_cast<std::uint32_t>(bytes.size()), static_cast<std::uint32_t>(bytes.size()), static_cast<std::uint32_t>(size)};
  return {std::string(reinterpret_cast<const char*>(header), sizeof header), packed};
}
// Inline or base64-appended, each part in its own base64.
std::string zlib_binary(const std::string& bytes) {
  const auto [header, packed] = zlib_parts(bytes);
  return base64(header) + base64(packed);
}
std::string zlib_raw(const std::string& bytes) {
  const auto [header, packed] = zlib_parts(bytes);
  return header + packed;
}
std::string count_raw(const std::string& bytes) {
  const std::uint32_t n = static_cast<std::uint32_t>(bytes.size());
  return std::string(reinterpret_cast<const char*>(&n), 4) + bytes;
}

// The same file with its arrays in AppendedData (encoding raw or base64): chunk(bytes) is each
// array's encoded header and data, placed at its offset after the '_'.
std::string vtp_appended(const std::string& compressor, const std::function<std::string(const std::string&)>& chunk, const char* encoding) {
  std::string data;
  auto array = [&](const char* type, const char* name, int components, const std::string& bytes) {
    const std::string a = std::string("<DataArray type=\"") + type + "\" Name=\"" + name + "\" NumberOfComponents=\"" + std::to_string(components) +
                          "\" format=\"appended\" offset=\"" + std::to_string(data.size()) + "\"/>";
    data += chunk(bytes);
    return a;
  };
  std::string head = "<?xml version=\"1.0\"?><VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\"" +
                     (compressor.empty() ? std::string() : " compressor=\"" + compressor + "\"") + "><PolyData><Piece NumberOfPoints=\"5\" NumberOfPolys=\"2\"><Points>";
  head += array("Float32", "Points", 3, bytes_of(kPoints)) + "</Points><Polys>";
  head += array("Int32", "connectivity", 1, bytes_of(kConnectivity));
  head += array("Int32", "offsets", 1, bytes_of(kOffsets));
  return head + "</Polys></Piece></PolyData>\n  <AppendedData encoding=\"" + encoding + "\">\n   _" + data + "\n  </AppendedData>\n</VTKFile>\n";
}

}  // namespace

TEST(MeshFiles, Gait2392FemurVtpHasItsPointsAndTriangles) {
  const std::string path = cpgait::refdata::shared_path("opensim/Geometry/femur_r.vtp");
  REQUIRE_REFERENCE(path);
  const TriangleMesh m = cpgait::services::read_mesh_file(path);
  EXPECT_EQ(m.positions.size(), 3u * 456);
  EXPECT_EQ(m.triangles.size(), 3u * 908);
  for (const unsigned i : m.triangles) ASSERT_LT(i, 456u);
  // The femur hangs below its hip centre: about 43 cm of bone along -y.
  float lowest = 0;
  for (std::size_t i = 1; i < m.positions.size(); i += 3) lowest = std::min(lowest, m.positions[i]);
  EXPECT_NEAR(lowest, -0.43, 0.01);
}

TEST(MeshFiles, AsciiBinaryAndCompressedVtpReadTheSame) {
  const TriangleMesh ascii = parse_mesh(vtp("", nullptr, "ascii"), "a.vtp");
  const TriangleMesh binary = parse_mesh(vtp("", raw_binary, "binary"), "b.vtp");
  const TriangleMesh zipped = parse_mesh(vtp("vtkZLibDataCompressor", zlib_binary, "binary"), "c.vtp");
  EXPECT_EQ(ascii.positions, kPoints);
  // The square fans into two triangles, then the triangle.
  EXPECT_EQ(ascii.triangles, (std::vector<unsigned>{0, 1, 2, 0, 2, 3, 0, 1, 4}));
  // Appended: raw bytes (NULs and all, not XML) or base64, compressed or not.
  const TriangleMesh raw = parse_mesh(vtp_appended("", count_raw, "raw"), "d.vtp");
  const TriangleMesh raw_zipped = parse_mesh(vtp_appended("vtkZLibDataCompressor", zlib_raw, "raw"), "e.vtp");
  const TriangleMesh text = parse_mesh(vtp_appended("", raw_binary, "base64"), "f.vtp");
  const TriangleMesh text_zipped = parse_mesh(vtp_appended("vtkZLibDataCompressor", zlib_binary, "base64"), "g.vtp");
  for (const TriangleMesh* m : {&binary, &zipped, &raw, &raw_zipped, &text, &text_zipped}) {
    EXPECT_EQ(m->positions, ascii.positions);
    EXPECT_EQ(m->triangles, ascii.triangles);
  }
}

// OpenSim's own pendulum meshes keep their arrays zlib-compressed in base64 AppendedData, with Int64
// cells. VTK wrote each array's range of magnitudes: the points read must fall inside it.
TEST(MeshFiles, OpenSimsAppendedDataVtpFiles) {
  for (const char* file : {"pendulum.vtp", "ConePendulum.vtp"}) {
    const std::string path = cpgait::refdata::shared_path(std::string("opensim/opensim-core-tests/Analyze/") + file);
    REQUIRE_REFERENCE(path);
    const std::string content = cpgait::text::read_file(path);
    const TriangleMesh m = cpgait::services::read_mesh_file(path);
    auto attribute = [&](const std::string& key, std::size_t from) {
      const std::size_t at = content.find(key + "=\"", from) + key.size() + 2;
      return std::stod(content.substr(at, content.find('"', at) - at));
    };
    const std::size_t points_at = content.find("<Points>");
    const double lo = attribute("RangeMin", points_at), hi = attribute("RangeMax", points_at);
    const auto n = static_cast<std::size_t>(attribute("NumberOfPoints", 0));
    ASSERT_EQ(m.positions.size(), 3 * n) << file;
    double shortest = 1e9, longest = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double r = std::hypot(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
      shortest = std::min(shortest, r), longest = std::max(longest, r);
    }
    EXPECT_NEAR(shortest, lo, 1e-6) << file;
    EXPECT_NEAR(longest, hi, 1e-6) << file;
    EXPECT_GE(m.triangles.size(), 3 * static_cast<std::size_t>(attribute("NumberOfPolys", 0))) << file;
    for (const unsigned i : m.triangles) ASSERT_LT(i, n) << file;
  }
}

TEST(MeshFiles, StlAsciiStlBinaryAndObjReadTheSameTriangles) {
  const std::vector<std::array<float, 9>> tris = {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 0, 1, 0, 0, 0, 1}};
  std::string ascii = "solid t\n", binary(80, ' ');
  const std::uint32_t count = 2;
  binary.append(reinterpret_cast<const char*>(&count), 4);
  for (const auto& t : tris) {
    ascii += "facet normal 0 0 1\n outer loop\n";
    for (int v = 0; v < 3; ++v) ascii += "  vertex " + std::to_string(t[3 * v]) + " " + std::to_string(t[3 * v + 1]) + " " + std::to_string(t[3 * v + 2]) + "\n";
    ascii += " endloop\nendfacet\n";
    binary.append(12, '\0');
    binary.append(reinterpret_cast<const char*>(t.data()), 36);
    binary.append(2, '\0');
  }
  ascii += "endsolid t\n";
  const TriangleMesh a = parse_mesh(ascii, "a.stl"), b = parse_mesh(binary, "b.STL");
  EXPECT_EQ(a.triangles.size(), 6u);
  EXPECT_EQ(a.positions, b.positions);
  // The same two faces as OBJ: shared vertices, v/vt/vn references, a negative index.
  const TriangleMesh o = parse_mesh("# two faces\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nf 1//1 2//1 3//1\nf 1/1/1 3 -1\n", "o.obj");
  ASSERT_EQ(o.triangles.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(o.positions[3 * o.triangles[k] + c], a.positions[3 * k + c]) << k;
}

TEST(MeshFiles, BadFilesAreRefusedNamingWhere) {
  auto refused = [](const std::string& content, const std::string& name, const std::string& words) {
    try {
      parse_mesh(content, name);
      ADD_FAILURE() << name << " accepted";
    } catch (const cpgait::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  refused("v 0 0 0\nv 1 0 0\nf 1 2 9\n", "bad.obj", "vertex 9");
  refused("v 0 0 x\n", "bad2.obj", "not a number");
  refused(vtp("", nullptr, "ascii").replace(vtp("", nullptr, "ascii").find("0 1 4"), 5, "0 1 7"), "bad.vtp", "does not exist");
  refused("<VTKFile type=\"UnstructuredGrid\"/>", "grid.vtp", "PolyData");
  refused(std::string(84, '\0').replace(80, 1, "\x05"), "short.stl", "shorter");
  refused("solid x", "model.3ds", ".vtp, .stl or .obj");
  // ASCII STL cut off inside a facet, or a facet of two vertices.
  refused("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", "cut.stl", "cut.stl:2: facet: the facet has no endfacet");
  refused("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid x\n", "two.stl",
          "two.stl:7: facet: a facet without three vertices");
}

TEST(OsimMeshes, BodiesKeepTheirMeshesAndScaleThemWithTheBody) {
  const std::string v4 = cpgait::refdata::gait2392("pipeline/OutputReference/subject01_simbody.osim");
  const std::string v3 = cpgait::refdata::shared_path("opensim/opensim-core-tests/Analyze/SinglePin.osim");
  REQUIRE_REFERENCE(v4);
  REQUIRE_REFERENCE(v3);
  const cpgait::Model m = cpgait::read_osim(v4).model;
  const auto& femur = m.bodies[static_cast<std::size_t>(m.body_index("femur_r"))];
  ASSERT_EQ(femur.meshes.size(), 1u);
  EXPECT_EQ(femur.meshes[0].file, "femur_r.vtp");
  EXPECT_NEAR(femur.meshes[0].scale.x(), 1.14724, 1e-12);
  int meshes = 0;
  for (const auto& b : m.bodies) meshes += static_cast<int>(b.meshes.size());
  EXPECT_EQ(meshes, 19);  // hat has four, each foot three (with the treadmill on the ground: 20 in the file)
  const cpgait::Model pin = cpgait::read_osim(v3).model;
  int pin_meshes = 0;
  for (const auto& b : pin.bodies)
    for (const auto& mesh : b.meshes) pin_meshes += mesh.file == "ConePendulum.vtp";
  EXPECT_EQ(pin_meshes, 1);

  // Scaled with its body, as OpenSim's scaleAttachedGeometry; written back and read again.
  std::vector<Eigen::Vector3d> factors(m.bodies.size(), Eigen::Vector3d::Ones());
  factors[static_cast<std::size_t>(m.body_index("femur_r"))] = Eigen::Vector3d(1.1, 0.9, 1.2);
  const cpgait::Model scaled = cpgait::scale_model(m, factors, true, 0);
  const Eigen::Vector3d expected = Eigen::Vector3d(1.1, 0.9, 1.2) * 1.14724;
  const auto& scaled_femur = scaled.bodies[static_cast<std::size_t>(scaled.body_index("femur_r"))];
  EXPECT_LT((scaled_femur.meshes[0].scale - expected).norm(), 1e-12);
  const cpgait::Model again = cpgait::parse_osim(cpgait::osim_document(scaled), "scaled.osim").model;
  EXPECT_LT((again.bodies[static_cast<std::size_t>(again.body_index("femur_r"))].meshes[0].scale - expected).norm(), 1e-9);
  EXPECT_EQ(again.bodies[static_cast<std::size_t>(again.body_index("tibia_r"))].meshes[0].scale,
            m.bodies[static_cast<std::size_t>(m.body_index("tibia_r"))].meshes[0].scale);
}

#include "mesh_files.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <pugixml.hpp>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait::services {
namespace {

std::string base64_decode(std::string_view in, const std::string& name, const std::string& field) {
  static const auto table = [] {
    std::array<int, 256> t{};
    t.fill(-1);
    const char* s = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i) t[static_cast<unsigned char>(s[i])] = i;
    return t;
  }();
  std::string out;
  std::uint32_t acc = 0;
  int bits = 0;
  for (const char c : in) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    if (c == '=') {  // padding ends a chunk; VTK writes a compressed array's header and blocks as two
      bits = 0;
      continue;
    }
    const int v = table[static_cast<unsigned char>(c)];
    if (v < 0) throw InputError(name, 0, field, std::string("not base64: '") + c + "'");
    acc = (acc << 6) | static_cast<std::uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += static_cast<char>((acc >> bits) & 0xff);
    }
  }
  return out;
}

// A VTK DataArray's values, whatever its format: ascii, binary (base64 of a byte count and the
// data, or of a zlib block header and compressed blocks), or appended (the same, raw or base64, at
// an offset into the file's AppendedData).
class VtkArrays {
 public:
  // appended: the AppendedData's content after its '_' (raw bytes, or base64 text).
  VtkArrays(const pugi::xml_node& file, std::string name, std::string_view appended)
      : name_(std::move(name)), appended_(appended) {
    compressed_ = std::string(file.attribute("compressor").value()) == "vtkZLibDataCompressor";
    header64_ = std::string(file.attribute("header_type").value()) == "UInt64";
    if (std::string(file.attribute("byte_order").value()) == "BigEndian") throw InputError(name_, 0, "byte_order", "big-endian VTK files are not supported");
    const std::string encoding = file.child("AppendedData").attribute("encoding").value();
    if (encoding != "raw" && encoding != "base64" && file.child("AppendedData"))
      throw InputError(name_, 0, "AppendedData", "encoding '" + encoding + "' is not supported (raw or base64)");
    appended_base64_ = encoding == "base64";
    // An appended array runs to the next one's offset (or the end).
    for (const auto& a : file.select_nodes("//DataArray[@format='appended']")) offsets_.push_back(a.node().attribute("offset").as_ullong());
    std::sort(offsets_.begin(), offsets_.end());
  }

  std::vector<double> values(const pugi::xml_node& array) const {
    const std::string field = std::string("DataArray ") + array.attribute("Name").value();
    const std::string format = array.attribute("format").value();
    const std::string type = array.attribute("type").value();
    std::vector<double> out;
    if (format == "ascii" || format.empty()) {
      // Values run over lines: any whitespace separates them.
      const char* p = array.child_value();
      const char* end = p + std::strlen(p);
      while (true) {
        while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
        if (p == end) break;
        double v = 0;
        const auto r = std::from_chars(p, end, v);
        if (r.ec != std::errc()) throw InputError(name_, 0, field, "not a number: '" + std::string(p, std::min<std::size_t>(12, static_cast<std::size_t>(end - p))) + "'");
        out.push_back(v);
        p = r.ptr;
      }
      return out;
    }
    std::string bytes;
    if (format == "binary") {
      bytes = decode(array.child_value(), true, field);
    } else if (format == "appended") {
      const std::uint64_t offset = array.attribute("offset").as_ullong();
      if (offset > appended_.size()) throw InputError(name_, 0, field, "offset " + std::to_string(offset) + " is past the appended data");
      const auto next = std::upper_bound(offsets_.begin(), offsets_.end(), offset);
      const std::uint64_t end = next == offsets_.end() ? appended_.size() : std::min<std::uint64_t>(*next, appended_.size());
      bytes = decode(appended_.substr(offset, end - offset), appended_base64_, field);
    } else {
      throw InputError(name_, 0, field, "format '" + format + "' is not supported (ascii, binary or appended)");
    }
    const std::size_t width = type_width(type, field);
    for (std::size_t i = 0; i + width <= bytes.size(); i += width) out.push_back(value_at(bytes.data() + i, type));
    return out;
  }

 private:
  std::string name_;
  std::string_view appended_;
  bool compressed_ = false, header64_ = false, appended_base64_ = false;
  std::vector<std::uint64_t> offsets_;

  static std::size_t type_width(const std::string& type, const std::string&) {
    if (type == "Float64" || type == "Int64" || type == "UInt64") return 8;
    if (type == "Float32" || type == "Int32" || type == "UInt32") return 4;
    if (type == "Int16" || type == "UInt16") return 2;
    return 1;
  }
  static double value_at(const char* p, const std::string& type) {
    auto get = [p](auto v) { std::memcpy(&v, p, sizeof v); return static_cast<double>(v); };
    if (type == "Float32") return get(float{});
    if (type == "Float64") return get(double{});
    if (type == "Int32") return get(std::int32_t{});
    if (type == "UInt32") return get(std::uint32_t{});
    if (type == "Int64") return get(std::int64_t{});
    if (type == "UInt64") return get(std::uint64_t{});
    if (type == "Int16") return get(std::int16_t{});
    if (type == "UInt16") return get(std::uint16_t{});
    if (type == "Int8") return get(std::int8_t{});
    return get(std::uint8_t{});
  }

  std::uint64_t header_value(const std::string& bytes, std::size_t index, const std::string& field) const {
    const std::size_t w = header64_ ? 8 : 4;
    if ((index + 1) * w > bytes.size()) throw InputError(name_, 0, field, "binary data shorter than its header");
    std::uint64_t v = 0;
    std::memcpy(&v, bytes.data() + index * w, w);
    return v;
  }

  // An array's bytes from its text (base64) or its raw appended bytes.
  std::string decode(std::string_view t, bool base64, const std::string& field) const {
    if (base64)
      while (!t.empty() && std::isspace(static_cast<unsigned char>(t.front()))) t.remove_prefix(1);
    auto bytes_of = [&](std::string_view part) { return base64 ? base64_decode(part, name_, field) : std::string(part); };
    const std::size_t w = header64_ ? 8 : 4;
    if (!compressed_) {
      const std::string bytes = bytes_of(t);
      const std::uint64_t n = header_value(bytes, 0, field);
      if (n > bytes.size() - w) throw InputError(name_, 0, field, "binary data shorter than its byte count");
      return bytes.substr(w, n);
    }
    // Compressed: the header (block count, block size, last block's size, each block's compressed
    // size), then the blocks; in base64, each of the two on its own.
    auto header_length = [&](std::uint64_t values) { return base64 ? 4 * ((values * w + 2) / 3) : values * w; };
    const std::string first = bytes_of(t.substr(0, std::min<std::size_t>(t.size(), header_length(3))));
    const std::uint64_t blocks = header_value(first, 0, field);
    if (blocks > (1u << 24)) throw InputError(name_, 0, field, "implausible block count");
    const std::size_t header_chars = header_length(3 + blocks);
    if (header_chars > t.size()) throw InputError(name_, 0, field, "binary data shorter than its header");
    const std::string header = bytes_of(t.substr(0, header_chars));
    const std::string data = bytes_of(t.substr(header_chars));
    const std::uint64_t block_size = header_value(header, 1, field), last = header_value(header, 2, field);
    std::string out;
    std::size_t at = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      const std::uint64_t size = header_value(header, 3 + b, field);
      const std::uint64_t raw = b + 1 == blocks && last ? last : block_size;
      if (size > data.size() - at || raw > (std::uint64_t{1} << 31)) throw InputError(name_, 0, field, "compressed block past the data");
      std::string block(raw, '\0');
      uLongf got = static_cast<uLongf>(raw);
      if (uncompress(reinterpret_cast<Bytef*>(block.data()), &got, reinterpret_cast<const Bytef*>(data.data() + at), static_cast<uLong>(size)) != Z_OK)
        throw InputError(name_, 0, field, "a zlib block does not decompress");
      out.append(block.data(), got);
      at += size;
    }
    return out;
  }
};

TriangleMesh parse_vtp(const std::string& content, const std::string& name) {
  // Raw appended data is not XML (any byte may follow its '_'): it is cut off before parsing, and
  // the document closed after the AppendedData tag.
  std::string xml = content;
  std::string_view appended;
  if (const std::size_t tag = content.find("<AppendedData"); tag != std::string::npos) {
    const std::size_t open_end = content.find('>', tag), underscore = content.find('_', open_end == std::string::npos ? tag : open_end);
    if (open_end == std::string::npos || underscore == std::string::npos)
      throw InputError(name, 0, "AppendedData", "no '_' marks the start of the appended data");
    std::size_t close = content.rfind("</AppendedData>");
    if (close == std::string::npos || close < underscore) close = content.size();
    appended = std::string_view(content).substr(underscore + 1, close - underscore - 1);
    xml = content.substr(0, open_end + 1) + "</AppendedData></VTKFile>";
  }
  pugi::xml_document doc;
  if (!doc.load_buffer(xml.data(), xml.size()))
    throw InputError(name, 0, "VTKFile", "not an XML document");
  const auto file = doc.child("VTKFile");
  if (std::string(file.attribute("type").value()) != "PolyData") throw InputError(name, 0, "VTKFile", "expected type=\"PolyData\"");
  const VtkArrays arrays(file, name, appended);
  TriangleMesh mesh;
  for (const auto& piece : file.child("PolyData").children("Piece")) {
    const auto base = static_cast<unsigned>(mesh.positions.size() / 3);
    const std::vector<double> points = arrays.values(piece.child("Points").child("DataArray"));
    if (points.size() % 3) throw InputError(name, 0, "Points", "point coordinates not a multiple of three");
    for (const double v : points) {
      if (!(std::abs(v) <= 3.4e38)) throw InputError(name, 0, "Points", "a coordinate that is not a finite float");  // NaN too
      mesh.positions.push_back(static_cast<float>(v));
    }
    const auto n = static_cast<unsigned>(points.size() / 3);
    for (const char* cells : {"Polys", "Strips"}) {
      std::vector<double> connectivity, offsets;
      for (const auto& a : piece.child(cells).children("DataArray")) {
        if (std::string(a.attribute("Name").value()) == "connectivity") connectivity = arrays.values(a);
        if (std::string(a.attribute("Name").value()) == "offsets") offsets = arrays.values(a);
      }
      std::size_t begin = 0;
      for (const double end_d : offsets) {
        // Written so that NaN fails too.
        if (!(end_d >= static_cast<double>(begin) && end_d <= static_cast<double>(connectivity.size())))
          throw InputError(name, 0, cells, "offsets run past the connectivity or go backwards");
        const auto end = static_cast<std::size_t>(end_d);
        for (std::size_t i = begin; i < end; ++i)
          if (!(connectivity[i] >= 0 && connectivity[i] < n)) throw InputError(name, 0, cells, "a cell names a point that does not exist");
        for (std::size_t k = begin + 2; k < end; ++k) {
          const bool strip = std::strcmp(cells, "Strips") == 0;
          const std::size_t a = strip ? k - 2 : begin, b = strip && (k - begin) % 2 ? k : k - 1, c = strip && (k - begin) % 2 ? k - 1 : k;
          for (const std::size_t i : {a, b, c}) mesh.triangles.push_back(base + static_cast<unsigned>(connectivity[i]));
        }
        begin = end;
      }
    }
  }
  return mesh;
}

TriangleMesh parse_stl(const std::string& content, const std::string& name) {
  TriangleMesh mesh;
  const bool ascii = content.rfind("solid", 0) == 0 && content.find("facet") != std::string::npos;
  if (!ascii) {
    if (content.size() < 84) throw InputError(name, 0, "header", "a binary STL has an 84-byte header");
    std::uint32_t count = 0;
    std::memcpy(&count, content.data() + 80, 4);
    if (content.size() < 84 + std::size_t{count} * 50) throw InputError(name, 0, "triangles", "shorter than its " + std::to_string(count) + " triangles");
    for (std::uint32_t t = 0; t < count; ++t)
      for (int v = 0; v < 3; ++v) {
        float p[3];
        std::memcpy(p, content.data() + 84 + std::size_t{t} * 50 + 12 + 12 * v, 12);
        mesh.positions.insert(mesh.positions.end(), p, p + 3);
        mesh.triangles.push_back(static_cast<unsigned>(mesh.triangles.size()));
      }
    return mesh;
  }
  int line_no = 0, facet_line = 0;  // facet_line: where the open facet began (0: none open)
  std::size_t facet_vertices = 0;
  for (const auto& line : text::split_lines(content, name).lines) {
    ++line_no;
    const auto cells = text::split_ws(line);
    if (!cells.empty() && cells[0] == "facet") {
      if (facet_line) throw InputError(name, line_no, "facet", "a facet inside the facet of line " + std::to_string(facet_line));
      facet_line = line_no;
      facet_vertices = mesh.triangles.size();
    }
    if (!cells.empty() && cells[0] == "endfacet") {
      if (!facet_line || mesh.triangles.size() - facet_vertices != 3) throw InputError(name, line_no, "facet", "a facet without three vertices");
      facet_line = 0;
    }
    if (cells.empty() || cells[0] != "vertex") continue;
    if (cells.size() != 4) throw InputError(name, line_no, "vertex", "expected three coordinates");
    for (int k = 1; k < 4; ++k) {
      float v = 0;
      if (std::from_chars(cells[k].data(), cells[k].data() + cells[k].size(), v).ec != std::errc())
        throw InputError(name, line_no, "vertex", "not a number: '" + std::string(cells[k]) + "'");
      mesh.positions.push_back(v);
    }
    mesh.triangles.push_back(static_cast<unsigned>(mesh.triangles.size()));
  }
  if (facet_line) throw InputError(name, facet_line, "facet", "the facet has no endfacet");
  if (mesh.triangles.size() % 3) throw InputError(name, line_no, "facet", "a facet without three vertices");
  return mesh;
}

TriangleMesh parse_obj(const std::string& content, const std::string& name) {
  TriangleMesh mesh;
  int line_no = 0;
  for (const auto& line : text::split_lines(content, name).lines) {
    ++line_no;
    const auto cells = text::split_ws(line);
    if (cells.empty()) continue;
    if (cells[0] == "v") {
      if (cells.size() < 4) throw InputError(name, line_no, "v", "expected three coordinates");
      for (int k = 1; k < 4; ++k) {
        float v = 0;
        if (std::from_chars(cells[k].data(), cells[k].data() + cells[k].size(), v).ec != std::errc())
          throw InputError(name, line_no, "v", "not a number: '" + std::string(cells[k]) + "'");
        mesh.positions.push_back(v);
      }
    } else if (cells[0] == "f") {
      const long n = static_cast<long>(mesh.positions.size() / 3);
      std::vector<unsigned> face;
      for (std::size_t k = 1; k < cells.size(); ++k) {
        long i = 0;  // "7", "7/1", "7//3", "-1"
        const auto r = std::from_chars(cells[k].data(), cells[k].data() + cells[k].size(), i);
        if (r.ec != std::errc()) throw InputError(name, line_no, "f", "not a vertex index: '" + std::string(cells[k]) + "'");
        const long index = i < 0 ? n + i : i - 1;
        if (index < 0 || index >= n) throw InputError(name, line_no, "f", "vertex " + std::to_string(i) + " is not defined above");
        face.push_back(static_cast<unsigned>(index));
      }
      if (face.size() < 3) throw InputError(name, line_no, "f", "a face needs three vertices");
      for (std::size_t k = 2; k < face.size(); ++k) mesh.triangles.insert(mesh.triangles.end(), {face[0], face[k - 1], face[k]});
    }
  }
  return mesh;
}

}  // namespace

TriangleMesh parse_mesh(const std::string& content, const std::string& name) {
  const std::string ext = text::lower_extension(name);
  if (ext == "vtp") return parse_vtp(content, name);
  if (ext == "stl") return parse_stl(content, name);
  if (ext == "obj") return parse_obj(content, name);
  throw InputError(name, 0, "file", "mesh files are .vtp, .stl or .obj");
}

bool is_mesh_file_name(const std::string& name) {
  const std::string ext = text::lower_extension(name);
  return ext == "vtp" || ext == "stl" || ext == "obj";
}

TriangleMesh read_mesh_file(const std::string& path) { return parse_mesh(text::read_file(path), path); }

}  // namespace cpgait::services

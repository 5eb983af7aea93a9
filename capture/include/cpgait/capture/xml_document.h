#pragma once
// pugixml with line numbers: every XML reader in cpgait (models, setups, task sets, loads) loads
// through this so that errors name the file, the line and the element.
#include <pugixml.hpp>

#include <memory>
#include <optional>
#include <utility>

#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

namespace cpgait::xml {

// A setup's tool tag as OpenSim knows it: its own IK test setups spell it "InverseKinemtaticsTool".
std::string_view tool_alias(std::string_view tag);
// A node's first child element (comments and text skipped); empty when it has none.
pugi::xml_node first_element(const pugi::xml_node& parent);

class Document {
 public:
  // Throws InputError with the line of the parse error.
  static Document load_file(const std::string& path, std::size_t max_bytes = std::size_t{1} << 30);
  static Document load_string(std::string content, const std::string& name);

  const pugi::xml_document& doc() const { return *doc_; }
  const std::string& name() const { return name_; }
  int line_of(const pugi::xml_node& node) const;

  // Errors tied to an element.
  [[noreturn]] void fail(const pugi::xml_node& node, const std::string& message) const;

  // Typed reads of a child element's text; `required` children that are missing throw.
  double number(const pugi::xml_node& parent, const char* child, double fallback, bool required = false) const;
  bool boolean(const pugi::xml_node& parent, const char* child, bool fallback) const;
  // Text, trimmed; OpenSim's "Unassigned" (a property not set) reads as the fallback.
  std::string text(const pugi::xml_node& parent, const char* child, const std::string& fallback = "") const;
  std::vector<double> numbers(const pugi::xml_node& parent, const char* child) const;
  Eigen::Vector3d vec3(const pugi::xml_node& parent, const char* child, const Eigen::Vector3d& fallback) const;
  // The <name> element of an OpenSim setup, as the root or inside <OpenSimDocument>, under any
  // spelling tool_alias knows; throws InputError when the document holds no such tool.
  pugi::xml_node tool(const char* name) const;
  // "<child>t0 t1</child>" with t0 <= t1 (s); unset when the child is absent.
  std::optional<std::pair<double, double>> time_range(const pugi::xml_node& parent, const char* child = "time_range") const;
  // Parses a node's own text as numbers.
  std::vector<double> numbers_of(const pugi::xml_node& node) const;

 private:
  Document() = default;
  std::string name_;
  std::string buffer_;
  std::vector<std::size_t> line_starts_;
  std::shared_ptr<pugi::xml_document> doc_;
  int line_at(std::ptrdiff_t offset) const;
};

}  // namespace cpgait::xml

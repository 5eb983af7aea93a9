#include "cpgait/capture/xml_document.h"

#include <algorithm>
#include <cmath>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait::xml {

Document Document::load_file(const std::string& path, std::size_t max_bytes) {
  return load_string(text::read_file(path, max_bytes), path);
}

Document Document::load_string(std::string content, const std::string& name) {
  Document d;
  d.name_ = name;
  d.buffer_ = std::move(content);
  d.line_starts_.push_back(0);
  for (std::size_t i = 0; i < d.buffer_.size(); ++i)
    if (d.buffer_[i] == '\n') d.line_starts_.push_back(i + 1);
  d.doc_ = std::make_shared<pugi::xml_document>();
  // parse_default keeps offsets valid (the buffer is not modified in place by load_buffer).
  const pugi::xml_parse_result r = d.doc_->load_buffer(d.buffer_.data(), d.buffer_.size());
  if (!r) throw InputError(name, d.line_at(r.offset), "", std::string("malformed XML: ") + r.description());
  if (!d.doc_->document_element()) throw InputError(name, 1, "", "no root element");
  return d;
}

int Document::line_at(std::ptrdiff_t offset) const {
  if (offset < 0) return 0;
  auto it = std::upper_bound(line_starts_.begin(), line_starts_.end(), static_cast<std::size_t>(offset));
  return static_cast<int>(it - line_starts_.begin());
}

int Document::line_of(const pugi::xml_node& node) const { return line_at(node.offset_debug()); }

void Document::fail(const pugi::xml_node& node, const std::string& message) const {
  throw InputError(name_, line_of(node), node.name(), message);
}

pugi::xml_node first_element(const pugi::xml_node& parent) {
  for (const auto& c : parent.children())
    if (c.type() == pugi::node_element) return c;
  return {};
}

std::string_view tool_alias(std::string_view tag) { return tag == "InverseKinemtaticsTool" ? "InverseKinematicsTool" : tag; }

pugi::xml_node Document::tool(const char* name) const {
  pugi::xml_node root = doc_->document_element();
  if (std::string_view(root.name()) == "OpenSimDocument") root = first_element(root);
  if (!root || tool_alias(root.name()) != name)
    throw InputError(name_, 1, name, std::string("not an OpenSim ") + name + " setup: no <" + name + ">");
  return root;
}

std::optional<std::pair<double, double>> Document::time_range(const pugi::xml_node& parent, const char* child) const {
  const auto node = parent.child(child);
  if (!node) return std::nullopt;
  const auto v = numbers_of(node);
  if (v.size() != 2 || !(v[0] <= v[1])) fail(node, "expected two increasing times in seconds");
  return std::make_pair(v[0], v[1]);
}

std::vector<double> Document::numbers_of(const pugi::xml_node& node) const {
  std::vector<double> out;
  for (auto cell : text::split_ws(node.child_value())) {
    double v;
    if (!text::parse_double(cell, v) || std::isnan(v))
      fail(node, "expected numbers, found '" + std::string(cell) + "'");
    out.push_back(v);
  }
  return out;
}

std::vector<double> Document::numbers(const pugi::xml_node& parent, const char* child) const {
  const auto node = parent.child(child);
  if (!node) return {};
  return numbers_of(node);
}

double Document::number(const pugi::xml_node& parent, const char* child, double fallback, bool required) const {
  const auto node = parent.child(child);
  if (!node) {
    if (required) fail(parent, std::string("missing <") + child + ">");
    return fallback;
  }
  const auto v = numbers_of(node);
  if (v.empty()) return fallback;
  if (v.size() != 1) fail(node, "expected one number");
  return v[0];
}

bool Document::boolean(const pugi::xml_node& parent, const char* child, bool fallback) const {
  const auto node = parent.child(child);
  if (!node) return fallback;
  const std::string_view v = text::trim(node.child_value());
  if (v == "true" || v == "1") return true;
  if (v == "false" || v == "0") return false;
  if (v.empty()) return fallback;
  fail(node, "expected true or false, found '" + std::string(v) + "'");
}

std::string Document::text(const pugi::xml_node& parent, const char* child, const std::string& fallback) const {
  const auto node = parent.child(child);
  if (!node) return fallback;
  const std::string_view value = text::trim(node.child_value());
  return value == "Unassigned" ? fallback : std::string(value);  // OpenSim's "not set"
}

Eigen::Vector3d Document::vec3(const pugi::xml_node& parent, const char* child,
                               const Eigen::Vector3d& fallback) const {
  const auto node = parent.child(child);
  if (!node) return fallback;
  const auto v = numbers_of(node);
  if (v.size() != 3) fail(node, "expected 3 numbers, found " + std::to_string(v.size()));
  return {v[0], v[1], v[2]};
}

}  // namespace cpgait::xml

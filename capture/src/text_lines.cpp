#include "cpgait/capture/text_lines.h"

#include <cctype>

#include <charconv>
#include <cmath>
#include <fstream>

#include "cpgait/capture/input_error.h"

namespace cpgait::text {

Lines split_lines(std::string_view content, const std::string& name) {
  Lines out;
  out.file = name;
  if (content.find('\0') != std::string_view::npos)
    throw InputError(name, 0, "", "file holds NUL bytes: expected a text file");
  std::size_t start = 0;
  while (start <= content.size()) {
    std::size_t end = content.find('\n', start);
    if (end == std::string_view::npos) end = content.size();
    std::string_view line = content.substr(start, end - start);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    out.lines.emplace_back(line);
    if (end == content.size()) break;
    start = end + 1;
  }
  // A final line end does not start a line.
  if (!out.lines.empty() && out.lines.back().empty()) out.lines.pop_back();
  return out;
}

std::string read_file(const std::string& path, std::size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open file");
  auto too_big = [&](std::size_t size) {
    return InputError(path, 0, "", "file is " + std::to_string(size) + " bytes, over the limit of " + std::to_string(max_bytes));
  };
  in.seekg(0, std::ios::end);
  const std::streamoff end = in.tellg();
  if (end < 0) {  // a pipe (`--options <(...)`): no size to ask, read up to the limit
    in.clear();
    std::string content;
    char chunk[65536];
    while (in.read(chunk, sizeof chunk) || in.gcount() > 0) {
      content.append(chunk, static_cast<std::size_t>(in.gcount()));
      if (content.size() > max_bytes) throw too_big(content.size());
    }
    return content;
  }
  const auto size = static_cast<std::size_t>(end);
  if (size > max_bytes) throw too_big(size);
  in.seekg(0);
  std::string content(size, '\0');
  in.read(content.data(), static_cast<std::streamsize>(size));
  if (!in) throw InputError(path, 0, "", "read failed");
  return content;
}

Lines read_lines(const std::string& path, std::size_t max_bytes) {
  return split_lines(read_file(path, max_bytes), path);
}

std::vector<std::string_view> split_tabs(std::string_view line) {
  std::vector<std::string_view> cells;
  std::size_t start = 0;
  while (true) {
    std::size_t end = line.find('\t', start);
    if (end == std::string_view::npos) {
      cells.push_back(line.substr(start));
      return cells;
    }
    cells.push_back(line.substr(start, end - start));
    start = end + 1;
  }
}

std::vector<std::string_view> split_ws(std::string_view line) {
  std::vector<std::string_view> cells;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) cells.push_back(line.substr(i, j - i));
    i = j;
  }
  return cells;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string lower_extension(std::string_view name) {
  const auto dot = name.rfind('.');
  return dot == std::string_view::npos ? std::string() : lower(name.substr(dot + 1));
}

bool parse_double(std::string_view cell, double& out) {
  cell = trim(cell);
  if (cell.empty()) return false;
  if (cell.front() == '+') cell.remove_prefix(1);
  if (cell == "nan" || cell == "NaN" || cell == "NAN" || cell == "-nan") {
    out = std::nan("");
    return true;
  }
  const char* end = cell.data() + cell.size();
  auto [ptr, ec] = std::from_chars(cell.data(), end, out);
  return ec == std::errc() && ptr == end;
}

bool parse_int(std::string_view cell, long long& out) {
  cell = trim(cell);
  if (cell.empty()) return false;
  const char* end = cell.data() + cell.size();
  auto [ptr, ec] = std::from_chars(cell.data(), end, out);
  return ec == std::errc() && ptr == end;
}

}  // namespace cpgait::text

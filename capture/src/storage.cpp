#include "cpgait/capture/storage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"

namespace cpgait {

int Storage::column(std::string_view label) const {
  for (int i = 0; i < static_cast<int>(labels.size()); ++i)
    if (labels[i] == label) return i;
  return -1;
}

Storage make_storage(std::string name, const std::vector<std::string>& labels, const std::vector<double>& time_s,
                     const Eigen::MatrixXd& values, std::optional<bool> in_degrees) {
  if (values.rows() != static_cast<Eigen::Index>(time_s.size()) || values.cols() != static_cast<Eigen::Index>(labels.size()))
    throw std::logic_error("make_storage: " + name + ": times, labels and values disagree in size");
  Storage s;
  s.name = std::move(name);
  s.in_degrees = in_degrees;
  s.labels.reserve(labels.size() + 1);
  s.labels.push_back("time");
  s.labels.insert(s.labels.end(), labels.begin(), labels.end());
  s.data.resize(values.rows(), values.cols() + 1);
  s.data.col(0) = Eigen::Map<const Eigen::VectorXd>(time_s.data(), values.rows());
  s.data.rightCols(values.cols()) = values;
  return s;
}

Storage read_storage(const std::string& path, const StorageReadOptions& options) {
  return parse_storage(text::read_file(path, options.max_bytes), path, options);
}

Storage parse_storage(std::string_view content, const std::string& name,
                      const StorageReadOptions& options) {
  if (content.size() > options.max_bytes)
    throw InputError(name, 0, "", "upload is over the limit of " + std::to_string(options.max_bytes) + " bytes");
  const text::Lines lines = text::split_lines(content, name);
  const auto& L = lines.lines;
  auto fail = [&](std::size_t index, const std::string& field, const std::string& msg) {
    return InputError(name, static_cast<int>(index) + 1, field, msg);
  };

  Storage table;
  long long n_rows = -1, n_columns = -1;
  std::size_t li = 0;
  bool ended = false;
  for (; li < L.size(); ++li) {
    const std::string_view line = text::trim(L[li]);
    if (line == "endheader") {
      ended = true;
      ++li;
      break;
    }
    auto key_value = [&](std::string_view key, long long& out) {
      // "key=value" (current header) or "key value" (SIMM header).
      if (line.substr(0, key.size()) != key) return false;
      std::string_view rest = text::trim(line.substr(key.size()));
      if (!rest.empty() && rest.front() == '=') rest = text::trim(rest.substr(1));
      if (!text::parse_int(rest, out) || out < 0)
        throw fail(li, std::string(key), "expected a non-negative whole number, found '" + std::string(rest) + "'");
      return true;
    };
    if (key_value("nRows", n_rows) || key_value("datarows", n_rows)) continue;
    if (key_value("nColumns", n_columns) || key_value("datacolumns", n_columns)) continue;
    if (line.substr(0, 9) == "inDegrees") {
      std::string_view v = text::trim(line.substr(9));
      if (!v.empty() && v.front() == '=') v = text::trim(v.substr(1));
      if (v == "yes" || v == "true") table.in_degrees = true;
      else if (v == "no" || v == "false") table.in_degrees = false;
      else throw fail(li, "inDegrees", "expected yes or no, found '" + std::string(v) + "'");
      continue;
    }
    if (line.substr(0, 7) == "version") continue;  // we always write version=1
    if (li == 0) {
      table.name = std::string(line);
      continue;
    }
    table.extra_header.emplace_back(L[li]);
  }
  if (!ended) throw fail(L.empty() ? 0 : L.size() - 1, "endheader", "no 'endheader' line: not a .mot/.sto file, or truncated header");

  while (li < L.size() && text::trim(L[li]).empty()) ++li;
  if (li >= L.size()) throw fail(L.size() - 1, "labels", "file ends before the column labels line");
  // Labels are tab separated (they may hold spaces in some writers) unless the line has no tab.
  const std::string_view label_line = L[li];
  auto label_cells = label_line.find('\t') != std::string_view::npos ? text::split_tabs(label_line)
                                                                      : text::split_ws(label_line);
  while (!label_cells.empty() && text::trim(label_cells.back()).empty()) label_cells.pop_back();
  for (auto c : label_cells) table.labels.emplace_back(text::trim(c));
  const std::size_t label_index = li;
  if (table.labels.empty()) throw fail(label_index, "labels", "empty column labels line");
  if (n_columns >= 0 && n_columns != static_cast<long long>(table.labels.size()))
    throw fail(label_index, "nColumns",
               "header says " + std::to_string(n_columns) + " columns but the labels line has " +
                   std::to_string(table.labels.size()));
  const std::size_t cols = table.labels.size();

  std::vector<double> values;
  values.reserve(std::min<std::size_t>(L.size() - li, n_rows < 0 ? 0 : n_rows) * cols);
  std::size_t rows = 0, repeated = 0;
  for (++li; li < L.size(); ++li) {
    if (text::trim(L[li]).empty()) continue;
    const auto cells = text::split_ws(L[li]);
    if (cells.size() != cols) {
      const std::string field = cells.size() < cols ? table.labels[cells.size()] : "";
      throw fail(li, field,
                 "expected " + std::to_string(cols) + " values, found " + std::to_string(cells.size()) +
                     (cells.size() < cols ? " (truncated row?)" : ""));
    }
    for (std::size_t c = 0; c < cols; ++c) {
      double v;
      if (!text::parse_double(cells[c], v))
        throw fail(li, table.labels[c], "expected a number, found '" + std::string(cells[c]) + "'");
      values.push_back(v);
    }
    if (rows > 0 && !(values[rows * cols] > values[(rows - 1) * cols])) {
      // OpenSim writes a simulation's last state twice (equal to its printed digits, not always to the
      // last one); such a repeat carries nothing new.
      const auto same = [](double a, double b) { return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(a)); };
      if (std::equal(values.end() - cols, values.end(), values.end() - 2 * cols, same)) {
        values.resize(values.size() - cols);
        ++repeated;
        continue;
      }
      throw fail(li, table.labels[0], "time does not increase");
    }
    ++rows;
  }
  // As OpenSim, the rows present are the table; the header's count is only a hint (the TRC reader
  // does the same with NumFrames).
  if (n_rows >= 0 && static_cast<long long>(rows + repeated) != n_rows)
    table.warnings.push_back(name + ": the header says nRows=" + std::to_string(n_rows) + " but the file has " +
                             std::to_string(rows + repeated) + " rows; the rows are used");
  if (rows == 0) throw fail(L.size() - 1, "nRows", "the file has no data rows");
  table.data = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      values.data(), static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
  return table;
}

std::string format_storage(const Storage& table, int digits) {
  std::string out;
  out += (table.name.empty() ? std::string("table") : table.name) + "\n";
  out += "version=1\n";
  out += "nRows=" + std::to_string(table.num_rows()) + "\n";
  out += "nColumns=" + std::to_string(table.labels.size()) + "\n";
  if (table.in_degrees) out += std::string("inDegrees=") + (*table.in_degrees ? "yes" : "no") + "\n";
  for (const auto& h : table.extra_header) out += h + "\n";
  out += "endheader\n";
  for (std::size_t c = 0; c < table.labels.size(); ++c) out += (c ? "\t" : "") + table.labels[c];
  out += "\n";
  // What printf's %.*g writes, without its locale and format parsing (a tenth of CMC's run time went
  // to snprintf here, then a sixth of run-tool's to std::to_chars).
  // Row by row through a buffer: each number takes at most 32 chars and its tab or line end one more.
  std::vector<char> row(static_cast<std::size_t>(table.num_columns() + 1) * 33);
  out.reserve(out.size() + static_cast<std::size_t>(table.num_rows()) * static_cast<std::size_t>(table.num_columns()) * (digits + 8));
  for (int r = 0; r < table.num_rows(); ++r) {
    char* p = row.data();
    for (int c = 0; c < table.num_columns(); ++c) {
      if (c) *p++ = '\t';
      p = text::format_general(table.data(r, c), digits, p);
    }
    *p++ = '\n';
    out.append(row.data(), p);
  }
  return out;
}

void write_storage(const Storage& table, const std::string& path, int digits) {
  if (table.labels.size() != static_cast<std::size_t>(table.num_columns()))
    throw std::logic_error("write_storage: labels and data columns differ for " + path);
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path + ": cannot open for writing");
  out << format_storage(table, digits);
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace cpgait

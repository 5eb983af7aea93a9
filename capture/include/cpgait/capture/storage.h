#pragma once
// OpenSim's tabular time series (.mot/.sto): the current header (version=, nRows=, nColumns=,
// inDegrees=, endheader) and the old SIMM motion header (datacolumns, datarows, range, name).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace cpgait {

struct Storage {
  std::string name;                 // first header line (the table's name)
  std::vector<std::string> labels;  // column labels; labels[0] is "time"
  Eigen::MatrixXd data;             // one row per time, one column per label
  // Whether angles in the file are degrees. Unset when the file did not say (old SIMM files are in
  // degrees by convention; the consumer decides and warns).
  std::optional<bool> in_degrees;
  // Header lines we do not interpret, kept in order so a round trip preserves them.
  std::vector<std::string> extra_header;
  // What the reader accepted but the user should know (e.g. fewer rows than the header's nRows).
  std::vector<std::string> warnings;

  int num_rows() const { return static_cast<int>(data.rows()); }
  int num_columns() const { return static_cast<int>(data.cols()); }
  int column(std::string_view label) const;  // -1 when absent
  auto time() const { return data.col(0); }
};

struct StorageReadOptions {
  std::size_t max_bytes = std::size_t{1} << 30;
};

// A table from times and a matrix of values (rows = times, columns = labels after "time").
Storage make_storage(std::string name, const std::vector<std::string>& labels, const std::vector<double>& time_s,
                     const Eigen::MatrixXd& values, std::optional<bool> in_degrees = false);

// Throws InputError naming the file, line and field for anything malformed.
Storage read_storage(const std::string& path, const StorageReadOptions& options = {});
Storage parse_storage(std::string_view content, const std::string& name,
                      const StorageReadOptions& options = {});

// Writes the current OpenSim header (version=1) and tab-separated columns with `digits`
// significant digits.
std::string format_storage(const Storage& table, int digits = 12);
void write_storage(const Storage& table, const std::string& path, int digits = 12);

}  // namespace cpgait

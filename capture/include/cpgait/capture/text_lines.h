#pragma once
// Line-oriented reading shared by the TRC and MOT/STO readers: CRLF and LF line ends, a size cap so a
// hostile upload cannot exhaust memory, and strict number parsing that reports what it saw; and the
// writers' number formatting.
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace cpgait::text {

struct Lines {
  std::string file;                 // name used in error messages
  std::vector<std::string> lines;   // without line ends
};

// Reads a whole file into memory. Throws InputError if it cannot be opened or exceeds max_bytes.
std::string read_file(const std::string& path, std::size_t max_bytes = std::size_t{1} << 30);
// Reads a whole text file. Throws InputError if it cannot be opened, exceeds max_bytes, or holds NUL
// bytes (a binary file passed by mistake).
Lines read_lines(const std::string& path, std::size_t max_bytes = std::size_t{1} << 30);
// The same over text already in memory (uploads); `name` is used in messages.
Lines split_lines(std::string_view content, const std::string& name);

// Splits on tabs only, keeping empty cells (TRC blank cells mean "missing marker").
std::vector<std::string_view> split_tabs(std::string_view line);
// Splits on any run of spaces or tabs (no empty cells).
std::vector<std::string_view> split_ws(std::string_view line);
std::string_view trim(std::string_view s);
// ASCII lower case (header keys, units, file extensions).
std::string lower(std::string_view s);
// A file name's extension after its last dot, lower case ("Femur.VTP" -> "vtp"; "" without a dot).
std::string lower_extension(std::string_view name);

// Parses a whole cell as a double ("nan" accepted); false if anything else is in the cell.
bool parse_double(std::string_view cell, double& out);
bool parse_int(std::string_view cell, long long& out);

// Writes x as printf's %.*g does with `digits` significant digits (1-17; C locale) into out, which
// holds at least 32 chars; returns the end. The same characters as std::to_chars' general format at
// that precision, in under two fifths of its instructions for a table's values (12 digits).
char* format_general(double x, int digits, char* out);

}  // namespace cpgait::text

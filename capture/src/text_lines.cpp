#include "cpgait/capture/text_lines.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
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

namespace {

// 10^k, k = 0..22: exact in double (5^22 < 2^53).
constexpr std::array<double, 23> powers_of_ten() {
  std::array<double, 23> p{};
  double v = 1;
  for (double& e : p) {
    e = v;
    v *= 10;
  }
  return p;
}
constexpr std::array<double, 23> kPow10 = powers_of_ten();

// a * 10^k with one rounding (|k| <= 22).
double times_power_of_ten(double a, int k) { return k >= 0 ? a * kPow10[k] : a / kPow10[-k]; }

char* general_by_to_chars(double x, int digits, char* out) {
  return std::to_chars(out, out + 32, x, std::chars_format::general, std::clamp(digits, 1, 17)).ptr;
}

}  // namespace

char* format_general(double x, int digits, char* out) {
  // The digits: m = |x| 10^k rounded to an integer. The product has one rounding, within a unit of its
  // last place, so the integer is the correctly rounded one unless m lies within two units of a half.
  // Those (54 of 136,000 values in a CMC run's tables), precisions over 15 and magnitudes outside
  // [1e-7, 1e15) go to std::to_chars.
  const double a = std::abs(x);
  if (x == 0 && digits >= 1 && digits <= 17) {
    if (std::signbit(x)) *out++ = '-';
    *out++ = '0';
    return out;
  }
  if (!(digits >= 1 && digits <= 15 && a >= 1e-7 && a < 1e15)) return general_by_to_chars(x, digits, out);
  // The decimal exponent of a's leading digit, from its binary one: floor(e2 log10 2) as Ryu takes
  // it (78913 / 2^18), then one step up where that fell short.
  std::uint64_t bits;
  std::memcpy(&bits, &a, sizeof bits);
  const int e2 = static_cast<int>(bits >> 52) - 1023;  // a = 1.f 2^e2 (normal here)
  int e10 = (e2 * 78913) >> 18;
  const double low = kPow10[digits - 1], high = kPow10[digits];
  double m = times_power_of_ten(a, digits - 1 - e10);
  if (m >= high) m = times_power_of_ten(a, digits - 1 - ++e10);
  std::uint64_t n = static_cast<std::uint64_t>(m);  // m >= 0: truncation is floor
  const double frac = m - static_cast<double>(n);
  if (m < low || std::abs(frac - 0.5) <= m * 4.5e-16) return general_by_to_chars(x, digits, out);
  n += frac > 0.5 ? 1 : 0;
  if (n >= static_cast<std::uint64_t>(high)) {  // rounded up to the next power of ten
    n /= 10;
    ++e10;
  }
  static constexpr char kPairs[] =
      "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
      "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
      "8081828384858687888990919293949596979899";
  // Two digits at a time, in 32-bit arithmetic: n < 10^15 splits into three parts below 10^6.
  char d[18];
  std::uint32_t parts[3] = {static_cast<std::uint32_t>(n / 1000000000000ULL), static_cast<std::uint32_t>(n / 1000000 % 1000000),
                            static_cast<std::uint32_t>(n % 1000000)};
  for (int p = (18 - digits) / 6; p < 3; ++p) {  // the parts holding n's digits
    std::uint32_t v = parts[p];
    for (int k = 4; k >= 0; k -= 2, v /= 100) std::memcpy(d + 6 * p + k, kPairs + 2 * (v % 100), 2);
  }
  const char* const digit = d + 18 - digits;  // n's digits are the last `digits` of these 18
  int used = digits;  // without trailing zeros, as %g drops them
  while (used > 1 && digit[used - 1] == '0') --used;
  if (x < 0) *out++ = '-';
  if (e10 >= -4 && e10 < digits) {  // fixed
    if (e10 < 0) {
      std::memcpy(out, "0.0000", static_cast<std::size_t>(1 - e10));
      out += 1 - e10;
      std::memcpy(out, digit, static_cast<std::size_t>(used));
      return out + used;
    }
    std::memcpy(out, digit, static_cast<std::size_t>(e10 + 1));
    out += e10 + 1;
    if (used > e10 + 1) {
      *out++ = '.';
      std::memcpy(out, digit + e10 + 1, static_cast<std::size_t>(used - e10 - 1));
      out += used - e10 - 1;
    }
    return out;
  }
  *out++ = digit[0];  // scientific: d.ddde+XX, at least two exponent digits
  if (used > 1) {
    *out++ = '.';
    std::memcpy(out, digit + 1, static_cast<std::size_t>(used - 1));
    out += used - 1;
  }
  *out++ = 'e';
  *out++ = e10 < 0 ? '-' : '+';
  std::memcpy(out, kPairs + 2 * std::abs(e10), 2);  // |e10| < 15 here: always two digits
  return out + 2;
}

}  // namespace cpgait::text

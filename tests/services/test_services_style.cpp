// services/ stays a thin layer of short functions: no function over 100 lines, run_pipeline under 80
// (issue 17). The scan strips comments, strings and preprocessor lines, then finds function bodies
// as brace blocks opened at namespace or class scope after a parameter list.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct FunctionSpan {
  std::string file, name;
  int first_line, lines;
};

// The source with comments, string and character literals, preprocessor lines and access specifiers
// blanked (newlines kept, so line numbers hold).
std::string code_only(const std::string& s) {
  std::string out = s;
  auto blank = [&](std::size_t a, std::size_t b) {
    for (std::size_t i = a; i < b && i < out.size(); ++i)
      if (out[i] != '\n') out[i] = ' ';
  };
  for (std::size_t i = 0; i < s.size();) {
    if (s.compare(i, 2, "//") == 0) {
      const std::size_t e = s.find('\n', i);
      blank(i, e), i = e == std::string::npos ? s.size() : e;
    } else if (s.compare(i, 2, "/*") == 0) {
      const std::size_t e = s.find("*/", i + 2) + 2;
      blank(i, e), i = e;
    } else if (s[i] == 'R' && i + 1 < s.size() && s[i + 1] == '"') {
      const std::size_t open = s.find('(', i);
      const std::string close = ")" + s.substr(i + 2, open - i - 2) + "\"";
      const std::size_t e = s.find(close, open) + close.size();
      blank(i, e), i = e;
    } else if (s[i] == '"' || (s[i] == '\'' && !(i > 0 && std::isxdigit(static_cast<unsigned char>(s[i - 1]))))) {
      std::size_t e = i + 1;
      while (e < s.size() && s[e] != s[i]) e += s[e] == '\\' ? 2 : 1;
      blank(i, e + 1), i = e + 1;
    } else if (s[i] == '#' && (i == 0 || s.find_first_not_of(" \t", s.rfind('\n', i - 1) + 1) == i)) {
      const std::size_t e = s.find('\n', i);
      blank(i, e), i = e == std::string::npos ? s.size() : e;
    } else {
      ++i;
    }
  }
  return std::regex_replace(out, std::regex(R"(\b(public|private|protected)\s*:)"), "       ");
}

std::vector<FunctionSpan> functions_in(const std::string& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string code = code_only(ss.str());
  enum Kind { kScope, kFunction, kOther };
  std::vector<std::pair<Kind, std::size_t>> open;  // kind, where the header began
  std::vector<FunctionSpan> out;
  std::size_t header_start = 0;
  auto line_of = [&](std::size_t pos) { return 1 + static_cast<int>(std::count(code.begin(), code.begin() + static_cast<long>(pos), '\n')); };
  for (std::size_t i = 0; i < code.size(); ++i) {
    const char c = code[i];
    if (c == '{') {
      const bool in_function = std::any_of(open.begin(), open.end(), [](const auto& o) { return o.first != kScope; });
      const std::string header = code.substr(header_start, i - header_start);
      Kind kind = kOther;
      if (!in_function) {
        if (std::regex_search(header, std::regex(R"(\b(namespace|class|struct|union|enum)\b|extern\s*$)")) && header.find('(') == std::string::npos)
          kind = kScope;
        else if (header.find(')') != std::string::npos && !std::regex_search(header.substr(0, header.find('(')), std::regex("=")))
          kind = kFunction;
      }
      open.push_back({kind, header_start + header.find_first_not_of(" \t\n")});
      header_start = i + 1;
    } else if (c == '}') {
      if (open.empty()) continue;
      const auto [kind, start] = open.back();
      open.pop_back();
      if (kind == kFunction) {
        const std::string header = code.substr(start, code.find('(', start) - start);
        std::smatch m;
        std::regex_search(header, m, std::regex(R"(([~\w:]+)\s*$)"));
        out.push_back({fs::path(file).filename().string(), m.size() > 1 ? m[1].str() : header, line_of(start), line_of(i) - line_of(start) + 1});
      }
      header_start = i + 1;
    } else if (c == ';') {
      header_start = i + 1;
    }
  }
  return out;
}

std::vector<FunctionSpan> services_functions() {
  std::vector<FunctionSpan> all;
  for (const auto& e : fs::recursive_directory_iterator(fs::path(CPGAIT_SOURCE_DIR) / "services" / "src"))
    if (e.path().extension() == ".cpp" || e.path().extension() == ".h")
      for (auto& f : functions_in(e.path().string())) all.push_back(f);
  return all;
}

}  // namespace

TEST(ServicesStyle, TheScannerFindsFunctionsAndTheirLengths) {
  const std::string file = (fs::temp_directory_path() / "cpgait_style_probe.cpp").string();
  std::ofstream(file) << "#include <x>\nnamespace a {\nstruct S {\n public:\n  int f(int x) const {\n    return x; // }\n  }\n};\n"
                         "const char* s = \"{\";\nint g() {\n  auto l = [] { return 1; };\n  if (l()) {\n  }\n  return 0;\n}\n}  // namespace a\n";
  const auto found = functions_in(file);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].name, "f");
  EXPECT_EQ(found[0].lines, 3);
  EXPECT_EQ(found[1].name, "g");
  EXPECT_EQ(found[1].first_line, 10);
  EXPECT_EQ(found[1].lines, 6);
}

TEST(ServicesStyle, NoFunctionOver100LinesAndRunPipelineUnder80) {
  const auto all = services_functions();
  EXPECT_GT(all.size(), 100u) << "the scan found too few functions to be reading services/src";
  bool saw_run_pipeline = false;
  for (const auto& f : all) {
    EXPECT_LE(f.lines, 100) << f.file << ":" << f.first_line << " " << f.name << " has " << f.lines << " lines";
    if (f.name == "run_pipeline") {
      saw_run_pipeline = true;
      EXPECT_LT(f.lines, 80) << "run_pipeline has " << f.lines << " lines";
    }
  }
  EXPECT_TRUE(saw_run_pipeline);
}

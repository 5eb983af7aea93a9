#pragma once
// The one error type for bad input anywhere in cpgait: it names the file, the line (0 when the
// problem is not tied to a line) and the field, so that the CLI prints it and the service turns it
// into {"error": {"code", "message", "field", "line"}} without parsing a message.
#include <stdexcept>
#include <string>

namespace cpgait {

class InputError : public std::runtime_error {
 public:
  InputError(std::string file, int line, std::string field, std::string message)
      : std::runtime_error(format(file, line, field, message)),
        file_(std::move(file)), line_(line), field_(std::move(field)), message_(std::move(message)) {}

  const std::string& file() const { return file_; }
  int line() const { return line_; }
  const std::string& field() const { return field_; }
  const std::string& message() const { return message_; }

 private:
  static std::string format(const std::string& file, int line, const std::string& field,
                            const std::string& message) {
    // Built with append (not operator+ chains): GCC 12 warns falsely (-Wrestrict) on the latter.
    std::string s;
    s.reserve(file.size() + field.size() + message.size() + 16);
    s.append(file);
    if (line > 0) s.append(":").append(std::to_string(line));
    s.append(": ");
    if (!field.empty()) s.append(field).append(": ");
    s.append(message);
    return s;
  }
  std::string file_;
  int line_;
  std::string field_;
  std::string message_;
};

}  // namespace cpgait

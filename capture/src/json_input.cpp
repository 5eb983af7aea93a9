#include "cpgait/capture/json_input.h"

#include <algorithm>

#include "cpgait/capture/input_error.h"

namespace cpgait {

nlohmann::json parse_json_input(const std::string& text, const std::string& name) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    const std::size_t upto = std::min<std::size_t>(e.byte, text.size());
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(upto), '\n'));
    throw InputError(name, line, "", std::string("malformed JSON: ") + e.what());
  } catch (const nlohmann::json::exception& e) {  // a number past double's range, found by fuzzing
    throw InputError(name, 0, "", std::string("malformed JSON: ") + e.what());
  }
}

void throw_json_field_error(const std::string& name, const std::string& field, const std::string& message) {
  throw InputError(name, 0, field, message);
}

}  // namespace cpgait

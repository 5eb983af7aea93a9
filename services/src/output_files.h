#pragma once
// Result files are written to a temporary name and renamed into place, so a crash or a concurrent
// reader never sees half a file.
#include <string>

#include <nlohmann/json.hpp>

#include "cpgait/capture/storage.h"

namespace cpgait::services {

void write_text_atomic(const std::string& path, const std::string& content);
// digits: significant digits (format_storage; 17 round-trips every double).
void write_storage_atomic(const Storage& table, const std::string& path, int digits = 12);
// Creates the folder (and parents); throws with the path on failure.
void ensure_directory(const std::string& dir);
// JSON text of `j`. Strings from users' files (labels, names, error messages) may hold bytes that are
// not UTF-8; they are replaced by U+FFFD instead of throwing.
std::string json_text(const nlohmann::json& j, int indent = -1);

}  // namespace cpgait::services

#pragma once
// SHA-256 (FIPS 180-4), for the checksums a worker records with a trial's results.
#include <string>
#include <string_view>

namespace cpgait::services {

std::string sha256_hex(std::string_view bytes);  // 64 lowercase hex digits

}  // namespace cpgait::services

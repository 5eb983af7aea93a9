#pragma once
// Files in a ZIP archive (PKWARE's APPNOTE: stored or deflated entries, with or without data
// descriptors), as a lab zips a model with its Geometry folder. ZIP64, encrypted and split archives
// are refused with a message saying so.
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace cpgait::services {

struct ZipEntry {
  std::string path;     // as stored, with '/' separators
  std::string content;  // unpacked
};

struct ZipReadOptions {
  // Unpacked bytes of all entries together; an archive that would unpack to more is refused (a zip
  // bomb). Default 1 GiB.
  std::size_t max_total_bytes = std::size_t{1} << 30;
};

// Whether bytes start as a ZIP archive does (a local file header, or an empty archive's end record).
bool looks_like_zip(std::string_view bytes);

// The archive's files in central-directory order. Folders, and macOS' resource forks (__MACOSX/ and
// ._ files, which Finder's "Compress" adds), are left out. Throws InputError naming the archive, the
// entry and the byte offset where the structure is wrong; every entry's CRC-32 is checked.
std::vector<ZipEntry> read_zip(std::string_view bytes, const std::string& name, const ZipReadOptions& options = {});

}  // namespace cpgait::services

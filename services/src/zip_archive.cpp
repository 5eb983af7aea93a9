#include "zip_archive.h"

#include <zlib.h>

#include <cstdint>

#include "cpgait/capture/input_error.h"

namespace cpgait::services {
namespace {

constexpr std::uint32_t kLocalHeader = 0x04034b50, kCentralHeader = 0x02014b50, kEndRecord = 0x06054b50;

std::uint32_t le(std::string_view b, std::size_t at, int bytes) {
  std::uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + static_cast<std::size_t>(i)]);
  return v;
}

std::string at_byte(std::size_t offset) { return " at byte " + std::to_string(offset); }

}  // namespace

bool looks_like_zip(std::string_view bytes) {
  return bytes.size() >= 4 && (le(bytes, 0, 4) == kLocalHeader || (bytes.size() == 22 && le(bytes, 0, 4) == kEndRecord));
}

std::vector<ZipEntry> read_zip(std::string_view b, const std::string& name, const ZipReadOptions& options) {
  auto fail = [&](const std::string& entry, const std::string& message) -> void {
    throw InputError(name, 0, entry.empty() ? "zip" : entry, message);
  };
  // The end-of-central-directory record: the last 22 bytes, or earlier by an archive comment.
  if (b.size() < 22) fail("", "not a ZIP archive: shorter than its end record (22 bytes)");
  std::size_t end = std::string_view::npos;
  for (std::size_t at = b.size() - 22;; --at) {
    if (le(b, at, 4) == kEndRecord && at + 22 + le(b, at + 20, 2) == b.size()) {
      end = at;
      break;
    }
    if (at == 0 || b.size() - at > 22 + 0xFFFF) break;
  }
  if (end == std::string_view::npos) fail("", "not a ZIP archive: no end-of-central-directory record");
  if (le(b, end + 4, 2) != 0 || le(b, end + 6, 2) != 0) fail("", "split (multi-part) ZIP archives are not supported");
  const std::uint32_t count = le(b, end + 10, 2), directory_size = le(b, end + 12, 4), directory_at = le(b, end + 16, 4);
  if (count == 0xFFFF || directory_size == 0xFFFFFFFF || directory_at == 0xFFFFFFFF)
    fail("", "ZIP64 archives are not supported (zip writes them past 4 GB or 65,535 files, or when forced)");
  if (std::uint64_t{directory_at} + directory_size > end) fail("", "the central directory" + at_byte(directory_at) + " runs past the end record");

  std::vector<ZipEntry> out;
  std::size_t total = 0, at = directory_at;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (at + 46 > end || le(b, at, 4) != kCentralHeader) fail("", "central directory entry " + std::to_string(i + 1) + " is missing" + at_byte(at));
    const std::uint32_t flags = le(b, at + 8, 2), method = le(b, at + 10, 2), crc = le(b, at + 16, 4);
    const std::uint32_t packed = le(b, at + 20, 4), size = le(b, at + 24, 4);
    const std::size_t name_length = le(b, at + 28, 2), extra = le(b, at + 30, 2), comment = le(b, at + 32, 2);
    const std::uint32_t local_at = le(b, at + 42, 4);
    if (at + 46 + name_length + extra + comment > end) fail("", "central directory entry " + std::to_string(i + 1) + " runs past its directory" + at_byte(at));
    std::string path(b.substr(at + 46, name_length));
    at += 46 + name_length + extra + comment;
    for (char& c : path)
      if (c == '\\') c = '/';  // some Windows tools
    const std::size_t slash = path.rfind('/');
    const std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
    if (path.empty() || path.back() == '/' || path.rfind("__MACOSX/", 0) == 0 || base.rfind("._", 0) == 0) continue;
    if (flags & 1u) fail(path, "encrypted entries are not supported");
    if (method != 0 && method != 8) fail(path, "compression method " + std::to_string(method) + " is not supported (only stored and deflate)");
    if (packed == 0xFFFFFFFF || size == 0xFFFFFFFF) fail(path, "ZIP64 entries are not supported");
    if (method == 0 && packed != size) fail(path, "a stored entry's packed and unpacked sizes differ");
    total += size;
    if (total > options.max_total_bytes)
      fail(path, "the archive unpacks to more than " + std::to_string(options.max_total_bytes) + " bytes, the most accepted");
    // The data follow the local header, whose name and extra field may differ in length from the
    // central directory's.
    if (std::uint64_t{local_at} + 30 > directory_at || le(b, local_at, 4) != kLocalHeader)
      fail(path, "no local file header" + at_byte(local_at));
    const std::uint64_t data_at = std::uint64_t{local_at} + 30 + le(b, local_at + 26, 2) + le(b, local_at + 28, 2);
    if (data_at + packed > directory_at) fail(path, "the entry's data" + at_byte(local_at) + " run into the central directory");
    const std::string_view data = b.substr(static_cast<std::size_t>(data_at), packed);
    ZipEntry e{path, std::string(size, '\0')};
    if (method == 0) {
      e.content.assign(data);
    } else {
      z_stream z{};
      if (inflateInit2(&z, -MAX_WBITS) != Z_OK) fail(path, "cannot start inflating");
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
      z.avail_in = static_cast<uInt>(data.size());
      z.next_out = reinterpret_cast<Bytef*>(e.content.data());
      z.avail_out = static_cast<uInt>(size);
      // An output buffer of exactly the declared size: a stream that wants more ends as Z_BUF_ERROR/Z_OK.
      const int r = inflate(&z, Z_FINISH);
      const uLong produced = z.total_out;
      inflateEnd(&z);
      if (r != Z_STREAM_END || produced != size)
        fail(path, "the deflated data" + at_byte(static_cast<std::size_t>(data_at)) + " are corrupt or do not unpack to the " + std::to_string(size) + " bytes declared");
    }
    if (crc32(0L, reinterpret_cast<const Bytef*>(e.content.data()), static_cast<uInt>(e.content.size())) != crc)
      fail(path, "CRC-32 mismatch: the entry is corrupt");
    out.push_back(std::move(e));
  }
  return out;
}

}  // namespace cpgait::services

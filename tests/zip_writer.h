#pragma once
// A minimal ZIP writer for tests and fuzz seeds: stored or deflated entries, optionally with data
// descriptors (sizes after the data, as streaming zippers write them).
#include <zlib.h>

#include <cstdint>
#include <string>
#include <vector>

namespace cpgait::testing {

struct ZipWriterEntry {
  std::string path, content;
  bool deflate = true;
  bool data_descriptor = false;
};

inline std::string write_zip(const std::vector<ZipWriterEntry>& entries, const std::string& comment = "") {
  std::string out, directory;
  auto put = [](std::string& s, std::uint32_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  for (const auto& e : entries) {
    std::string data = e.content;
    if (e.deflate) {
      z_stream z{};
      deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
      data.assign(deflateBound(&z, static_cast<uLong>(e.content.size())), '\0');
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(e.content.data()));
      z.avail_in = static_cast<uInt>(e.content.size());
      z.next_out = reinterpret_cast<Bytef*>(data.data());
      z.avail_out = static_cast<uInt>(data.size());
      deflate(&z, Z_FINISH);
      data.resize(z.total_out);
      deflateEnd(&z);
    }
    const auto crc = static_cast<std::uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(e.content.data()), static_cast<uInt>(e.content.size())));
    const auto offset = static_cast<std::uint32_t>(out.size());
    const std::uint32_t flags = e.data_descriptor ? 8 : 0, method = e.deflate ? 8 : 0;
    put(out, 0x04034b50, 4), put(out, 20, 2), put(out, flags, 2), put(out, method, 2), put(out, 0, 4);
    put(out, e.data_descriptor ? 0 : crc, 4), put(out, e.data_descriptor ? 0 : static_cast<std::uint32_t>(data.size()), 4);
    put(out, e.data_descriptor ? 0 : static_cast<std::uint32_t>(e.content.size()), 4);
    put(out, static_cast<std::uint32_t>(e.path.size()), 2), put(out, 0, 2);
    out += e.path + data;
    if (e.data_descriptor)
      put(out, 0x08074b50, 4), put(out, crc, 4), put(out, static_cast<std::uint32_t>(data.size()), 4),
          put(out, static_cast<std::uint32_t>(e.content.size()), 4);
    put(directory, 0x02014b50, 4), put(directory, 20, 2), put(directory, 20, 2), put(directory, flags, 2), put(directory, method, 2);
    put(directory, 0, 4), put(directory, crc, 4), put(directory, static_cast<std::uint32_t>(data.size()), 4);
    put(directory, static_cast<std::uint32_t>(e.content.size()), 4), put(directory, static_cast<std::uint32_t>(e.path.size()), 2);
    put(directory, 0, 2), put(directory, 0, 2), put(directory, 0, 2), put(directory, 0, 2), put(directory, 0, 4), put(directory, offset, 4);
    directory += e.path;
  }
  const auto directory_at = static_cast<std::uint32_t>(out.size());
  out += directory;
  put(out, 0x06054b50, 4), put(out, 0, 2), put(out, 0, 2), put(out, static_cast<std::uint32_t>(entries.size()), 2);
  put(out, static_cast<std::uint32_t>(entries.size()), 2), put(out, static_cast<std::uint32_t>(directory.size()), 4), put(out, directory_at, 4);
  put(out, static_cast<std::uint32_t>(comment.size()), 2);
  return out + comment;
}

}  // namespace cpgait::testing

#include "io/zip_write.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

void put16(std::string& o, uint32_t v) {
  o += char(v & 0xff);
  o += char((v >> 8) & 0xff);
}
void put32(std::string& o, uint32_t v) {
  put16(o, v & 0xffff);
  put16(o, v >> 16);
}

// MS-DOS date and time of now (local time, as zip tools expect).
void dos_now(uint32_t& date, uint32_t& time) {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  ::localtime_r(&t, &tm);
  date = uint32_t(((std::max(tm.tm_year, 80) - 80) << 9) | ((tm.tm_mon + 1) << 5) | tm.tm_mday);
  time = uint32_t((tm.tm_hour << 11) | (tm.tm_min << 5) | (tm.tm_sec / 2));
}

}  // namespace

void write_zip(const std::string& path,
               const std::vector<std::pair<std::string, std::string>>& entries) {
  uint32_t date, time;
  dos_now(date, time);
  write_via_temp(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw Error("cannot write " + tmp);
    std::string central;
    uint64_t offset = 0;
    std::vector<char> buf(1 << 16);
    for (const auto& [name, file] : entries) {
      std::ifstream in(file, std::ios::binary);
      if (!in) throw Error("zip: cannot read " + file);
      const uint64_t size = fs::file_size(file);
      if (size >= 0xffffffffull || offset + size >= 0xffffffffull || name.size() > 0xffff)
        throw Error("zip: " + file + " is too large for a zip without zip64");
      // The CRC first (one read), then the header and the data (a second).
      uLong crc = crc32(0L, Z_NULL, 0);
      while (in) {
        in.read(buf.data(), std::streamsize(buf.size()));
        crc = crc32(crc, reinterpret_cast<const Bytef*>(buf.data()), uInt(in.gcount()));
      }
      std::string local;
      put32(local, 0x04034b50u);
      put16(local, 10);        // version needed: 1.0
      put16(local, 1u << 11);  // names are UTF-8
      put16(local, 0);         // stored
      put16(local, time);
      put16(local, date);
      put32(local, uint32_t(crc));
      put32(local, uint32_t(size));
      put32(local, uint32_t(size));
      put16(local, uint32_t(name.size()));
      put16(local, 0);
      local += name;
      out.write(local.data(), std::streamsize(local.size()));
      in.clear();
      in.seekg(0);
      uint64_t copied = 0;
      while (in) {
        in.read(buf.data(), std::streamsize(buf.size()));
        out.write(buf.data(), in.gcount());
        copied += uint64_t(in.gcount());
      }
      if (copied != size) throw Error("zip: " + file + " changed while being archived");
      put32(central, 0x02014b50u);
      put16(central, (3u << 8) | 20);  // made by: Unix, 2.0
      put16(central, 10);
      put16(central, 1u << 11);
      put16(central, 0);
      put16(central, time);
      put16(central, date);
      put32(central, uint32_t(crc));
      put32(central, uint32_t(size));
      put32(central, uint32_t(size));
      put16(central, uint32_t(name.size()));
      put16(central, 0);               // extra
      put16(central, 0);               // comment
      put16(central, 0);               // disk
      put16(central, 0);               // internal attributes
      put32(central, 0100644u << 16);  // external: a regular file, rw-r--r--
      put32(central, uint32_t(offset));
      central += name;
      offset += local.size() + size;
    }
    if (entries.size() > 0xffff || offset + central.size() >= 0xffffffffull)
      throw Error("zip: too many or too large entries for a zip without zip64");
    std::string end;
    put32(end, 0x06054b50u);
    put16(end, 0);
    put16(end, 0);
    put16(end, uint32_t(entries.size()));
    put16(end, uint32_t(entries.size()));
    put32(end, uint32_t(central.size()));
    put32(end, uint32_t(offset));
    put16(end, 0);
    out.write(central.data(), std::streamsize(central.size()));
    out.write(end.data(), std::streamsize(end.size()));
    out.close();
    if (!out) throw Error("zip: cannot write " + tmp);
  });
}

void write_zip_of_folder(const std::string& path, const std::string& folder,
                         const std::string& prefix) {
  std::vector<std::pair<std::string, std::string>> entries;
  for (const auto& e : fs::recursive_directory_iterator(folder))
    if (e.is_regular_file())
      entries.push_back(
          {prefix + e.path().lexically_relative(folder).generic_string(), e.path().string()});
  std::sort(entries.begin(), entries.end());
  write_zip(path, entries);
}

}  // namespace ks

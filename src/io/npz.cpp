#include "io/npz.hpp"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <sstream>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {

namespace {

uint16_t rd16(const uint8_t* p) {
  return uint16_t(p[0] | (p[1] << 8));
}
uint32_t rd32(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
void wr16(std::vector<uint8_t>& b, uint32_t v) {
  b.push_back(uint8_t(v & 0xff));
  b.push_back(uint8_t((v >> 8) & 0xff));
}
void wr32(std::vector<uint8_t>& b, uint32_t v) {
  wr16(b, v & 0xffff);
  wr16(b, v >> 16);
}

// Finds the value text after 'key': in a Python dict literal header.
std::string header_value(const std::string& h, const std::string& key, const std::string& what) {
  const std::string k1 = "'" + key + "'", k2 = "\"" + key + "\"";
  size_t p = h.find(k1);
  size_t klen = k1.size();
  if (p == std::string::npos) {
    p = h.find(k2);
    klen = k2.size();
  }
  if (p == std::string::npos) throw Error(what + ": .npy header lacks '" + key + "'");
  p = h.find(':', p + klen);
  if (p == std::string::npos) throw Error(what + ": malformed .npy header");
  ++p;
  while (p < h.size() && h[p] == ' ') ++p;
  if (p >= h.size()) throw Error(what + ": malformed .npy header");
  size_t e;
  if (h[p] == '\'' || h[p] == '"') {
    e = h.find(h[p], p + 1);
    if (e == std::string::npos) throw Error(what + ": malformed .npy header");
    return h.substr(p + 1, e - p - 1);
  }
  if (h[p] == '(') {
    e = h.find(')', p);
    if (e == std::string::npos) throw Error(what + ": malformed .npy header");
    return h.substr(p, e - p + 1);
  }
  e = p;
  while (e < h.size() && h[e] != ',' && h[e] != '}') ++e;
  return h.substr(p, e - p);
}

std::vector<int64_t> parse_shape(const std::string& s, const std::string& what) {
  std::vector<int64_t> shape;
  if (s.empty() || s[0] != '(') throw Error(what + ": malformed shape " + s + " in .npy header");
  size_t i = 1;  // skip '('
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == ',' || s[i] == ')')) ++i;
    if (i >= s.size()) break;
    if (s[i] == 'L') {
      ++i;
      continue;
    }
    if (!std::isdigit(static_cast<unsigned char>(s[i])))
      throw Error(what + ": malformed shape " + s + " in .npy header");
    int64_t v = 0;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) {
      v = v * 10 + (s[i] - '0');
      if (v > (int64_t(1) << 40)) throw Error(what + ": absurd shape " + s + " in .npy header");
      ++i;
    }
    shape.push_back(v);
  }
  return shape;
}

void byteswap(std::vector<uint8_t>& d, int itemsize) {
  if (itemsize <= 1) return;
  for (size_t i = 0; i + itemsize <= d.size(); i += itemsize)
    std::reverse(d.begin() + i, d.begin() + i + itemsize);
}

// Transposes Fortran-order element data into C order.
std::vector<uint8_t> fortran_to_c(const std::vector<uint8_t>& d, const std::vector<int64_t>& shape,
                                  int itemsize) {
  const size_t nd = shape.size();
  if (nd < 2) return d;
  int64_t n = 1;
  for (auto s : shape) n *= s;
  std::vector<uint8_t> out(d.size());
  std::vector<int64_t> idx(nd, 0);
  // Fortran strides.
  std::vector<int64_t> fstride(nd, 1);
  for (size_t k = 1; k < nd; ++k) fstride[k] = fstride[k - 1] * shape[k - 1];
  for (int64_t c = 0; c < n; ++c) {
    int64_t f = 0;
    for (size_t k = 0; k < nd; ++k) f += idx[k] * fstride[k];
    std::memcpy(&out[size_t(c) * itemsize], &d[size_t(f) * itemsize], itemsize);
    for (size_t k = nd; k-- > 0;) {
      if (++idx[k] < shape[k]) break;
      idx[k] = 0;
    }
  }
  return out;
}

std::vector<uint8_t> inflate_raw(const uint8_t* src, size_t n, size_t out_size,
                                 const std::string& what) {
  std::vector<uint8_t> out(out_size);
  z_stream zs{};
  if (inflateInit2(&zs, -MAX_WBITS) != Z_OK) throw Error(what + ": zlib init failed");
  zs.next_in = const_cast<Bytef*>(src);
  zs.avail_in = uInt(n);
  zs.next_out = out.data();
  zs.avail_out = uInt(out_size);
  const int rc = inflate(&zs, Z_FINISH);
  const size_t produced = zs.total_out;
  inflateEnd(&zs);
  if (rc != Z_STREAM_END || produced != out_size)
    throw Error(what + ": corrupt deflate data (" + (zs.msg ? zs.msg : "size mismatch") + ")");
  return out;
}

// Raw deflate of the concatenation of two buffers (an .npy header and its data, never copied).
std::vector<uint8_t> deflate_raw(const uint8_t* a, size_t na, const uint8_t* b, size_t nb) {
  z_stream zs{};
  if (deflateInit2(&zs, 6, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw Error("zlib deflate init failed");
  std::vector<uint8_t> out(deflateBound(&zs, uLong(na + nb)));
  zs.next_out = out.data();
  zs.avail_out = uInt(out.size());
  zs.next_in = const_cast<Bytef*>(a);
  zs.avail_in = uInt(na);
  int rc = deflate(&zs, Z_NO_FLUSH);
  if (rc == Z_OK) {
    zs.next_in = const_cast<Bytef*>(b);
    zs.avail_in = uInt(nb);
    rc = deflate(&zs, Z_FINISH);
  }
  const size_t produced = zs.total_out;
  deflateEnd(&zs);
  if (rc != Z_STREAM_END) throw Error("zlib deflate failed");
  out.resize(produced);
  return out;
}

}  // namespace

int64_t NpyArray::size() const {
  int64_t n = 1;
  for (auto s : shape) n *= s;
  return n;
}

std::string NpyArray::descr() const {
  std::string s = (itemsize == 1) ? "|" : "<";
  s += kind;
  s += std::to_string(itemsize);
  return s;
}

std::string NpyArray::shape_string() const {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(shape[i]);
  }
  if (shape.size() == 1) s += ",";
  return s + ")";
}

double NpyArray::as_double(int64_t i) const {
  const uint8_t* p = data.data() + size_t(i) * itemsize;
  switch (kind) {
    case 'f':
      if (itemsize == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      } else {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    default:
      return double(as_int(i));
  }
}

int64_t NpyArray::as_int(int64_t i) const {
  const uint8_t* p = data.data() + size_t(i) * itemsize;
  if (kind == 'f') return int64_t(as_double(i));
  if (kind == 'b') return p[0] ? 1 : 0;
  const bool sgn = kind == 'i';
  switch (itemsize) {
    case 1:
      return sgn ? int64_t(int8_t(p[0])) : int64_t(p[0]);
    case 2: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return sgn ? int64_t(int16_t(v)) : int64_t(v);
    }
    case 4: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return sgn ? int64_t(int32_t(v)) : int64_t(v);
    }
    default: {
      uint64_t v;
      std::memcpy(&v, p, 8);
      return int64_t(v);  // uint64 above 2^63 wraps; indices never get there
    }
  }
}

NpyArray NpyArray::from_doubles(const std::vector<int64_t>& shape, const double* values,
                                bool as_float32) {
  NpyArray a;
  a.kind = 'f';
  a.itemsize = as_float32 ? 4 : 8;
  a.shape = shape;
  const int64_t n = a.size();
  a.data.resize(size_t(n) * a.itemsize);
  for (int64_t i = 0; i < n; ++i) {
    if (as_float32) {
      const float f = float(values[i]);
      std::memcpy(&a.data[size_t(i) * 4], &f, 4);
    } else {
      std::memcpy(&a.data[size_t(i) * 8], &values[i], 8);
    }
  }
  return a;
}

NpyArray NpyArray::from_ints(const std::vector<int64_t>& shape, const int64_t* values, char kind,
                             int itemsize) {
  if (kind != 'i' && kind != 'u') throw Error("NpyArray::from_ints: kind must be 'i' or 'u'");
  if (itemsize != 1 && itemsize != 2 && itemsize != 4 && itemsize != 8)
    throw Error("NpyArray::from_ints: bad itemsize");
  NpyArray a;
  a.kind = kind;
  a.itemsize = itemsize;
  a.shape = shape;
  const int64_t n = a.size();
  a.data.resize(size_t(n) * itemsize);
  for (int64_t i = 0; i < n; ++i) {
    const uint64_t v = uint64_t(values[i]);
    for (int b = 0; b < itemsize; ++b) a.data[size_t(i) * itemsize + b] = uint8_t(v >> (8 * b));
  }
  return a;
}

NpyArray NpyArray::from_matrix(const Eigen::MatrixXd& m, bool as_float32) {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> r = m;
  return from_doubles({int64_t(m.rows()), int64_t(m.cols())}, r.data(), as_float32);
}

NpyArray NpyArray::from_matrix(const Eigen::MatrixXi& m, char kind, int itemsize) {
  std::vector<int64_t> v(size_t(m.size()));
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j) v[size_t(i * m.cols() + j)] = m(i, j);
  return from_ints({int64_t(m.rows()), int64_t(m.cols())}, v.data(), kind, itemsize);
}

bool parse_npy(const uint8_t* data, size_t size, const std::string& what, NpyArray& out,
               std::string* unsupported_descr) {
  static const uint8_t magic[6] = {0x93, 'N', 'U', 'M', 'P', 'Y'};
  if (size < 10 || std::memcmp(data, magic, 6) != 0)
    throw Error(what + ": not a .npy array (bad magic)");
  const int major = data[6];
  size_t hlen, hstart;
  if (major == 1) {
    hlen = rd16(data + 8);
    hstart = 10;
  } else if (major == 2 || major == 3) {
    if (size < 12) throw Error(what + ": truncated .npy header");
    hlen = rd32(data + 8);
    hstart = 12;
  } else {
    throw Error(what + ": unsupported .npy version " + std::to_string(major));
  }
  if (hstart + hlen > size) throw Error(what + ": truncated .npy header");
  const std::string h(reinterpret_cast<const char*>(data + hstart), hlen);
  const std::string descr = header_value(h, "descr", what);
  const std::string fo = header_value(h, "fortran_order", what);
  const std::vector<int64_t> shape = parse_shape(header_value(h, "shape", what), what);
  if (descr.size() < 2) throw Error(what + ": malformed dtype '" + descr + "'");
  char order = descr[0];
  std::string rest = descr;
  if (order == '<' || order == '>' || order == '|' || order == '=') {
    rest = descr.substr(1);
  } else {
    order = '=';
  }
  const char kind = rest[0];
  if (kind == 'O') return false;  // pickled objects: skipped
  int itemsize = 0;
  try {
    itemsize = std::stoi(rest.substr(1));
  } catch (...) {
    itemsize = 0;
  }
  const bool ok_kind = (kind == 'f' && (itemsize == 4 || itemsize == 8)) ||
                       ((kind == 'i' || kind == 'u') &&
                        (itemsize == 1 || itemsize == 2 || itemsize == 4 || itemsize == 8)) ||
                       (kind == 'b' && itemsize == 1);
  if (!ok_kind) {
    if (unsupported_descr) {
      *unsupported_descr = descr;
      return false;
    }
    throw Error(what + ": unsupported dtype '" + descr + "'");
  }
  // The element count, checked against the bytes present before anything is multiplied out (a
  // header may claim (2**40, 2**40, ...) elements).
  const size_t dstart = hstart + hlen;
  const size_t avail = size - dstart;
  size_t count = 1;
  bool empty = false;
  for (const int64_t s : shape) empty = empty || s == 0;
  for (const int64_t s : shape) {
    if (empty) break;
    if (size_t(s) > avail / size_t(itemsize) / count)
      throw Error(what + ": truncated .npy data (shape " + header_value(h, "shape", what) +
                  " needs more than the " + std::to_string(avail) + " bytes present)");
    count *= size_t(s);
  }
  out = NpyArray{};
  out.kind = kind;
  out.itemsize = itemsize;
  out.shape = shape;
  const size_t nbytes = (empty ? 0 : count) * size_t(itemsize);
  if (avail < nbytes)
    throw Error(what + ": truncated .npy data (" + std::to_string(size - dstart) + " of " +
                std::to_string(nbytes) + " bytes)");
  out.data.assign(data + dstart, data + dstart + nbytes);
  if (order == '>') byteswap(out.data, itemsize);
  if (fo.find("True") != std::string::npos) out.data = fortran_to_c(out.data, shape, itemsize);
  return true;
}

namespace {
std::vector<uint8_t> npy_header(const NpyArray& a) {
  std::string h =
      "{'descr': '" + a.descr() + "', 'fortran_order': False, 'shape': " + a.shape_string() + ", }";
  // Pad so that magic(6)+version(2)+len(2)+header is a multiple of 64, ending in '\n'.
  size_t total = 10 + h.size() + 1;
  const size_t pad = (64 - total % 64) % 64;
  h.append(pad, ' ');
  h.push_back('\n');
  std::vector<uint8_t> b = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0};
  wr16(b, uint32_t(h.size()));
  b.insert(b.end(), h.begin(), h.end());
  return b;
}
}  // namespace

std::vector<uint8_t> serialize_npy(const NpyArray& a) {
  std::vector<uint8_t> b = npy_header(a);
  b.insert(b.end(), a.data.begin(), a.data.end());
  return b;
}

NpzFile read_npz_bytes(const std::vector<uint8_t>& bytes, const std::string& what) {
  const size_t n = bytes.size();
  const uint8_t* d = bytes.data();
  if (n >= 2 && d[0] == 0x80 && d[1] <= 5)
    throw Error(what + ": this is a Python pickle, not an .npz archive");
  if (n < 4 || rd32(d) != 0x04034b50u) {
    if (n >= 6 && std::memcmp(d, "\x93NUMPY", 6) == 0)
      throw Error(what + ": this is a single .npy array, not an .npz archive");
    if (n == 0) throw Error(what + ": empty file, not an .npz archive");
    throw Error(what + ": not an .npz archive (no zip signature)");
  }
  // End of central directory: scan backwards (the comment may be up to 64 KiB).
  if (n < 22) throw Error(what + ": truncated zip archive (no end of central directory)");
  size_t eocd = std::string::npos;
  const size_t lo = n > 22 + 65535 ? n - 22 - 65535 : 0;
  for (size_t p = n - 22 + 1; p-- > lo;) {
    if (rd32(d + p) == 0x06054b50u) {
      eocd = p;
      break;
    }
  }
  if (eocd == std::string::npos)
    throw Error(what + ": truncated or corrupt zip archive (no end of central directory)");
  const uint32_t count = rd16(d + eocd + 10);
  const uint32_t cd_size = rd32(d + eocd + 12);
  const uint32_t cd_off = rd32(d + eocd + 16);
  if (count == 0xffff || cd_size == 0xffffffffu || cd_off == 0xffffffffu)
    throw Error(what + ": zip64 archives are not supported (re-save with numpy.savez)");
  if (size_t(cd_off) + cd_size > eocd)
    throw Error(what + ": truncated or corrupt zip archive (central directory out of range)");
  NpzFile out;
  size_t p = cd_off;
  for (uint32_t e = 0; e < count; ++e) {
    if (p + 46 > eocd || rd32(d + p) != 0x02014b50u)
      throw Error(what + ": corrupt zip central directory");
    const uint16_t flags = rd16(d + p + 8);
    const uint16_t method = rd16(d + p + 10);
    const uint32_t crc = rd32(d + p + 16);
    const uint32_t csize = rd32(d + p + 20);
    const uint32_t usize = rd32(d + p + 24);
    const uint16_t nlen = rd16(d + p + 28), xlen = rd16(d + p + 30), clen = rd16(d + p + 32);
    const uint32_t loff = rd32(d + p + 42);
    if (p + 46 + nlen + xlen + clen > eocd) throw Error(what + ": corrupt zip central directory");
    std::string name(reinterpret_cast<const char*>(d + p + 46), nlen);
    p += 46 + size_t(nlen) + xlen + clen;
    if (csize == 0xffffffffu || usize == 0xffffffffu || loff == 0xffffffffu)
      throw Error(what + ": entry '" + name + "' uses zip64, which is not supported");
    if (flags & 1) throw Error(what + ": entry '" + name + "' is encrypted");
    if (size_t(loff) + 30 > n || rd32(d + loff) != 0x04034b50u)
      throw Error(what + ": truncated or corrupt zip archive (bad local header for '" + name +
                  "')");
    const size_t dstart = size_t(loff) + 30 + rd16(d + loff + 26) + rd16(d + loff + 28);
    if (dstart + csize > n)
      throw Error(what + ": truncated zip archive (entry '" + name + "' runs past the end)");
    std::vector<uint8_t> raw;
    if (method == 0) {
      if (csize != usize) throw Error(what + ": corrupt stored entry '" + name + "'");
      raw.assign(d + dstart, d + dstart + csize);
    } else if (method == 8) {
      // Deflate expands at most about 1032:1: a larger claim is a corrupt (or hostile) header, and
      // the buffer for it is never allocated.
      if (uint64_t(usize) > uint64_t(csize) * 1032 + 1024)
        throw Error(what + ": corrupt zip entry '" + name + "' (claims " + std::to_string(usize) +
                    " bytes uncompressed from " + std::to_string(csize) + ")");
      raw = inflate_raw(d + dstart, csize, usize, what + " entry '" + name + "'");
    } else {
      throw Error(what + ": entry '" + name + "' uses zip compression method " +
                  std::to_string(method) + " (only stored and deflated are supported)");
    }
    if (uint32_t(crc32(0L, raw.data(), uInt(raw.size()))) != crc)
      throw Error(what + ": CRC mismatch in entry '" + name + "' (corrupt file)");
    std::string key = name;
    if (key.size() > 4 && key.compare(key.size() - 4, 4, ".npy") == 0)
      key = key.substr(0, key.size() - 4);
    NpyArray arr;
    std::string bad;
    if (parse_npy(raw.data(), raw.size(), what + " array '" + key + "'", arr, &bad)) {
      out.arrays[key] = std::move(arr);
    } else {
      out.skipped.push_back(key);
    }
  }
  return out;
}

NpzFile read_npz(const std::string& path) {
  return read_npz_bytes(read_file_bytes(path), path);
}

std::vector<uint8_t> npz_bytes(const std::map<std::string, NpyArray>& arrays, bool compress) {
  std::vector<uint8_t> out, cd;
  uint32_t count = 0;
  for (const auto& [key, arr] : arrays) {
    const std::vector<uint8_t> header = npy_header(arr);
    const size_t raw_size = header.size() + arr.data.size();
    const std::string name = key + ".npy";
    uint32_t crc = uint32_t(crc32(0L, header.data(), uInt(header.size())));
    // (zlib's crc32 returns the initial value for a null buffer: skip empty data.)
    if (!arr.data.empty()) crc = uint32_t(crc32(crc, arr.data.data(), uInt(arr.data.size())));
    std::vector<uint8_t> comp;
    uint16_t method = 0;
    if (compress) {
      comp = deflate_raw(header.data(), header.size(), arr.data.data(), arr.data.size());
      method = 8;
    }
    const size_t payload_size = compress ? comp.size() : raw_size;
    if (raw_size >= 0xffffffffu || out.size() + payload_size >= 0xffffffffu)
      throw Error("npz writer: array '" + key + "' too large (zip64 is not supported)");
    const uint32_t off = uint32_t(out.size());
    // Local header.
    wr32(out, 0x04034b50u);
    wr16(out, 20);
    wr16(out, 0);
    wr16(out, method);
    wr16(out, 0);     // time
    wr16(out, 0x21);  // date 1980-01-01
    wr32(out, crc);
    wr32(out, uint32_t(payload_size));
    wr32(out, uint32_t(raw_size));
    wr16(out, uint32_t(name.size()));
    wr16(out, 0);
    out.insert(out.end(), name.begin(), name.end());
    if (compress) {
      out.insert(out.end(), comp.begin(), comp.end());
    } else {
      out.insert(out.end(), header.begin(), header.end());
      out.insert(out.end(), arr.data.begin(), arr.data.end());
    }
    // Central directory record.
    wr32(cd, 0x02014b50u);
    wr16(cd, 20);
    wr16(cd, 20);
    wr16(cd, 0);
    wr16(cd, method);
    wr16(cd, 0);
    wr16(cd, 0x21);
    wr32(cd, crc);
    wr32(cd, uint32_t(payload_size));
    wr32(cd, uint32_t(raw_size));
    wr16(cd, uint32_t(name.size()));
    wr16(cd, 0);
    wr16(cd, 0);
    wr16(cd, 0);
    wr16(cd, 0);
    wr32(cd, 0);
    wr32(cd, off);
    cd.insert(cd.end(), name.begin(), name.end());
    ++count;
  }
  if (count >= 0xffff) throw Error("npz writer: too many arrays");
  const uint32_t cd_off = uint32_t(out.size());
  out.insert(out.end(), cd.begin(), cd.end());
  wr32(out, 0x06054b50u);
  wr16(out, 0);
  wr16(out, 0);
  wr16(out, count);
  wr16(out, count);
  wr32(out, uint32_t(cd.size()));
  wr32(out, cd_off);
  wr16(out, 0);
  return out;
}

void write_npz(const std::string& path, const std::map<std::string, NpyArray>& arrays,
               bool compress) {
  const std::vector<uint8_t> b = npz_bytes(arrays, compress);
  write_file_atomic(path, b.data(), b.size());
}

}  // namespace ks

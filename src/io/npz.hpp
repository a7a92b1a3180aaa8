#pragma once
// NumPy .npy arrays and .npz archives (a zip of .npy files, stored or deflated), read and written
// with our own small zip reader/writer (zlib for deflate). Zip64 archives are refused clearly.
#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace ks {

// One array, always held little-endian in C (row-major) order.
struct NpyArray {
  char kind = 'f';   // 'f' float, 'i' signed int, 'u' unsigned int, 'b' bool
  int itemsize = 8;  // bytes per element
  std::vector<int64_t> shape;
  std::vector<uint8_t> data;

  int64_t size() const;
  std::string descr() const;         // e.g. "<f8"
  std::string shape_string() const;  // e.g. "(6890, 3)"
  // Element i (flat, C order) converted to double / int64.
  double as_double(int64_t i) const;
  int64_t as_int(int64_t i) const;
  bool is_float() const { return kind == 'f'; }
  bool is_integer() const { return kind == 'i' || kind == 'u' || kind == 'b'; }

  // Builders. `shape` must match the element count.
  static NpyArray from_doubles(const std::vector<int64_t>& shape, const double* values,
                               bool as_float32 = false);
  static NpyArray from_ints(const std::vector<int64_t>& shape, const int64_t* values,
                            char kind = 'i', int itemsize = 4);
  // A 2-D matrix (rows x cols, row-major on disk).
  static NpyArray from_matrix(const Eigen::MatrixXd& m, bool as_float32 = false);
  static NpyArray from_matrix(const Eigen::MatrixXi& m, char kind = 'i', int itemsize = 4);
};

// Parsed archive: name (without ".npy") -> array. Entries of object dtype ('|O', pickled) and
// other unsupported dtypes are skipped and their names listed in `skipped`.
struct NpzFile {
  std::map<std::string, NpyArray> arrays;
  std::vector<std::string> skipped;
  bool has(const std::string& name) const { return arrays.count(name) != 0; }
};

// Parses one .npy blob. `what` names it in error messages. Throws ks::Error for unsupported
// dtypes except object arrays, for which it returns false (nothing parsed).
bool parse_npy(const uint8_t* data, size_t size, const std::string& what, NpyArray& out,
               std::string* unsupported_descr = nullptr);
std::vector<uint8_t> serialize_npy(const NpyArray& a);

NpzFile read_npz(const std::string& path);
NpzFile read_npz_bytes(const std::vector<uint8_t>& bytes, const std::string& what);
// Writes atomically. `compress` = deflate (np.savez_compressed), else stored (np.savez).
void write_npz(const std::string& path, const std::map<std::string, NpyArray>& arrays,
               bool compress = true);
std::vector<uint8_t> npz_bytes(const std::map<std::string, NpyArray>& arrays, bool compress);

}  // namespace ks

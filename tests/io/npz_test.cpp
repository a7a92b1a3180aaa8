#include "io/npz.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace ks {
namespace {

namespace fs = std::filesystem;

std::string tmp(const std::string& n) {
  return (fs::temp_directory_path() / ("ks_npz_test_" + std::to_string(::getpid()) + "_" + n))
      .string();
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::map<std::string, NpyArray> sample_arrays() {
  std::map<std::string, NpyArray> a;
  std::vector<double> d(2 * 3 * 4);
  for (size_t i = 0; i < d.size(); ++i) d[i] = 0.5 * double(i) - 3.25;
  a["f64"] = NpyArray::from_doubles({2, 3, 4}, d.data());
  a["f32"] = NpyArray::from_doubles({4, 6}, d.data(), true);
  std::vector<int64_t> ints = {-1, 0, 7, 4294967295LL, 123456789012LL, 5};
  a["i64"] = NpyArray::from_ints({6}, ints.data(), 'i', 8);
  std::vector<int64_t> u = {4294967295LL, 0, 1};
  a["u32"] = NpyArray::from_ints({3}, u.data(), 'u', 4);
  const int64_t one = 42;
  a["scalar"] = NpyArray::from_ints({}, &one, 'i', 4);
  a["empty"] = NpyArray::from_doubles({0, 3}, nullptr);
  return a;
}

TEST(Npz, RoundTripStoredAndDeflated) {
  const auto a = sample_arrays();
  for (bool compress : {false, true}) {
    const std::string p = tmp(compress ? "c.npz" : "s.npz");
    write_npz(p, a, compress);
    const NpzFile z = read_npz(p);
    fs::remove(p);
    ASSERT_EQ(z.arrays.size(), a.size());
    EXPECT_TRUE(z.skipped.empty());
    for (const auto& [k, arr] : a) {
      ASSERT_TRUE(z.has(k)) << k;
      const NpyArray& b = z.arrays.at(k);
      EXPECT_EQ(b.kind, arr.kind) << k;
      EXPECT_EQ(b.itemsize, arr.itemsize) << k;
      EXPECT_EQ(b.shape, arr.shape) << k;
      EXPECT_EQ(b.data, arr.data) << k;
    }
    const NpyArray& f = z.arrays.at("f64");
    EXPECT_DOUBLE_EQ(f.as_double(5), 0.5 * 5 - 3.25);
    EXPECT_EQ(z.arrays.at("i64").as_int(0), -1);
    EXPECT_EQ(z.arrays.at("i64").as_int(4), 123456789012LL);
    EXPECT_EQ(z.arrays.at("u32").as_int(0), 4294967295LL);
    EXPECT_EQ(z.arrays.at("scalar").size(), 1);
    EXPECT_EQ(z.arrays.at("scalar").as_int(0), 42);
    EXPECT_EQ(z.arrays.at("f32").descr(), "<f4");
  }
}

// A .npy written by hand the way NumPy writes Fortran-order and big-endian arrays.
std::vector<uint8_t> handmade_npy(const std::string& header, const std::vector<uint8_t>& data) {
  std::string h = header;
  while ((10 + h.size() + 1) % 64) h.push_back(' ');
  h.push_back('\n');
  std::string b = "\x93NUMPY";
  b.push_back(char(1));
  b.push_back(char(0));
  b.push_back(char(h.size() & 0xff));
  b.push_back(char(h.size() >> 8));
  b += h;
  for (uint8_t c : data) b.push_back(char(c));
  return std::vector<uint8_t>(b.begin(), b.end());
}

TEST(Npz, FortranOrderAndBigEndian) {
  // 2 x 3 int16 in Fortran order: memory holds columns [1 4] [2 5] [3 6].
  std::vector<uint8_t> d;
  for (int v : {1, 4, 2, 5, 3, 6}) d.push_back(uint8_t(v)), d.push_back(0);
  NpyArray a;
  const auto fo = handmade_npy("{'descr': '<i2', 'fortran_order': True, 'shape': (2, 3), }", d);
  ASSERT_TRUE(parse_npy(fo.data(), fo.size(), "f", a));
  for (int i = 0; i < 6; ++i) EXPECT_EQ(a.as_int(i), i + 1);
  // Big-endian float64 1.5.
  std::vector<uint8_t> be = {0x3f, 0xf8, 0, 0, 0, 0, 0, 0};
  const auto blob = handmade_npy("{'descr': '>f8', 'fortran_order': False, 'shape': (1,), }", be);
  ASSERT_TRUE(parse_npy(blob.data(), blob.size(), "be", a));
  EXPECT_DOUBLE_EQ(a.as_double(0), 1.5);
  // Object arrays are reported as skipped (false), unknown dtypes throw.
  const auto obj = handmade_npy("{'descr': '|O', 'fortran_order': False, 'shape': (), }", {0x80});
  EXPECT_FALSE(parse_npy(obj.data(), obj.size(), "obj", a));
  const auto cplx = handmade_npy("{'descr': '<c16', 'fortran_order': False, 'shape': (1,), }",
                                 std::vector<uint8_t>(16, 0));
  EXPECT_NE(
      error_of([&] { parse_npy(cplx.data(), cplx.size(), "c", a); }).find("unsupported dtype"),
      std::string::npos);
  // Truncated data.
  const auto shortblob =
      handmade_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (4,), }", be);
  EXPECT_NE(
      error_of([&] { parse_npy(shortblob.data(), shortblob.size(), "t", a); }).find("truncated"),
      std::string::npos);
}

TEST(Npz, MalformedArchives) {
  const auto bytes = npz_bytes(sample_arrays(), true);
  // Truncations anywhere give a clear error, never a crash.
  for (size_t keep = 0; keep < bytes.size(); keep += 37) {
    std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + Eigen::Index(keep));
    EXPECT_THROW(read_npz_bytes(cut, "cut.npz"), Error) << keep;
  }
  // A flipped payload byte fails the CRC or the inflater.
  std::vector<uint8_t> bad = bytes;
  bad[60] ^= 0x55;
  EXPECT_THROW(read_npz_bytes(bad, "bad.npz"), Error);
  // Not a zip at all.
  const std::string text = "just some text";
  EXPECT_NE(error_of([&] {
              read_npz_bytes({text.begin(), text.end()}, "t.npz");
            }).find("not an .npz archive"),
            std::string::npos);
  // Zip64 end record markers are refused clearly.
  std::vector<uint8_t> z64 = npz_bytes(sample_arrays(), false);
  const size_t eocd = z64.size() - 22;
  z64[eocd + 10] = 0xff;
  z64[eocd + 11] = 0xff;
  EXPECT_NE(error_of([&] { read_npz_bytes(z64, "z64.npz"); }).find("zip64"), std::string::npos);
}

}  // namespace
}  // namespace ks

#include "gaussians/ply.hpp"

#include <cmath>
#include <cstring>
#include <sstream>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {
namespace {

std::vector<std::string> standard_names(int rest) {
  std::vector<std::string> n = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
  for (int i = 0; i < rest; ++i) n.push_back("f_rest_" + std::to_string(i));
  for (const char* s :
       {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"})
    n.push_back(s);
  return n;
}

}  // namespace

Gaussians read_ply(const std::string& path, PlyExtra* extra) {
  const std::vector<uint8_t> bytes = read_file_bytes(path);
  auto fail = [&](const std::string& what) -> Error { return Error(path + ": " + what); };
  // Header: text lines up to "end_header\n".
  size_t pos = 0;
  auto next_line = [&](std::string& line) -> bool {
    if (pos >= bytes.size()) return false;
    size_t e = pos;
    while (e < bytes.size() && bytes[e] != '\n') ++e;
    if (e >= bytes.size()) return false;
    line.assign(reinterpret_cast<const char*>(bytes.data()) + pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    pos = e + 1;
    return true;
  };
  std::string line;
  if (!next_line(line) || line != "ply") throw fail("not a PLY file (missing 'ply' magic)");
  bool format_ok = false, in_vertex = false, seen_vertex = false, ended = false;
  long long count = -1;
  std::vector<std::string> props;
  while (next_line(line)) {
    std::istringstream ss(line);
    std::string kw;
    ss >> kw;
    if (kw == "end_header") {
      ended = true;
      break;
    }
    if (kw == "comment" || kw == "obj_info" || kw.empty()) continue;
    if (kw == "format") {
      std::string f, v;
      ss >> f >> v;
      if (f == "ascii") throw fail("ASCII PLY is not supported (need binary_little_endian)");
      if (f == "binary_big_endian")
        throw fail("big-endian PLY is not supported (need binary_little_endian)");
      if (f != "binary_little_endian") throw fail("unknown PLY format '" + f + "'");
      format_ok = true;
    } else if (kw == "element") {
      std::string name;
      long long n = -1;
      ss >> name >> n;
      if (in_vertex || seen_vertex) {
        in_vertex = false;  // elements after "vertex" are ignored
        continue;
      }
      if (name != "vertex")
        throw fail("expected the first element to be 'vertex', got '" + name + "'");
      if (ss.fail() || n < 0) throw fail("bad vertex count");
      count = n;
      in_vertex = seen_vertex = true;
    } else if (kw == "property") {
      if (!in_vertex) {
        if (!seen_vertex) throw fail("property before the vertex element");
        continue;
      }
      std::string type, name;
      ss >> type;
      if (type == "list") throw fail("list properties are not supported in the vertex element");
      ss >> name;
      if (type != "float" && type != "float32")
        throw fail("property '" + name + "' has type '" + type + "'; every property must be float");
      props.push_back(name);
    } else {
      throw fail("unexpected header line '" + line + "'");
    }
  }
  if (!ended) throw fail("PLY header has no end_header");
  if (!format_ok) throw fail("PLY header has no format line");
  if (!seen_vertex) throw fail("PLY file has no vertex element");
  int rest = 0;
  for (const auto& p : props)
    if (p.rfind("f_rest_", 0) == 0) ++rest;
  int degree = -1;
  for (int d = 0; d <= 3; ++d)
    if (rest == 3 * (sh_coeff_count(d) - 1)) degree = d;
  if (degree < 0)
    throw fail(std::to_string(rest) +
               " f_rest properties: expected 0, 9, 24 or 45 (SH degree 0-3)");
  const auto std_names = standard_names(rest);
  for (size_t i = 0; i < std_names.size(); ++i) {
    if (i >= props.size()) throw fail("missing property '" + std_names[i] + "'");
    if (props[i] != std_names[i])
      throw fail("expected property '" + std_names[i] + "' at position " + std::to_string(i) +
                 ", found '" + props[i] + "' (missing or out of order)");
  }
  const size_t P = props.size();
  // Checked by division: a header may claim billions of vertices (nothing is allocated for them).
  if (size_t(count) > (bytes.size() - pos) / (P * 4))
    throw fail("truncated data: " + std::to_string(count) + " vertices of " + std::to_string(P) +
               " floats need more than the " + std::to_string(bytes.size() - pos) +
               " bytes after the header");
  Gaussians g;
  g.sh_degree = degree;
  g.resize(size_t(count));
  const int K = g.coeffs();
  const size_t n_extra = P - std_names.size();
  if (extra) {
    extra->names.assign(props.begin() + std_names.size(), props.end());
    extra->values.resize(size_t(count) * n_extra);
  }
  std::vector<float> row(P);
  for (size_t i = 0; i < size_t(count); ++i) {
    std::memcpy(row.data(), bytes.data() + pos + i * P * 4, P * 4);
    const float* r = row.data();
    for (size_t k = 0; k < P; ++k)
      if (!std::isfinite(r[k]))
        throw fail("vertex " + std::to_string(i) + ": property '" + props[k] +
                   "' is not a finite number");
    for (int a = 0; a < 3; ++a) g.means[3 * i + a] = r[a];
    for (int c = 0; c < 3; ++c) g.sh[(i * K) * 3 + c] = r[6 + c];
    for (int c = 0; c < 3; ++c)
      for (int k = 1; k < K; ++k) g.sh[(i * K + k) * 3 + c] = r[9 + c * (K - 1) + (k - 1)];
    const size_t o = 9 + size_t(rest);
    g.opacity_logits[i] = r[o];
    for (int a = 0; a < 3; ++a) g.log_scales[3 * i + a] = r[o + 1 + a];
    for (int a = 0; a < 4; ++a) g.quats[4 * i + a] = r[o + 4 + a];
    if (extra)
      for (size_t e = 0; e < n_extra; ++e) extra->values[i * n_extra + e] = r[std_names.size() + e];
  }
  return g;
}

void write_ply(const std::string& path, const Gaussians& g, const PlyExtra* extra) {
  const size_t N = g.size();
  const int K = g.coeffs();
  const int rest = 3 * (K - 1);
  if (g.means.size() != 3 * N || g.sh.size() != N * K * 3 || g.log_scales.size() != 3 * N ||
      g.quats.size() != 4 * N)
    throw Error("write_ply " + path + ": inconsistent Gaussian array sizes");
  const size_t n_extra = extra ? extra->names.size() : 0;
  if (extra && extra->values.size() != N * n_extra)
    throw Error("write_ply " + path + ": extra property values do not match the Gaussian count");
  std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(N) + "\n";
  auto names = standard_names(rest);
  if (extra) names.insert(names.end(), extra->names.begin(), extra->names.end());
  for (const auto& n : names) header += "property float " + n + "\n";
  header += "end_header\n";
  const size_t P = names.size();
  std::vector<uint8_t> out(header.size() + N * P * 4);
  std::memcpy(out.data(), header.data(), header.size());
  std::vector<float> row(P);
  for (size_t i = 0; i < N; ++i) {
    float* r = row.data();
    for (int a = 0; a < 3; ++a) r[a] = g.means[3 * i + a], r[3 + a] = 0.f;
    for (int c = 0; c < 3; ++c) r[6 + c] = g.sh[(i * K) * 3 + c];
    for (int c = 0; c < 3; ++c)
      for (int k = 1; k < K; ++k) r[9 + c * (K - 1) + (k - 1)] = g.sh[(i * K + k) * 3 + c];
    const size_t o = 9 + size_t(rest);
    r[o] = g.opacity_logits[i];
    for (int a = 0; a < 3; ++a) r[o + 1 + a] = g.log_scales[3 * i + a];
    for (int a = 0; a < 4; ++a) r[o + 4 + a] = g.quats[4 * i + a];
    for (size_t e = 0; e < n_extra; ++e) r[o + 8 + e] = extra->values[i * n_extra + e];
    std::memcpy(out.data() + header.size() + i * P * 4, r, P * 4);
  }
  write_file_atomic(path, out.data(), out.size());
}

}  // namespace ks

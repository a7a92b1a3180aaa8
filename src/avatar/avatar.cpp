#include "avatar/avatar.hpp"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <map>
#include <utility>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {

static_assert(std::endian::native == std::endian::little,
              "the avatar file is little-endian; big-endian hosts need byte swapping");

namespace {

constexpr char kMagic[8] = {'K', 'S', 'A', 'V', 'A', 'T', 'A', 'R'};
constexpr size_t kAlign = 16;

size_t align_up(size_t x) {
  return (x + kAlign - 1) / kAlign * kAlign;
}

uint32_t crc_of(const void* data, size_t size) {
  uLong c = crc32(0L, Z_NULL, 0);
  const auto* p = static_cast<const Bytef*>(data);
  while (size > 0) {
    const uInt chunk = uInt(std::min<size_t>(size, 1u << 30));
    c = crc32(c, p, chunk);
    p += chunk;
    size -= chunk;
  }
  return uint32_t(c);
}

struct BlockWriter {
  std::vector<uint8_t> data;
  nlohmann::json blocks = nlohmann::json::object();

  void add(const std::string& name, const char* dtype, std::vector<int64_t> shape, const void* ptr,
           size_t bytes) {
    const size_t off = align_up(data.size());
    data.resize(off + bytes, 0);
    if (bytes) std::memcpy(data.data() + off, ptr, bytes);
    blocks[name] = {{"dtype", dtype},
                    {"shape", shape},
                    {"offset", off},
                    {"size", bytes},
                    {"crc32", crc_of(ptr, bytes)}};
  }
};

void check_finite(const std::vector<float>& v, const std::string& what, const char* name) {
  for (float x : v)
    if (!std::isfinite(x)) throw Error(what + ": non-finite value in " + name);
}

// A whole number of type T from the header (a float such as 1e30 or 2.5 is refused, not cast).
template <typename T>
T whole(const nlohmann::json& v, const std::string& what, const std::string& key) {
  bool ok = v.is_number_integer();
  if (ok && v.is_number_unsigned()) ok = std::in_range<T>(v.get<uint64_t>());
  if (ok && !v.is_number_unsigned()) ok = std::in_range<T>(v.get<int64_t>());
  if (!ok) throw Error(what + ": header value " + key + " must be a whole number in range");
  return v.is_number_unsigned() ? T(v.get<uint64_t>()) : T(v.get<int64_t>());
}

template <typename T>
std::vector<T> whole_array(const nlohmann::json& v, const std::string& what,
                           const std::string& key) {
  if (!v.is_array()) throw Error(what + ": header value " + key + " must be an array");
  std::vector<T> out;
  for (const auto& e : v) out.push_back(whole<T>(e, what, key));
  return out;
}

}  // namespace

void Avatar::validate(const std::string& what) const {
  const int J = num_joints();
  if (J < 1) throw Error(what + ": the skeleton has no joints");
  if (int(joint_names.size()) != J)
    throw Error(what + ": " + std::to_string(joint_names.size()) + " joint names for " +
                std::to_string(J) + " joints");
  if (parents[0] != -1) throw Error(what + ": the first joint must be the root (parent -1)");
  for (int j = 1; j < J; ++j)
    if (parents[j] < 0 || parents[j] >= j)
      throw Error(what + ": joint " + std::to_string(j) + " has parent " +
                  std::to_string(parents[j]) + " (parents must precede their children)");
  if (rest_joints.rows() != J || rest_joints.cols() != 3)
    throw Error(what + ": rest joints must be " + std::to_string(J) + " x 3");
  if (!rest_joints.allFinite()) throw Error(what + ": non-finite rest joints");
  if (template_vertices.rows() > 0 && template_vertices.cols() != 3)
    throw Error(what + ": template vertices must be N x 3");
  if (template_faces.rows() > 0) {
    if (template_faces.cols() != 3) throw Error(what + ": template faces must be F x 3");
    if (template_faces.minCoeff() < 0 || template_faces.maxCoeff() >= template_vertices.rows())
      throw Error(what + ": a template face index is out of range");
  }
  const size_t N = gaussians.size();
  const size_t K = size_t(gaussians.coeffs());
  if (gaussians.sh_degree < 0 || gaussians.sh_degree > 3)
    throw Error(what + ": SH degree must be 0..3");
  if (gaussians.means.size() != 3 * N || gaussians.log_scales.size() != 3 * N ||
      gaussians.quats.size() != 4 * N || gaussians.sh.size() != N * K * 3)
    throw Error(what + ": Gaussian attribute arrays have inconsistent sizes");
  if (anchors.size() != 3 * N) throw Error(what + ": anchors must have 3 values per Gaussian");
  if (skin_joints.size() != kAvatarSkinK * N || skin_weights.size() != kAvatarSkinK * N)
    throw Error(what + ": skin weights must have 4 entries per Gaussian");
  if (!part_labels.empty() && part_labels.size() != N)
    throw Error(what + ": part labels must have one entry per Gaussian");
  for (int32_t j : skin_joints)
    if (j < 0 || j >= J) throw Error(what + ": a skin joint index is out of range");
  for (size_t i = 0; i < N; ++i) {
    double s = 0;
    for (int k = 0; k < kAvatarSkinK; ++k) {
      const float w = skin_weights[i * kAvatarSkinK + k];
      if (!(w >= 0.f)) throw Error(what + ": negative or non-finite skin weight");
      s += w;
    }
    if (std::abs(s - 1.0) > 1e-3)
      throw Error(what + ": skin weights of Gaussian " + std::to_string(i) + " sum to " +
                  std::to_string(s) + ", not 1");
  }
  if (posedirs.size() > 0 &&
      (posedirs.rows() != Eigen::Index(3 * N) || posedirs.cols() != Eigen::Index(9 * (J - 1))))
    throw Error(what + ": posedirs must be (3N) x 9(J-1)");
  check_finite(gaussians.means, what, "means");
  check_finite(gaussians.log_scales, what, "log_scales");
  check_finite(gaussians.quats, what, "quats");
  check_finite(gaussians.opacity_logits, what, "opacity_logits");
  check_finite(gaussians.sh, what, "sh");
  check_finite(anchors, what, "anchors");
}

std::vector<uint8_t> serialize_avatar(const Avatar& a) {
  a.validate("save_avatar");
  const int64_t N = int64_t(a.gaussians.size());
  const int64_t K = a.gaussians.coeffs();
  BlockWriter w;
  // Eigen matrices are column-major: convert to row-major float/int buffers.
  std::vector<float> tv(size_t(a.template_vertices.rows()) * 3);
  for (Eigen::Index i = 0; i < a.template_vertices.rows(); ++i)
    for (int k = 0; k < 3; ++k) tv[size_t(i) * 3 + k] = float(a.template_vertices(i, k));
  std::vector<int32_t> tf(size_t(a.template_faces.rows()) * 3);
  for (Eigen::Index i = 0; i < a.template_faces.rows(); ++i)
    for (int k = 0; k < 3; ++k) tf[size_t(i) * 3 + k] = a.template_faces(i, k);
  const int64_t Nv = a.template_vertices.rows(), F = a.template_faces.rows();
  w.add("template_vertices", "f32", {Nv, 3}, tv.data(), tv.size() * 4);
  w.add("template_faces", "i32", {F, 3}, tf.data(), tf.size() * 4);
  const auto& g = a.gaussians;
  w.add("means", "f32", {N, 3}, g.means.data(), g.means.size() * 4);
  w.add("log_scales", "f32", {N, 3}, g.log_scales.data(), g.log_scales.size() * 4);
  w.add("quats", "f32", {N, 4}, g.quats.data(), g.quats.size() * 4);
  w.add("opacity_logits", "f32", {N}, g.opacity_logits.data(), g.opacity_logits.size() * 4);
  w.add("sh", "f32", {N, K, 3}, g.sh.data(), g.sh.size() * 4);
  w.add("anchors", "f32", {N, 3}, a.anchors.data(), a.anchors.size() * 4);
  w.add("skin_joints", "i32", {N, kAvatarSkinK}, a.skin_joints.data(), a.skin_joints.size() * 4);
  w.add("skin_weights", "f32", {N, kAvatarSkinK}, a.skin_weights.data(), a.skin_weights.size() * 4);
  if (!a.part_labels.empty())
    w.add("part_labels", "i32", {N}, a.part_labels.data(), a.part_labels.size() * 4);
  if (a.posedirs.size() > 0) {
    Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> pd = a.posedirs;
    w.add("posedirs", "f32", {int64_t(pd.rows()), int64_t(pd.cols())}, pd.data(),
          size_t(pd.size()) * 4);
  }

  nlohmann::json h;
  h["format"] = "kinesplat-avatar";
  h["version"] = {{"major", kAvatarVersionMajor}, {"minor", kAvatarVersionMinor}};
  h["counts"] = {{"gaussians", N},
                 {"template_vertices", Nv},
                 {"template_faces", F},
                 {"joints", a.num_joints()}};
  h["body_model"] = {{"kind", a.body_kind}, {"name", a.body_model}};
  h["betas"] = std::vector<double>(a.betas.data(), a.betas.data() + a.betas.size());
  nlohmann::json rj = nlohmann::json::array();
  for (int j = 0; j < a.num_joints(); ++j)
    rj.push_back({a.rest_joints(j, 0), a.rest_joints(j, 1), a.rest_joints(j, 2)});
  h["skeleton"] = {{"parents", a.parents}, {"joint_names", a.joint_names}, {"rest_joints", rj}};
  h["sh_degree"] = g.sh_degree;
  h["skin_k"] = kAvatarSkinK;
  h["pose_correctives"] = a.posedirs.size() > 0 ? "posedirs" : "none";
  h["byte_order"] = "little";
  h["blocks"] = w.blocks;
  h["metadata"] = a.metadata;
  const std::string header = h.dump();

  const uint32_t hl = uint32_t(header.size());
  const size_t data_start = align_up(12 + header.size());
  std::vector<uint8_t> out(data_start + w.data.size(), 0);
  std::memcpy(out.data(), kMagic, 8);
  for (int k = 0; k < 4; ++k) out[8 + k] = uint8_t(hl >> (8 * k));
  std::memcpy(out.data() + 12, header.data(), header.size());
  if (!w.data.empty()) std::memcpy(out.data() + data_start, w.data.data(), w.data.size());
  return out;
}

void save_avatar(const std::string& path, const Avatar& avatar) {
  const auto bytes = serialize_avatar(avatar);
  write_file_atomic(path, bytes.data(), bytes.size());
}

namespace {

struct BlockReader {
  const std::vector<uint8_t>& bytes;
  size_t data_start;
  const nlohmann::json& blocks;
  const std::string& what;

  bool has(const std::string& name) const { return blocks.contains(name); }

  template <typename T>
  std::vector<T> get(const std::string& name, const char* dtype,
                     const std::vector<int64_t>& expect_shape) const {
    if (!blocks.contains(name)) throw Error(what + ": missing data block \"" + name + "\"");
    const auto& b = blocks.at(name);
    std::string dt;
    std::vector<int64_t> shape;
    size_t off = 0, size = 0;
    uint32_t crc = 0;
    try {
      dt = b.at("dtype").get<std::string>();
      const std::string key = "blocks." + name;
      shape = whole_array<int64_t>(b.at("shape"), what, key + ".shape");
      off = whole<size_t>(b.at("offset"), what, key + ".offset");
      size = whole<size_t>(b.at("size"), what, key + ".size");
      crc = whole<uint32_t>(b.at("crc32"), what, key + ".crc32");
    } catch (const nlohmann::json::exception& e) {
      throw Error(what + ": malformed entry for block \"" + name + "\": " + e.what());
    }
    if (dt != dtype)
      throw Error(what + ": block \"" + name + "\" has dtype " + dt + ", expected " + dtype);
    if (!expect_shape.empty() && shape != expect_shape) {
      std::string s, e;
      for (auto x : shape) s += std::to_string(x) + " ";
      for (auto x : expect_shape) e += std::to_string(x) + " ";
      throw Error(what + ": block \"" + name + "\" has shape [ " + s + "], expected [ " + e + "]");
    }
    // The element count, checked against the file's size as it is multiplied out (a header may
    // claim billions of Gaussians: nothing is allocated for them).
    size_t count = 1;
    for (auto x : shape)
      if (x < 0) throw Error(what + ": block \"" + name + "\" has a negative dimension");
    for (auto x : shape) {
      if (x != 0 && count > bytes.size() / sizeof(T) / size_t(x))
        throw Error(what + ": file is truncated (block \"" + name +
                    "\" claims more data than the file holds)");
      count *= size_t(x);
    }
    if (size != count * sizeof(T))
      throw Error(what + ": block \"" + name + "\" byte size does not match its shape");
    if (data_start + off < data_start || data_start + off + size > bytes.size() ||
        data_start + off + size < data_start + off)
      throw Error(what + ": file is truncated (block \"" + name + "\" extends past the end)");
    const uint8_t* p = bytes.data() + data_start + off;
    if (crc_of(p, size) != crc)
      throw Error(what + ": block \"" + name + "\" is corrupted (CRC-32 mismatch)");
    std::vector<T> v(count);
    if (size) std::memcpy(v.data(), p, size);
    return v;
  }
};

}  // namespace

Avatar parse_avatar(const std::vector<uint8_t>& bytes, const std::string& what) {
  if (bytes.size() < 12 || std::memcmp(bytes.data(), kMagic, 8) != 0)
    throw Error(what + ": not a kinesplat avatar file (missing \"KSAVATAR\" magic)");
  const uint32_t hl = uint32_t(bytes[8]) | uint32_t(bytes[9]) << 8 | uint32_t(bytes[10]) << 16 |
                      uint32_t(bytes[11]) << 24;
  if (size_t(hl) > bytes.size() - 12)
    throw Error(what + ": file is truncated (header length " + std::to_string(hl) +
                " exceeds the file size)");
  nlohmann::json h;
  try {
    h = nlohmann::json::parse(bytes.begin() + 12, bytes.begin() + 12 + hl);
  } catch (const nlohmann::json::exception& e) {
    throw Error(what + ": malformed header: " + e.what());
  }
  Avatar a;
  try {
    if (h.value("format", std::string()) != "kinesplat-avatar")
      throw Error(what + ": header \"format\" is not \"kinesplat-avatar\"");
    const int major = whole<int>(h.at("version").at("major"), what, "version.major");
    const int minor = whole<int>(h.at("version").at("minor"), what, "version.minor");
    if (major > kAvatarVersionMajor)
      throw Error(what + ": avatar format version " + std::to_string(major) + "." +
                  std::to_string(minor) + " is newer than this kinesplat supports (" +
                  std::to_string(kAvatarVersionMajor) + "." + std::to_string(kAvatarVersionMinor) +
                  "); please upgrade kinesplat");
    if (major < 1) throw Error(what + ": unknown avatar format version " + std::to_string(major));
    if (h.value("byte_order", std::string("little")) != "little")
      throw Error(what + ": only little-endian avatar files are supported");
    const auto& c = h.at("counts");
    const int64_t N = whole<int64_t>(c.at("gaussians"), what, "counts.gaussians");
    const int64_t Nv = whole<int64_t>(c.at("template_vertices"), what, "counts.template_vertices");
    const int64_t F = whole<int64_t>(c.at("template_faces"), what, "counts.template_faces");
    const int J = whole<int>(c.at("joints"), what, "counts.joints");
    if (N < 0 || Nv < 0 || F < 0 || J < 1) throw Error(what + ": invalid counts in the header");
    if (N > int64_t(bytes.size()) || Nv > int64_t(bytes.size()) || F > int64_t(bytes.size()))
      throw Error(what + ": the header's counts exceed what the file holds (truncated or corrupt)");
    a.body_kind = h.at("body_model").at("kind").get<std::string>();
    a.body_model = h.at("body_model").at("name").get<std::string>();
    const auto betas = h.at("betas").get<std::vector<double>>();
    a.betas = Eigen::Map<const Eigen::VectorXd>(betas.data(), Eigen::Index(betas.size()));
    const auto& sk = h.at("skeleton");
    a.parents = whole_array<int>(sk.at("parents"), what, "skeleton.parents");
    a.joint_names = sk.at("joint_names").get<std::vector<std::string>>();
    const auto& rj = sk.at("rest_joints");
    if (!rj.is_array() || int(rj.size()) != J || int(a.parents.size()) != J)
      throw Error(what + ": skeleton sizes do not match the joint count " + std::to_string(J));
    a.rest_joints.resize(J, 3);
    for (int j = 0; j < J; ++j) {
      if (!rj[j].is_array() || rj[j].size() != 3)
        throw Error(what + ": rest joint " + std::to_string(j) + " is not 3 numbers");
      for (int k = 0; k < 3; ++k) a.rest_joints(j, k) = rj[j][k].get<double>();
    }
    const int deg = whole<int>(h.at("sh_degree"), what, "sh_degree");
    if (deg < 0 || deg > 3) throw Error(what + ": SH degree must be 0..3");
    if (whole<int>(h.at("skin_k"), what, "skin_k") != kAvatarSkinK)
      throw Error(what + ": only 4 skin weights per Gaussian are supported");
    if (h.contains("metadata")) a.metadata = h.at("metadata");
    const int64_t K = sh_coeff_count(deg);

    const auto& blocks = h.at("blocks");
    if (!blocks.is_object()) throw Error(what + ": header \"blocks\" must be an object");
    const size_t data_start = align_up(12 + size_t(hl));
    BlockReader r{bytes, data_start, blocks, what};
    const auto tv = r.get<float>("template_vertices", "f32", {Nv, 3});
    a.template_vertices.resize(Nv, 3);
    for (int64_t i = 0; i < Nv; ++i)
      for (int k = 0; k < 3; ++k) a.template_vertices(i, k) = tv[size_t(i) * 3 + k];
    const auto tf = r.get<int32_t>("template_faces", "i32", {F, 3});
    a.template_faces.resize(F, 3);
    for (int64_t i = 0; i < F; ++i)
      for (int k = 0; k < 3; ++k) a.template_faces(i, k) = tf[size_t(i) * 3 + k];
    a.gaussians.sh_degree = deg;
    a.gaussians.means = r.get<float>("means", "f32", {N, 3});
    a.gaussians.log_scales = r.get<float>("log_scales", "f32", {N, 3});
    a.gaussians.quats = r.get<float>("quats", "f32", {N, 4});
    a.gaussians.opacity_logits = r.get<float>("opacity_logits", "f32", {N});
    a.gaussians.sh = r.get<float>("sh", "f32", {N, K, 3});
    a.anchors = r.get<float>("anchors", "f32", {N, 3});
    a.skin_joints = r.get<int32_t>("skin_joints", "i32", {N, kAvatarSkinK});
    a.skin_weights = r.get<float>("skin_weights", "f32", {N, kAvatarSkinK});
    if (r.has("part_labels")) a.part_labels = r.get<int32_t>("part_labels", "i32", {N});
    const std::string pc = h.value("pose_correctives", std::string("none"));
    if (pc == "posedirs") {
      const auto pd = r.get<float>("posedirs", "f32", {3 * N, 9 * (J - 1)});
      a.posedirs =
          Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
              pd.data(), 3 * N, 9 * (J - 1));
    } else if (pc != "none") {
      throw Error(what + ": unknown pose_correctives \"" + pc + "\"");
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(what + ": malformed header: " + e.what());
  }
  a.validate(what);
  return a;
}

Avatar load_avatar(const std::string& path) {
  return parse_avatar(read_file_bytes(path), path);
}

}  // namespace ks

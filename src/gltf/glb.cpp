#include "gltf/glb.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace ks {

namespace {

constexpr uint32_t kMagic = 0x46546C67;      // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
}

uint32_t get_u32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

int component_bytes(int c) {
  switch (c) {
    case kGltfByte:
    case kGltfUnsignedByte:
      return 1;
    case kGltfShort:
    case kGltfUnsignedShort:
      return 2;
    case kGltfUnsignedInt:
    case kGltfFloat:
      return 4;
    default:
      return 0;
  }
}

}  // namespace

int gltf_type_components(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4") return 4;
  if (type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  if (type == "MAT4") return 16;
  return 0;
}

int GlbBuilder::add_view(const void* data, size_t bytes, int target) {
  while (bin_.size() % 4) bin_.push_back(0);
  nlohmann::json view = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", bytes}};
  if (target) view["target"] = target;
  const auto* p = static_cast<const uint8_t*>(data);
  bin_.insert(bin_.end(), p, p + bytes);
  if (!gltf.contains("bufferViews")) gltf["bufferViews"] = nlohmann::json::array();
  gltf["bufferViews"].push_back(view);
  return int(gltf["bufferViews"].size()) - 1;
}

int GlbBuilder::add_floats(const std::vector<float>& values, const std::string& type, int target,
                           bool with_bounds) {
  const int nc = gltf_type_components(type);
  if (nc == 0 || values.empty() || values.size() % size_t(nc))
    throw Error("glb: " + std::to_string(values.size()) + " floats do not make " + type +
                " elements");
  const size_t count = values.size() / size_t(nc);
  nlohmann::json acc = {{"bufferView", add_view(values.data(), values.size() * 4, target)},
                        {"componentType", kGltfFloat},
                        {"count", count},
                        {"type", type}};
  if (with_bounds) {
    std::vector<float> lo(size_t(nc), std::numeric_limits<float>::infinity()),
        hi(size_t(nc), -std::numeric_limits<float>::infinity());
    for (size_t i = 0; i < count; ++i)
      for (int c = 0; c < nc; ++c) {
        lo[size_t(c)] = std::min(lo[size_t(c)], values[i * size_t(nc) + size_t(c)]);
        hi[size_t(c)] = std::max(hi[size_t(c)], values[i * size_t(nc) + size_t(c)]);
      }
    acc["min"] = lo;
    acc["max"] = hi;
  }
  if (!gltf.contains("accessors")) gltf["accessors"] = nlohmann::json::array();
  gltf["accessors"].push_back(acc);
  return int(gltf["accessors"].size()) - 1;
}

int GlbBuilder::add_uints(const std::vector<uint32_t>& values, const std::string& type,
                          int component, int target) {
  const int nc = gltf_type_components(type);
  const int cb = component_bytes(component);
  if (nc == 0 || values.empty() || values.size() % size_t(nc) ||
      !(component == kGltfUnsignedByte || component == kGltfUnsignedShort ||
        component == kGltfUnsignedInt))
    throw Error("glb: cannot store " + std::to_string(values.size()) + " integers as " + type);
  std::vector<uint8_t> bytes(values.size() * size_t(cb));
  const uint32_t limit = cb == 1 ? 0xFFu : cb == 2 ? 0xFFFFu : 0xFFFFFFFFu;
  for (size_t i = 0; i < values.size(); ++i) {
    if (values[i] > limit)
      throw Error("glb: integer " + std::to_string(values[i]) + " does not fit its component");
    for (int k = 0; k < cb; ++k) bytes[i * size_t(cb) + size_t(k)] = uint8_t(values[i] >> (8 * k));
  }
  nlohmann::json acc = {{"bufferView", add_view(bytes.data(), bytes.size(), target)},
                        {"componentType", component},
                        {"count", values.size() / size_t(nc)},
                        {"type", type}};
  if (!gltf.contains("accessors")) gltf["accessors"] = nlohmann::json::array();
  gltf["accessors"].push_back(acc);
  return int(gltf["accessors"].size()) - 1;
}

std::vector<uint8_t> GlbBuilder::finish() {
  while (bin_.size() % 4) bin_.push_back(0);
  if (!bin_.empty()) gltf["buffers"] = nlohmann::json::array({{{"byteLength", bin_.size()}}});
  std::string text = gltf.dump();
  while (text.size() % 4) text.push_back(' ');
  const size_t total = 12 + 8 + text.size() + (bin_.empty() ? 0 : 8 + bin_.size());
  if (total > 0xFFFFFFFFull) throw Error("glb: the file would exceed GLB's 4 GiB limit");
  std::vector<uint8_t> out;
  out.reserve(total);
  put_u32(out, kMagic);
  put_u32(out, 2);
  put_u32(out, uint32_t(total));
  put_u32(out, uint32_t(text.size()));
  put_u32(out, kChunkJson);
  out.insert(out.end(), text.begin(), text.end());
  if (!bin_.empty()) {
    put_u32(out, uint32_t(bin_.size()));
    put_u32(out, kChunkBin);
    out.insert(out.end(), bin_.begin(), bin_.end());
  }
  return out;
}

GlbDocument parse_glb(const std::vector<uint8_t>& bytes, const std::string& what) {
  if (bytes.size() < 20)
    throw Error(what + ": not a GLB file (" + std::to_string(bytes.size()) +
                " bytes, shorter than the GLB header)");
  if (get_u32(bytes.data()) != kMagic) throw Error(what + ": not a GLB file (wrong magic)");
  const uint32_t version = get_u32(bytes.data() + 4);
  if (version != 2)
    throw Error(what + ": GLB version " + std::to_string(version) + " (only 2 is read)");
  const uint32_t length = get_u32(bytes.data() + 8);
  if (length != bytes.size())
    throw Error(what + ": GLB header says " + std::to_string(length) + " bytes, the file has " +
                std::to_string(bytes.size()) + " (truncated or corrupted)");
  GlbDocument doc;
  doc.what = what;
  size_t pos = 12;
  int chunk = 0;
  while (pos < bytes.size()) {
    if (bytes.size() - pos < 8) throw Error(what + ": truncated GLB chunk header");
    const uint32_t len = get_u32(bytes.data() + pos), type = get_u32(bytes.data() + pos + 4);
    pos += 8;
    if (len > bytes.size() - pos)
      throw Error(what + ": GLB chunk " + std::to_string(chunk) + " says " + std::to_string(len) +
                  " bytes, only " + std::to_string(bytes.size() - pos) + " remain");
    if (chunk == 0) {
      if (type != kChunkJson) throw Error(what + ": the first GLB chunk is not JSON");
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(bytes.begin() + long(pos), bytes.begin() + long(pos + len));
      } catch (const std::exception& e) {
        throw Error(what + ": malformed glTF JSON: " + e.what());
      }
      if (!j.is_object()) throw Error(what + ": the glTF JSON is not an object");
      doc.gltf = std::move(j);
    } else if (chunk == 1 && type == kChunkBin) {
      doc.bin.assign(bytes.begin() + long(pos), bytes.begin() + long(pos + len));
    }  // other chunks are skipped, as the specification asks
    pos += len;
    ++chunk;
  }
  if (chunk == 0) throw Error(what + ": GLB file without a JSON chunk");
  return doc;
}

GlbDocument read_glb(const std::string& path) {
  return parse_glb(read_file_bytes(path), path);
}

namespace {

struct AccessorView {
  const uint8_t* base = nullptr;
  size_t stride = 0;
  int count = 0, comps = 0, component = 0;
  bool normalized = false;
};

// A non-negative integer field of a glTF object: an integer JSON number in [0, max] (glTF's
// counts, indices and offsets); `fallback` where it is missing (< 0: required). Anything else
// (a fraction, a number out of range, a string) is a ks::Error naming the field.
int64_t index_field(const nlohmann::json& obj, const char* key, int64_t fallback, int64_t max,
                    const std::string& name) {
  const auto it = obj.find(key);
  if (it == obj.end()) {
    if (fallback < 0) throw Error(name + ": no \"" + key + "\"");
    return fallback;
  }
  if (it->is_number_unsigned() && it->get<uint64_t>() <= uint64_t(max))
    return int64_t(it->get<uint64_t>());
  if (it->is_number_integer() && it->get<int64_t>() >= 0 && it->get<int64_t>() <= max)
    return it->get<int64_t>();
  throw Error(name + ": \"" + key + "\" must be an integer in [0, " + std::to_string(max) +
              "], not " + it->dump());
}

AccessorView view_of(const GlbDocument& d, int index) {
  const auto& accs = d.gltf.value("accessors", nlohmann::json::array());
  if (index < 0 || !accs.is_array() || size_t(index) >= accs.size() ||
      !accs[size_t(index)].is_object())
    throw Error(d.what + ": no accessor " + std::to_string(index));
  const auto& a = accs[size_t(index)];
  const std::string name = d.what + ": accessor " + std::to_string(index);
  constexpr int64_t kMaxInt = std::numeric_limits<int>::max();
  const auto big = int64_t(std::numeric_limits<uint32_t>::max());
  try {
    AccessorView v;
    v.count = int(index_field(a, "count", -1, kMaxInt, name));
    v.comps = gltf_type_components(a.at("type").get<std::string>());
    v.component = int(index_field(a, "componentType", -1, kMaxInt, name));
    v.normalized = a.value("normalized", false);
    const int cb = component_bytes(v.component);
    if (v.comps == 0 || cb == 0) throw Error(name + ": unknown type or component");
    const int64_t bv = index_field(a, "bufferView", -1, kMaxInt, name);
    const auto& views = d.gltf.at("bufferViews");
    if (!views.is_array() || size_t(bv) >= views.size() || !views[size_t(bv)].is_object())
      throw Error(name + ": no buffer view " + std::to_string(bv));
    const auto& view = views[size_t(bv)];
    const std::string vname = d.what + ": buffer view " + std::to_string(bv);
    if (index_field(view, "buffer", -1, kMaxInt, vname) != 0)
      throw Error(name + ": not in the GLB's binary buffer");
    const auto voff = size_t(index_field(view, "byteOffset", 0, big, vname));
    const auto vlen = size_t(index_field(view, "byteLength", -1, big, vname));
    const size_t elem = size_t(v.comps) * size_t(cb);
    v.stride = size_t(index_field(view, "byteStride", int64_t(elem), 252, vname));
    const auto aoff = size_t(index_field(a, "byteOffset", 0, big, name));
    if (voff > d.bin.size() || vlen > d.bin.size() - voff)
      throw Error(name + ": buffer view outside the BIN chunk");
    if (v.count > 0 &&
        (aoff > vlen || v.stride < elem || (size_t(v.count) - 1) * v.stride + elem > vlen - aoff))
      throw Error(name + ": elements run past the end of its buffer view");
    v.base = d.bin.data() + voff + aoff;
    return v;
  } catch (const nlohmann::json::exception& e) {
    throw Error(name + ": " + e.what());
  }
}

}  // namespace

std::vector<float> GlbDocument::read_floats(int index) const {
  const AccessorView v = view_of(*this, index);
  std::vector<float> out(size_t(v.count) * size_t(v.comps));
  const int cb = component_bytes(v.component);
  for (int i = 0; i < v.count; ++i)
    for (int c = 0; c < v.comps; ++c) {
      const uint8_t* p = v.base + size_t(i) * v.stride + size_t(c) * size_t(cb);
      float x = 0;
      switch (v.component) {
        case kGltfFloat:
          std::memcpy(&x, p, 4);
          break;
        case kGltfUnsignedByte:
          x = v.normalized ? p[0] / 255.f : float(p[0]);
          break;
        case kGltfByte: {
          const auto s = int8_t(p[0]);
          x = v.normalized ? std::max(s / 127.f, -1.f) : float(s);
          break;
        }
        case kGltfUnsignedShort: {
          const int u = p[0] | p[1] << 8;
          x = v.normalized ? u / 65535.f : float(u);
          break;
        }
        case kGltfShort: {
          const auto s = int16_t(p[0] | p[1] << 8);
          x = v.normalized ? std::max(s / 32767.f, -1.f) : float(s);
          break;
        }
        case kGltfUnsignedInt:
          x = float(get_u32(p));
          break;
      }
      out[size_t(i) * size_t(v.comps) + size_t(c)] = x;
    }
  return out;
}

std::vector<uint32_t> GlbDocument::read_uints(int index) const {
  const AccessorView v = view_of(*this, index);
  if (!(v.component == kGltfUnsignedByte || v.component == kGltfUnsignedShort ||
        v.component == kGltfUnsignedInt))
    throw Error(what + ": accessor " + std::to_string(index) + " is not of an unsigned type");
  const int cb = component_bytes(v.component);
  std::vector<uint32_t> out(size_t(v.count) * size_t(v.comps));
  for (int i = 0; i < v.count; ++i)
    for (int c = 0; c < v.comps; ++c) {
      const uint8_t* p = v.base + size_t(i) * v.stride + size_t(c) * size_t(cb);
      out[size_t(i) * size_t(v.comps) + size_t(c)] = cb == 1   ? p[0]
                                                     : cb == 2 ? uint32_t(p[0] | p[1] << 8)
                                                               : get_u32(p);
    }
  return out;
}

int GlbDocument::accessor_count(int index) const {
  return view_of(*this, index).count;
}
int GlbDocument::accessor_components(int index) const {
  return view_of(*this, index).comps;
}

}  // namespace ks

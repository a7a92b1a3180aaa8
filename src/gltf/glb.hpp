#pragma once
// The GLB container of glTF 2.0 (binary glTF): a 12-byte header ("glTF", version 2, total
// length), a JSON chunk (padded with spaces to 4 bytes) and an optional BIN chunk (padded with
// zeros), all little-endian. GlbBuilder collects the binary buffer, buffer views and accessors
// while the JSON is built; read_glb / GlbDocument read a file back (the tests' reader, and any
// tool's). Documented in docs/export.md.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace ks {

// glTF accessor component types and buffer-view targets.
inline constexpr int kGltfByte = 5120, kGltfUnsignedByte = 5121, kGltfShort = 5122,
                     kGltfUnsignedShort = 5123, kGltfUnsignedInt = 5125, kGltfFloat = 5126;
inline constexpr int kGltfArrayBuffer = 34962, kGltfElementArrayBuffer = 34963;

// Builds the one binary buffer of a GLB: each add_* appends a 4-byte aligned buffer view with
// one accessor and returns the accessor's index in `gltf["accessors"]`.
class GlbBuilder {
 public:
  nlohmann::json gltf = nlohmann::json::object();

  // type: "SCALAR", "VEC2", "VEC3", "VEC4", "MAT4"; `values` count * components floats.
  // with_bounds: the accessor gets "min" / "max" (required for POSITION and animation inputs).
  int add_floats(const std::vector<float>& values, const std::string& type, int target = 0,
                 bool with_bounds = false);
  // Unsigned integers stored as component type `component` (unsigned byte / short / int).
  int add_uints(const std::vector<uint32_t>& values, const std::string& type, int component,
                int target = 0);
  // Raw bytes (an image) as a buffer view without a target; returns the view's index.
  int add_bytes(const void* data, size_t bytes) { return add_view(data, bytes, 0); }
  // The whole file: JSON chunk with buffers[0] = the binary buffer, then the BIN chunk.
  std::vector<uint8_t> finish();

 private:
  int add_view(const void* data, size_t bytes, int target);
  std::vector<uint8_t> bin_;
};

// Number of components of an accessor type ("VEC3" -> 3); 0 for an unknown type.
int gltf_type_components(const std::string& type);

// A GLB read back: the JSON and the BIN chunk, with typed accessor reads.
struct GlbDocument {
  nlohmann::json gltf;
  std::vector<uint8_t> bin;
  std::string what;  // names the source in messages

  // Accessor `index` as floats (count * components values): float components as stored,
  // integer ones as their values, or, when the accessor is normalized, scaled to [0, 1] / [-1, 1].
  // Throws ks::Error for a missing accessor or buffer view, an unknown type, or a range outside
  // the BIN chunk.
  std::vector<float> read_floats(int index) const;
  // Accessor `index` of an unsigned integer component type as uint32 values.
  std::vector<uint32_t> read_uints(int index) const;
  // Count and components of accessor `index`.
  int accessor_count(int index) const;
  int accessor_components(int index) const;
};

// Parses GLB bytes. Throws ks::Error naming `what` for a file shorter than its header, a wrong
// magic or version, a length field that disagrees with the size, a chunk running past the end or
// with a wrong type, malformed JSON or JSON that is not an object.
GlbDocument parse_glb(const std::vector<uint8_t>& bytes, const std::string& what);
GlbDocument read_glb(const std::string& path);

}  // namespace ks

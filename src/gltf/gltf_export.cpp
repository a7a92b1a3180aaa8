#include "gltf/gltf_export.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "avatar/pose.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "core/rotation.hpp"
#include "gltf/color_bake.hpp"
#include "gltf/glb.hpp"
#include "io/image_io.hpp"
#include "mesh/trimesh.hpp"

namespace ks {

using nlohmann::json;

float srgb_to_linear(float c) {
  c = std::clamp(c, 0.f, 1.f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

namespace {

float sigmoid(float x) {
  return 1.f / (1.f + std::exp(-x));
}

// glTF quaternion (x, y, z, w) of an axis-angle.
Eigen::Vector4d gltf_quat(const Eigen::Vector3d& aa) {
  Eigen::Quaterniond q(axis_angle_to_matrix<double>(aa));
  q.normalize();
  return {q.x(), q.y(), q.z(), q.w()};
}

std::vector<uint32_t> joint_list(const std::vector<int32_t>& joints) {
  return std::vector<uint32_t>(joints.begin(), joints.end());
}

// Slots of weight 0 name joint 0, as glTF asks (the validator warns about any other joint there).
void zero_padding(std::vector<int32_t>& joints, const std::vector<float>& weights) {
  for (size_t i = 0; i < joints.size(); ++i)
    if (!(weights[i] > 0)) joints[i] = 0;
}

int joint_component(int J) {
  return J <= 256 ? kGltfUnsignedByte : kGltfUnsignedShort;
}

// The skinned template surface: its attributes, indices and material (a base-colour texture over
// the UV atlas, or COLOR_0) added to `b`; returns the mesh's JSON.
json add_mesh(GlbBuilder& b, const Avatar& a, const GltfExportOptions& opt, int jcomp) {
  const long V = a.template_vertices.rows(), F = a.template_faces.rows();
  if (V == 0) throw Error("gltf: the avatar has no template surface");
  if (F == 0) throw Error("gltf: the avatar's template has no faces");
  if (a.template_faces.minCoeff() < 0 || a.template_faces.maxCoeff() >= V)
    throw Error("gltf: the avatar's template has a face out of range");
  const auto members = gaussians_per_vertex(a);
  const BakedVertexAttributes baked = bake_vertex_attributes(a, members);
  // The surface written: where the splats are (the default), or the template itself.
  const Eigen::MatrixXd P = opt.template_surface ? a.template_vertices : splat_surface(a, members);
  const Eigen::MatrixXd normals = vertex_normals(P, a.template_faces);
  // The vertices written: the template's own, or with a texture its atlas copies.
  std::vector<int> source;
  Eigen::MatrixXi faces = a.template_faces;
  BakedTexture tex;
  if (!opt.vertex_colors) {
    tex = bake_texture(a, P, baked, members, opt.texture);
    source = tex.atlas.source;
    faces = tex.atlas.faces;
  } else {
    source.resize(size_t(V));
    for (long v = 0; v < V; ++v) source[size_t(v)] = int(v);
  }
  const size_t W = source.size();
  std::vector<float> pos(3 * W), nrm(3 * W), col, wts(4 * W);
  std::vector<int32_t> joints(4 * W);
  if (opt.vertex_colors) col.resize(3 * W);
  for (size_t w = 0; w < W; ++w) {
    const int v = source[w];
    Eigen::Vector3f n = normals.row(v).transpose().cast<float>();
    if (!n.allFinite() || n.norm() < 1e-6f) n = Eigen::Vector3f(0, 1, 0);
    n.normalize();
    for (int k = 0; k < 3; ++k) {
      pos[3 * w + size_t(k)] = float(P(v, k));
      nrm[3 * w + size_t(k)] = n[k];
      if (opt.vertex_colors)
        col[3 * w + size_t(k)] = srgb_to_linear(baked.srgb[3 * size_t(v) + size_t(k)]);
    }
    for (int s = 0; s < 4; ++s) {
      joints[4 * w + size_t(s)] = baked.joints[4 * size_t(v) + size_t(s)];
      wts[4 * w + size_t(s)] = baked.weights[4 * size_t(v) + size_t(s)];
    }
  }
  zero_padding(joints, wts);
  std::vector<uint32_t> idx(3 * size_t(F));
  for (long f = 0; f < F; ++f)
    for (int k = 0; k < 3; ++k) idx[3 * size_t(f) + size_t(k)] = uint32_t(faces(f, k));
  json attrs = {{"POSITION", b.add_floats(pos, "VEC3", kGltfArrayBuffer, true)},
                {"NORMAL", b.add_floats(nrm, "VEC3", kGltfArrayBuffer)},
                {"JOINTS_0", b.add_uints(joint_list(joints), "VEC4", jcomp, kGltfArrayBuffer)},
                {"WEIGHTS_0", b.add_floats(wts, "VEC4", kGltfArrayBuffer)}};
  // The colours are the splats' own (lighting baked in): an unlit material shows them as they are.
  json material = {
      {"name", "avatar"},
      {"pbrMetallicRoughness",
       {{"baseColorFactor", {1, 1, 1, 1}}, {"metallicFactor", 0.0}, {"roughnessFactor", 1.0}}},
      {"extensions", {{"KHR_materials_unlit", json::object()}}}};
  if (opt.vertex_colors) {
    attrs["COLOR_0"] = b.add_floats(col, "VEC3", kGltfArrayBuffer);
  } else {
    attrs["TEXCOORD_0"] = b.add_floats(tex.atlas.uv, "VEC2", kGltfArrayBuffer);
    const std::vector<uint8_t> png = encode_png(tex.image);
    b.gltf["images"] = json::array({{{"name", "avatar_colour"},
                                     {"bufferView", b.add_bytes(png.data(), png.size())},
                                     {"mimeType", "image/png"}}});
    // LINEAR / LINEAR_MIPMAP_LINEAR, CLAMP_TO_EDGE.
    b.gltf["samplers"] = json::array(
        {{{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33071}}});
    b.gltf["textures"] = json::array({{{"sampler", 0}, {"source", 0}}});
    material["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}, {"texCoord", 0}};
  }
  b.gltf["materials"] = json::array({material});
  const int ind = b.add_uints(idx, "SCALAR", W <= 65536 ? kGltfUnsignedShort : kGltfUnsignedInt,
                              kGltfElementArrayBuffer);
  return {{"name", "avatar_mesh"},
          {"primitives",
           json::array({{{"attributes", attrs}, {"indices", ind}, {"material", 0}, {"mode", 4}}})}};
}

}  // namespace

std::vector<uint8_t> avatar_gltf(const Avatar& a, const std::vector<Motion>& motions,
                                 const GltfExportOptions& opt) {
  if (!opt.mesh && !opt.splats) throw Error("gltf: choose the mesh, the splats or both");
  const int J = a.num_joints();
  if (J == 0 || J > 65536)
    throw Error("gltf: the avatar's skeleton has " + std::to_string(J) +
                " joints (1..65536 can be exported)");
  GlbBuilder b;
  json& g = b.gltf;
  g["asset"] = {{"version", "2.0"}, {"generator", "kinesplat"}};
  // Skeleton.
  json nodes = json::array();
  std::vector<std::vector<int>> children(static_cast<size_t>(J));
  for (int j = 1; j < J; ++j) children[size_t(a.parents[size_t(j)])].push_back(j);
  auto rest_offset = [&](int j) {
    Eigen::Vector3d t = a.rest_joints.row(j).transpose();
    const int p = a.parents[size_t(j)];
    if (p >= 0) t -= a.rest_joints.row(p).transpose();
    return t;
  };
  for (int j = 0; j < J; ++j) {
    const Eigen::Vector3d t = rest_offset(j);
    json n = {{"name", a.joint_names.size() == size_t(J) ? a.joint_names[size_t(j)]
                                                         : "joint_" + std::to_string(j)},
              {"translation", {t.x(), t.y(), t.z()}}};
    if (!children[size_t(j)].empty()) n["children"] = children[size_t(j)];
    nodes.push_back(n);
  }
  std::vector<float> ibm(16 * size_t(J), 0.f);
  for (int j = 0; j < J; ++j) {
    float* m = &ibm[16 * size_t(j)];  // column-major
    m[0] = m[5] = m[10] = m[15] = 1.f;
    for (int k = 0; k < 3; ++k) m[12 + k] = float(-a.rest_joints(j, k));
  }
  std::vector<int> joint_nodes(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j) joint_nodes[size_t(j)] = j;
  g["skins"] = json::array({{{"name", "skeleton"},
                             {"joints", joint_nodes},
                             {"skeleton", 0},
                             {"inverseBindMatrices", b.add_floats(ibm, "MAT4")}}});
  json scene_nodes = json::array({0});
  json extensions = json::array();
  json meshes = json::array();
  const int jcomp = joint_component(J);

  if (opt.mesh) {
    meshes.push_back(add_mesh(b, a, opt, jcomp));
    nodes.push_back({{"name", "avatar_mesh"}, {"mesh", int(meshes.size()) - 1}, {"skin", 0}});
    scene_nodes.push_back(int(nodes.size()) - 1);
    extensions.push_back("KHR_materials_unlit");
  }

  if (opt.splats) {
    const Gaussians& G = a.gaussians;
    const size_t N = G.size();
    if (N == 0) throw Error("gltf: the avatar has no Gaussians");
    if (a.skin_joints.size() != 4 * N || a.skin_weights.size() != 4 * N)
      throw Error("gltf: the avatar's skin weights do not match its Gaussians");
    std::vector<float> pos(3 * N), rot(4 * N), scale(3 * N), opac(N), col(4 * N);
    for (size_t i = 0; i < N; ++i) {
      for (int k = 0; k < 3; ++k) {
        pos[3 * i + size_t(k)] = G.means[3 * i + size_t(k)];
        scale[3 * i + size_t(k)] = std::exp(G.log_scales[3 * i + size_t(k)]);
      }
      Eigen::Vector4f q(G.quats[4 * i + 1], G.quats[4 * i + 2], G.quats[4 * i + 3], G.quats[4 * i]);
      const float qn = q.norm();
      q = qn > 0 && std::isfinite(qn) ? Eigen::Vector4f(q / qn) : Eigen::Vector4f(0, 0, 0, 1);
      for (int k = 0; k < 4; ++k) rot[4 * i + size_t(k)] = q[k];
      opac[i] = sigmoid(G.opacity_logits[i]);
      const Eigen::Vector3f c = band0_srgb(G, i);
      for (int k = 0; k < 3; ++k) col[4 * i + size_t(k)] = srgb_to_linear(c[k]);
      col[4 * i + 3] = opac[i];
    }
    std::vector<int32_t> joints = a.skin_joints;
    zero_padding(joints, a.skin_weights);
    json attrs = {
        {"POSITION", b.add_floats(pos, "VEC3", kGltfArrayBuffer, true)},
        {"COLOR_0", b.add_floats(col, "VEC4", kGltfArrayBuffer)},
        {"KHR_gaussian_splatting:ROTATION", b.add_floats(rot, "VEC4", kGltfArrayBuffer)},
        {"KHR_gaussian_splatting:SCALE", b.add_floats(scale, "VEC3", kGltfArrayBuffer)},
        {"KHR_gaussian_splatting:OPACITY", b.add_floats(opac, "SCALAR", kGltfArrayBuffer)},
        {"JOINTS_0", b.add_uints(joint_list(joints), "VEC4", jcomp, kGltfArrayBuffer)},
        {"WEIGHTS_0", b.add_floats(a.skin_weights, "VEC4", kGltfArrayBuffer)}};
    const int K = G.coeffs();
    std::vector<float> coef(3 * N);
    for (int k = 0; k < K; ++k) {
      const int l = int(std::sqrt(double(k)) + 1e-9), m = k - l * l;
      for (size_t i = 0; i < N; ++i)
        for (int c = 0; c < 3; ++c)
          coef[3 * i + size_t(c)] = G.sh[(i * size_t(K) + size_t(k)) * 3 + size_t(c)];
      attrs["KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(l) + "_COEF_" +
            std::to_string(m)] = b.add_floats(coef, "VEC3", kGltfArrayBuffer);
    }
    meshes.push_back(
        {{"name", "avatar_splats"},
         {"primitives",
          json::array({{{"attributes", attrs},
                        {"mode", 0},
                        {"extensions",
                         {{"KHR_gaussian_splatting",
                           {{"kernel", "ellipse"}, {"colorSpace", "srgb_rec709_display"}}}}}}})}});
    nodes.push_back({{"name", "avatar_splats"}, {"mesh", int(meshes.size()) - 1}, {"skin", 0}});
    scene_nodes.push_back(int(nodes.size()) - 1);
    extensions.push_back("KHR_gaussian_splatting");
  }

  // Animations.
  json anims = json::array();
  for (const Motion& mo : motions) {
    const size_t T = mo.frames.size();
    if (T == 0) throw Error("gltf: motion \"" + mo.name + "\" has no frames");
    if (!(mo.fps > 0) || !std::isfinite(mo.fps))
      throw Error("gltf: motion \"" + mo.name + "\" has no positive frame rate");
    std::vector<float> times(T), transl(3 * T);
    std::vector<std::vector<float>> rots(size_t(J), std::vector<float>(4 * T));
    for (size_t f = 0; f < T; ++f) {
      times[f] = float(double(f) / mo.fps);
      const Eigen::MatrixXd pose = avatar_full_pose(a, mo.frames[f]);
      for (int j = 0; j < J; ++j) {
        Eigen::Vector4d q = gltf_quat(pose.row(j).transpose());
        if (f > 0) {  // the same hemisphere as the previous key: interpolation takes the short way
          Eigen::Vector4d prev;
          for (int k = 0; k < 4; ++k) prev[k] = rots[size_t(j)][4 * (f - 1) + size_t(k)];
          if (prev.dot(q) < 0) q = -q;
        }
        for (int k = 0; k < 4; ++k) rots[size_t(j)][4 * f + size_t(k)] = float(q[k]);
      }
      const Eigen::Vector3d t = a.rest_joints.row(0).transpose() + mo.frames[f].transl;
      for (int k = 0; k < 3; ++k) transl[3 * f + size_t(k)] = float(t[k]);
    }
    const int in = b.add_floats(times, "SCALAR", 0, true);
    json samplers = json::array(), channels = json::array();
    for (int j = 0; j < J; ++j) {
      samplers.push_back({{"input", in},
                          {"output", b.add_floats(rots[size_t(j)], "VEC4")},
                          {"interpolation", "LINEAR"}});
      channels.push_back({{"sampler", j}, {"target", {{"node", j}, {"path", "rotation"}}}});
    }
    samplers.push_back(
        {{"input", in}, {"output", b.add_floats(transl, "VEC3")}, {"interpolation", "LINEAR"}});
    channels.push_back({{"sampler", J}, {"target", {{"node", 0}, {"path", "translation"}}}});
    anims.push_back({{"name", mo.name},
                     {"samplers", samplers},
                     {"channels", channels},
                     {"extras", {{"fps", mo.fps}, {"frames", T}}}});
  }
  if (!extensions.empty()) g["extensionsUsed"] = extensions;
  g["nodes"] = nodes;
  g["meshes"] = meshes;
  if (!anims.empty()) g["animations"] = anims;
  g["scenes"] = json::array({{{"name", "avatar"}, {"nodes", scene_nodes}}});
  g["scene"] = 0;
  return b.finish();
}

void export_gltf(const std::string& path, const Avatar& avatar, const std::vector<Motion>& motions,
                 const GltfExportOptions& opt) {
  const std::vector<uint8_t> bytes = avatar_gltf(avatar, motions, opt);
  write_file_atomic(path, bytes.data(), bytes.size());
}

}  // namespace ks

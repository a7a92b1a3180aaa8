#include "body/body_model.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "body/posing.hpp"
#include "core/error.hpp"
#include "io/npz.hpp"

namespace ks {

namespace {

const std::vector<std::string> kSmplBody22 = {
    "pelvis",     "left_hip",    "right_hip",    "spine1",     "left_knee",     "right_knee",
    "spine2",     "left_ankle",  "right_ankle",  "spine3",     "left_foot",     "right_foot",
    "neck",       "left_collar", "right_collar", "head",       "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist",   "right_wrist"};

std::vector<std::string> hand_names(const std::string& side) {
  std::vector<std::string> n;
  for (const char* f : {"index", "middle", "pinky", "ring", "thumb"})
    for (int k = 1; k <= 3; ++k) n.push_back(side + "_" + f + std::to_string(k));
  return n;
}

std::vector<std::string> make_names(BodyKind kind) {
  std::vector<std::string> n = kSmplBody22;
  if (kind == BodyKind::kSMPL || kind == BodyKind::kDefault) {
    n.push_back("left_hand");
    n.push_back("right_hand");
    return n;
  }
  if (kind == BodyKind::kSMPLX) {
    n.push_back("jaw");
    n.push_back("left_eye");
    n.push_back("right_eye");
  }
  for (auto& s : hand_names("left")) n.push_back(s);
  for (auto& s : hand_names("right")) n.push_back(s);
  return n;
}

// SMPL's 24 joints -> part.
constexpr Part kSmplJointPart[24] = {
    kHips,         kLeftUpperLeg,  kRightUpperLeg, kTorso,     kLeftLowerLeg, kRightLowerLeg,
    kTorso,        kLeftFoot,      kRightFoot,     kTorso,     kLeftFoot,     kRightFoot,
    kHeadNeck,     kTorso,         kTorso,         kHeadNeck,  kLeftUpperArm, kRightUpperArm,
    kLeftLowerArm, kRightLowerArm, kLeftHand,      kRightHand, kLeftHand,     kRightHand};

BodyKind kind_from_joints(int J, const std::string& path) {
  switch (J) {
    case 24:
      return BodyKind::kSMPL;
    case 52:
      return BodyKind::kSMPLH;
    case 55:
      return BodyKind::kSMPLX;
    default:
      throw Error(path + ": " + std::to_string(J) +
                  " joints is not a known body model (24 = SMPL, 52 = SMPL+H, 55 = SMPL-X)");
  }
}

const NpyArray& need(const NpzFile& z, const std::string& key, const std::string& path) {
  auto it = z.arrays.find(key);
  if (it != z.arrays.end()) return it->second;
  for (const auto& s : z.skipped)
    if (s == key)
      throw Error(path + ": array '" + key +
                  "' is stored as a Python object (e.g. a scipy sparse matrix or chumpy array); "
                  "save it as a dense numeric array (numpy.asarray / .toarray()) and retry");
  throw Error(path + ": missing array '" + key +
              "' (a body model .npz needs v_template, f, shapedirs, posedirs, J_regressor, "
              "weights and kintree_table)");
}

[[noreturn]] void bad_shape(const std::string& path, const std::string& key, const NpyArray& a,
                            const std::string& expected) {
  throw Error(path + ": array '" + key + "' has shape " + a.shape_string() + ", expected " +
              expected);
}

void need_numeric(const std::string& path, const std::string& key, const NpyArray& a,
                  bool integer) {
  if (integer && !a.is_integer())
    throw Error(path + ": array '" + key + "' must hold integers, found dtype " + a.descr());
  if (!integer && !(a.is_float() || a.is_integer()))
    throw Error(path + ": array '" + key + "' must be numeric, found dtype " + a.descr());
}

Eigen::MatrixXd to_matrix(const NpyArray& a, int64_t rows, int64_t cols, const std::string& path,
                          const std::string& key) {
  using RowD = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  using RowF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Eigen::MatrixXd m;
  if (a.kind == 'f' && a.itemsize == 8) {
    m = Eigen::Map<const RowD>(reinterpret_cast<const double*>(a.data.data()), rows, cols);
  } else if (a.kind == 'f' && a.itemsize == 4) {
    m = Eigen::Map<const RowF>(reinterpret_cast<const float*>(a.data.data()), rows, cols)
            .cast<double>();
  } else {
    m.resize(rows, cols);
    for (int64_t r = 0; r < rows; ++r)
      for (int64_t c = 0; c < cols; ++c) m(r, c) = a.as_double(r * cols + c);
  }
  if (!m.allFinite())
    throw Error(path + ": array '" + key + "' holds a non-finite value (NaN or inf)");
  return m;
}

}  // namespace

const std::vector<std::string>& body_joint_names(BodyKind kind) {
  static const std::vector<std::string> smpl = make_names(BodyKind::kSMPL);
  static const std::vector<std::string> smplh = make_names(BodyKind::kSMPLH);
  static const std::vector<std::string> smplx = make_names(BodyKind::kSMPLX);
  switch (kind) {
    case BodyKind::kSMPLH:
      return smplh;
    case BodyKind::kSMPLX:
      return smplx;
    default:
      return smpl;
  }
}

Part joint_part(BodyKind kind, int j) {
  if (j < 0) throw Error("joint_part: negative joint index");
  if (kind == BodyKind::kSMPL || kind == BodyKind::kDefault) {
    if (j >= 24) throw Error("joint_part: joint index out of range");
    return kSmplJointPart[j];
  }
  if (j < 22) return kSmplJointPart[j];
  if (kind == BodyKind::kSMPLX) {
    if (j < 25) return kHeadNeck;  // jaw, eyes
    if (j < 40) return kLeftHand;
    if (j < 55) return kRightHand;
  } else {
    if (j < 37) return kLeftHand;
    if (j < 52) return kRightHand;
  }
  throw Error("joint_part: joint index out of range");
}

std::vector<int> part_labels_from_weights(const Eigen::MatrixXd& weights, BodyKind kind) {
  std::vector<int> labels(size_t(weights.rows()), 0);
  std::vector<Part> jp(size_t(weights.cols()));
  for (int j = 0; j < int(weights.cols()); ++j) jp[size_t(j)] = joint_part(kind, j);
  for (Eigen::Index v = 0; v < weights.rows(); ++v) {
    double sum[kNumParts] = {};
    for (Eigen::Index j = 0; j < weights.cols(); ++j) sum[jp[size_t(j)]] += weights(v, j);
    int best = 0;
    for (int p = 1; p < kNumParts; ++p)
      if (sum[p] > sum[best]) best = p;
    labels[size_t(v)] = best;
  }
  return labels;
}

std::vector<int> part_vertex_counts(const std::vector<int>& labels) {
  std::vector<int> c(kNumParts, 0);
  for (int l : labels)
    if (l >= 0 && l < kNumParts) ++c[size_t(l)];
  return c;
}

int BodyModel::num_body_pose_joints() const {
  return (kind == BodyKind::kSMPL || kind == BodyKind::kDefault) ? 23 : 21;
}

const char* BodyModel::kind_name() const {
  switch (kind) {
    case BodyKind::kSMPL:
      return "smpl";
    case BodyKind::kSMPLH:
      return "smplh";
    case BodyKind::kSMPLX:
      return "smplx";
    default:
      return "default";
  }
}

BodyModel load_body_model(const std::string& path) {
  if (path == "default") return default_body_model();
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".pkl")
    throw Error(path +
                ": SMPL .pkl files are Python pickles (with chumpy arrays) that kinesplat does not "
                "read. Convert it once to the smplx .npz layout with Python, e.g.\n"
                "  python -c \"import pickle,numpy as np; d=pickle.load(open('" +
                path +
                "','rb'),encoding='latin1'); "
                "np.savez('model.npz', **{k: (v.toarray() if hasattr(v,'toarray') else "
                "np.asarray(v)) for k,v in d.items() if k in ('v_template','f','shapedirs',"
                "'posedirs','J_regressor','weights','kintree_table')})\"\n"
                "(needs the chumpy package installed to unpickle) and pass model.npz");
  const NpzFile z = read_npz(path);
  BodyModel m;

  const NpyArray& vt = need(z, "v_template", path);
  need_numeric(path, "v_template", vt, false);
  if (vt.shape.size() != 2 || vt.shape[1] != 3 || vt.shape[0] < 1)
    bad_shape(path, "v_template", vt, "(V, 3)");
  const int64_t V = vt.shape[0];
  m.v_template = to_matrix(vt, V, 3, path, "v_template");

  const NpyArray& kt = need(z, "kintree_table", path);
  need_numeric(path, "kintree_table", kt, true);
  if (kt.shape.size() != 2 || kt.shape[0] != 2 || kt.shape[1] < 1)
    bad_shape(path, "kintree_table", kt, "(2, J)");
  const int64_t J = kt.shape[1];
  m.kind = kind_from_joints(int(J), path);
  if (z.has("ks_model_kind") && z.arrays.at("ks_model_kind").size() == 1 &&
      z.arrays.at("ks_model_kind").as_int(0) == 3 && J == 24)
    m.kind = BodyKind::kDefault;
  m.parents.assign(size_t(J), -2);
  for (int64_t i = 0; i < J; ++i) {
    int64_t parent = kt.as_int(i);
    const int64_t child = kt.as_int(J + i);
    if (child < 0 || child >= J || m.parents[size_t(child)] != -2)
      throw Error(path + ": kintree_table row 1 must list each joint 0.." + std::to_string(J - 1) +
                  " once");
    if (parent == 4294967295LL || parent == -1) parent = -1;
    m.parents[size_t(child)] = int(parent);
  }
  for (int64_t j = 0; j < J; ++j) {
    const int p = m.parents[size_t(j)];
    if (j == 0 ? p != -1 : (p < 0 || p >= j))
      throw Error(path + ": kintree_table gives joint " + std::to_string(j) + " the parent " +
                  std::to_string(p) +
                  " (expected -1 / 4294967295 for the root and a lower index for every other "
                  "joint)");
  }
  m.joint_names = body_joint_names(m.kind);

  const NpyArray& f = need(z, "f", path);
  need_numeric(path, "f", f, true);
  if (f.shape.size() != 2 || f.shape[1] != 3 || f.shape[0] < 1) bad_shape(path, "f", f, "(F, 3)");
  m.faces.resize(f.shape[0], 3);
  for (int64_t i = 0; i < f.shape[0] * 3; ++i) {
    const int64_t idx = f.as_int(i);
    if (idx < 0 || idx >= V)
      throw Error(path + ": face index " + std::to_string(idx) + " out of range (" +
                  std::to_string(V) + " vertices)");
    m.faces(i / 3, i % 3) = int(idx);
  }

  const NpyArray& sd = need(z, "shapedirs", path);
  need_numeric(path, "shapedirs", sd, false);
  if (sd.shape.size() != 3 || sd.shape[0] != V || sd.shape[1] != 3)
    bad_shape(path, "shapedirs", sd, "(" + std::to_string(V) + ", 3, S)");
  const int64_t S = sd.shape[2];
  m.shapedirs = to_matrix(sd, 3 * V, S, path, "shapedirs");
  m.num_betas = int(S);
  m.num_expression = 0;
  if (z.has("num_expression") && z.arrays.at("num_expression").size() == 1) {
    const int64_t ne = z.arrays.at("num_expression").as_int(0);
    if (ne < 0 || ne > S)
      throw Error(path + ": num_expression = " + std::to_string(ne) + " but shapedirs has " +
                  std::to_string(S) + " columns");
    m.num_expression = int(ne);
    m.num_betas = int(S - ne);
  } else if (m.kind == BodyKind::kSMPLX) {
    if (S == 20) {
      m.num_betas = 10;
      m.num_expression = 10;
    } else if (S == 400) {
      m.num_betas = 300;
      m.num_expression = 100;
    }
  }

  const int64_t P = 9 * (J - 1);
  const NpyArray& pd = need(z, "posedirs", path);
  need_numeric(path, "posedirs", pd, false);
  if (pd.shape.size() == 3) {
    if (pd.shape[0] != V || pd.shape[1] != 3 || pd.shape[2] != P)
      bad_shape(path, "posedirs", pd,
                "(" + std::to_string(V) + ", 3, " + std::to_string(P) + ") for " +
                    std::to_string(J) + " joints");
    m.posedirs = to_matrix(pd, 3 * V, P, path, "posedirs");
  } else if (pd.shape.size() == 2 && pd.shape[0] == P && pd.shape[1] == 3 * V) {
    m.posedirs = to_matrix(pd, P, 3 * V, path, "posedirs").transpose();
  } else {
    bad_shape(path, "posedirs", pd,
              "(" + std::to_string(V) + ", 3, " + std::to_string(P) + ") for " + std::to_string(J) +
                  " joints");
  }

  const NpyArray& jr = need(z, "J_regressor", path);
  need_numeric(path, "J_regressor", jr, false);
  if (jr.shape.size() != 2 || jr.shape[0] != J || jr.shape[1] != V)
    bad_shape(path, "J_regressor", jr,
              "(" + std::to_string(J) + ", " + std::to_string(V) + ") (dense)");
  m.J_regressor = to_matrix(jr, J, V, path, "J_regressor");

  const NpyArray& w = need(z, "weights", path);
  need_numeric(path, "weights", w, false);
  if (w.shape.size() != 2 || w.shape[0] != V || w.shape[1] != J)
    bad_shape(path, "weights", w, "(" + std::to_string(V) + ", " + std::to_string(J) + ")");
  m.weights = to_matrix(w, V, J, path, "weights");

  if (z.has("part_labels")) {
    const NpyArray& pl = z.arrays.at("part_labels");
    need_numeric(path, "part_labels", pl, true);
    if (pl.size() != V) bad_shape(path, "part_labels", pl, "(" + std::to_string(V) + ",)");
    m.part_labels.resize(size_t(V));
    for (int64_t i = 0; i < V; ++i) {
      const int64_t l = pl.as_int(i);
      if (l < 0 || l >= kNumParts)
        throw Error(path + ": part label " + std::to_string(l) + " out of range [0, 15)");
      m.part_labels[size_t(i)] = int(l);
    }
  } else {
    m.part_labels = part_labels_from_weights(m.weights, m.kind);
  }
  m.update_posedirs_flag();
  return m;
}

void save_body_model(const std::string& path, const BodyModel& m) {
  const int64_t V = m.num_vertices(), J = m.num_joints();
  const int64_t S = m.shapedirs.cols(), P = m.posedirs.cols();
  if (m.v_template.cols() != 3 || m.shapedirs.rows() != 3 * V || m.posedirs.rows() != 3 * V ||
      P != 9 * (J - 1) || m.J_regressor.rows() != J || m.J_regressor.cols() != V ||
      m.weights.rows() != V || m.weights.cols() != J || m.faces.cols() != 3 ||
      (!m.part_labels.empty() && int64_t(m.part_labels.size()) != V))
    throw Error("save_body_model: inconsistent model arrays, not writing " + path);
  std::map<std::string, NpyArray> a;
  a["v_template"] = NpyArray::from_matrix(m.v_template);
  a["f"] = NpyArray::from_matrix(m.faces, 'i', 4);
  // (3V x S) with row 3v+k is exactly the C-order layout of (V, 3, S).
  {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> r = m.shapedirs;
    a["shapedirs"] = NpyArray::from_doubles({V, 3, S}, r.data());
    if (m.posedirs.isZero(0)) {
      // All-zero correctives (the default model): float32 zeros, exact and half the size.
      NpyArray z;
      z.kind = 'f';
      z.itemsize = 4;
      z.shape = {V, 3, P};
      z.data.assign(size_t(V) * 3 * size_t(P) * 4, 0);
      a["posedirs"] = std::move(z);
    } else {
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> q = m.posedirs;
      a["posedirs"] = NpyArray::from_doubles({V, 3, P}, q.data());
    }
  }
  a["J_regressor"] = NpyArray::from_matrix(m.J_regressor);
  a["weights"] = NpyArray::from_matrix(m.weights);
  std::vector<int64_t> kt(static_cast<size_t>(2 * J));
  for (int64_t j = 0; j < J; ++j) {
    kt[size_t(j)] = m.parents[size_t(j)];
    kt[size_t(J + j)] = j;
  }
  a["kintree_table"] = NpyArray::from_ints({2, J}, kt.data(), 'i', 4);
  if (!m.part_labels.empty()) {
    std::vector<int64_t> pl(m.part_labels.begin(), m.part_labels.end());
    a["part_labels"] = NpyArray::from_ints({V}, pl.data(), 'i', 4);
  }
  const int64_t ne = m.num_expression;
  a["num_expression"] = NpyArray::from_ints({}, &ne, 'i', 4);
  const int64_t kind = int64_t(m.kind);
  a["ks_model_kind"] = NpyArray::from_ints({}, &kind, 'i', 4);
  write_npz(path, a, true);
}

// ---------------------------------------------------------------------------------------------
// Parameters

namespace {

void flatten_numbers(const nlohmann::json& j, std::vector<double>& out, const std::string& key) {
  if (j.is_number()) {
    out.push_back(j.get<double>());
  } else if (j.is_array()) {
    for (const auto& e : j) flatten_numbers(e, out, key);
  } else {
    throw Error("params: '" + key + "' must be a number or an array of numbers");
  }
}

Eigen::VectorXd vec_of(const nlohmann::json& j, const std::string& key) {
  std::vector<double> v;
  flatten_numbers(j, v, key);
  Eigen::VectorXd r(Eigen::Index(v.size()));
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) throw Error("params: '" + key + "' holds a non-finite value");
    r[Eigen::Index(i)] = v[i];
  }
  return r;
}

void check_len(const Eigen::VectorXd& v, Eigen::Index n, const std::string& key,
               const std::string& why) {
  if (v.size() != n)
    throw Error("params: '" + key + "' has " + std::to_string(v.size()) + " values, expected " +
                std::to_string(n) + " (" + why + ")");
}

bool has_hands(const BodyModel& m) {
  return m.kind == BodyKind::kSMPLX || m.kind == BodyKind::kSMPLH;
}

}  // namespace

BodyParams BodyParams::from_json(const nlohmann::json& j, const BodyModel& model) {
  if (!j.is_object()) throw Error("params: expected a JSON object");
  BodyParams p;
  const std::string kn = model.kind_name();
  auto get3 = [&](const char* key, Eigen::Vector3d& dst) {
    if (!j.contains(key)) return;
    Eigen::VectorXd v = vec_of(j[key], key);
    check_len(v, 3, key, "one axis-angle");
    dst = v;
  };
  if (j.contains("betas")) {
    p.betas = vec_of(j["betas"], "betas");
    if (p.betas.size() > model.num_betas)
      throw Error("params: 'betas' has " + std::to_string(p.betas.size()) + " values, but the " +
                  kn + " model has " + std::to_string(model.num_betas) + " shape coefficients");
  }
  if (j.contains("expression")) {
    p.expression = vec_of(j["expression"], "expression");
    if (p.expression.size() > model.num_expression)
      throw Error("params: 'expression' has " + std::to_string(p.expression.size()) +
                  " values, but the " + kn + " model has " + std::to_string(model.num_expression) +
                  " expression coefficients");
  }
  get3("global_orient", p.global_orient);
  get3("transl", p.transl);
  if (j.contains("body_pose")) {
    p.body_pose = vec_of(j["body_pose"], "body_pose");
    check_len(p.body_pose, 3 * model.num_body_pose_joints(), "body_pose",
              "3 per non-root body joint of the " + kn + " model");
  }
  for (const char* key : {"jaw_pose", "leye_pose", "reye_pose"}) {
    if (!j.contains(key)) continue;
    if (model.kind != BodyKind::kSMPLX)
      throw Error(std::string("params: '") + key + "' is only used by SMPL-X models, not " + kn);
  }
  get3("jaw_pose", p.jaw_pose);
  get3("leye_pose", p.leye_pose);
  get3("reye_pose", p.reye_pose);
  for (const char* key : {"left_hand_pose", "right_hand_pose"}) {
    if (!j.contains(key)) continue;
    if (!has_hands(model))
      throw Error(std::string("params: '") + key +
                  "' is only used by SMPL+H / SMPL-X models, not " + kn);
    Eigen::VectorXd v = vec_of(j[key], key);
    check_len(v, 45, key, "full axis-angle of 15 hand joints; PCA hand poses are not supported");
    (std::string(key) == "left_hand_pose" ? p.left_hand_pose : p.right_hand_pose) = v;
  }
  return p;
}

nlohmann::json BodyParams::to_json() const {
  auto arr = [](const Eigen::VectorXd& v) {
    nlohmann::json a = nlohmann::json::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(v[i]);
    return a;
  };
  nlohmann::json j;
  if (betas.size()) j["betas"] = arr(betas);
  if (expression.size()) j["expression"] = arr(expression);
  j["global_orient"] = arr(global_orient);
  if (body_pose.size()) j["body_pose"] = arr(body_pose);
  if (!jaw_pose.isZero(0)) j["jaw_pose"] = arr(jaw_pose);
  if (!leye_pose.isZero(0)) j["leye_pose"] = arr(leye_pose);
  if (!reye_pose.isZero(0)) j["reye_pose"] = arr(reye_pose);
  if (left_hand_pose.size()) j["left_hand_pose"] = arr(left_hand_pose);
  if (right_hand_pose.size()) j["right_hand_pose"] = arr(right_hand_pose);
  j["transl"] = arr(transl);
  return j;
}

Eigen::MatrixXd BodyParams::full_pose(const BodyModel& model) const {
  const int J = model.num_joints();
  const int nb = model.num_body_pose_joints();
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(J, 3);
  P.row(0) = global_orient.transpose();
  if (body_pose.size()) {
    check_len(body_pose, 3 * nb, "body_pose",
              std::string("3 per non-root body joint of the ") + model.kind_name() + " model");
    for (int k = 0; k < nb; ++k) P.row(1 + k) = body_pose.segment(3 * k, 3).transpose();
  }
  int hand0 = -1;
  if (model.kind == BodyKind::kSMPLX) {
    P.row(22) = jaw_pose.transpose();
    P.row(23) = leye_pose.transpose();
    P.row(24) = reye_pose.transpose();
    hand0 = 25;
  } else if (model.kind == BodyKind::kSMPLH) {
    hand0 = 22;
  } else if (left_hand_pose.size() || right_hand_pose.size() || !jaw_pose.isZero(0) ||
             !leye_pose.isZero(0) || !reye_pose.isZero(0)) {
    throw Error(std::string("params: hand / face poses given for a ") + model.kind_name() +
                " model, which has no such joints");
  }
  if (hand0 >= 0) {
    if (left_hand_pose.size()) {
      check_len(left_hand_pose, 45, "left_hand_pose", "15 hand joints");
      for (int k = 0; k < 15; ++k) P.row(hand0 + k) = left_hand_pose.segment(3 * k, 3).transpose();
    }
    if (right_hand_pose.size()) {
      check_len(right_hand_pose, 45, "right_hand_pose", "15 hand joints");
      for (int k = 0; k < 15; ++k)
        P.row(hand0 + 15 + k) = right_hand_pose.segment(3 * k, 3).transpose();
    }
  }
  return P;
}

// ---------------------------------------------------------------------------------------------
// Forward model

BodyState body_forward(const BodyModel& m, const BodyParams& params) {
  const int V = m.num_vertices(), J = m.num_joints();
  if (params.betas.size() > m.num_betas)
    throw Error("body_forward: " + std::to_string(params.betas.size()) +
                " betas for a model with " + std::to_string(m.num_betas));
  if (params.expression.size() > m.num_expression)
    throw Error("body_forward: " + std::to_string(params.expression.size()) +
                " expression coefficients for a model with " + std::to_string(m.num_expression));
  const Eigen::MatrixXd pose = params.full_pose(m);
  BodyState s;

  // Shape and expression blend shapes.
  Eigen::VectorXd coeffs = Eigen::VectorXd::Zero(m.shapedirs.cols());
  coeffs.head(params.betas.size()) = params.betas;
  coeffs.segment(m.num_betas, params.expression.size()) = params.expression;
  s.rest_vertices = m.v_template;
  if (!coeffs.isZero(0)) {
    const Eigen::VectorXd d = m.shapedirs * coeffs;
    for (int v = 0; v < V; ++v)
      for (int k = 0; k < 3; ++k) s.rest_vertices(v, k) += d[3 * v + k];
  }
  s.rest_joints = m.J_regressor * s.rest_vertices;

  // Forward kinematics and pose correctives.
  const PosedSkeleton<double> sk =
      forward_kinematics<double>(m.parents, s.rest_joints, pose, params.transl);
  const Eigen::VectorXd feat = pose_feature(sk.local);
  s.pose_offsets = Eigen::MatrixXd::Zero(V, 3);
  if (!m.posedirs_zero && !feat.isZero(0)) {
    // 3V x P (P = 9 (J - 1)): 34 MB of doubles for SMPL, read once a call; rows over the threads
    // (each row's sum is the same whatever the split).
    const long rows = long(m.posedirs.rows());
    constexpr long kRows = 2048;
    const long blocks = (rows + kRows - 1) / kRows;
    Eigen::VectorXd d(rows);
#pragma omp parallel for schedule(static) if (blocks > 4)
    for (long b = 0; b < blocks; ++b) {
      const long r0 = b * kRows, len = std::min(kRows, rows - r0);
      d.segment(r0, len).noalias() = m.posedirs.middleRows(r0, len) * feat;
    }
    for (int v = 0; v < V; ++v)
      for (int k = 0; k < 3; ++k) s.pose_offsets(v, k) = d[3 * v + k];
  }
  s.transforms = sk.transforms;
  s.joints = sk.joints;

  // Linear blend skinning. Joint-outer loop so the (column-major) weights are read contiguously.
  s.vertices.resize(V, 3);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(12, V);  // per-vertex blended 3x4 transform
  std::vector<Eigen::Matrix<double, 12, 1>> ts(static_cast<size_t>(J));
  for (int j = 0; j < J; ++j)
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 3; ++r) ts[size_t(j)][3 * c + r] = s.transforms[size_t(j)](r, c);
  // Blocks of vertices over the threads, each vertex's joints in order.
  constexpr int kVerts = 1024;
  const int vblocks = (V + kVerts - 1) / kVerts;
#pragma omp parallel for schedule(static) if (vblocks > 4)
  for (int b = 0; b < vblocks; ++b) {
    const int v0 = b * kVerts, v1 = std::min(V, v0 + kVerts);
    for (int j = 0; j < J; ++j) {
      const double* w = m.weights.col(j).data();
      for (int v = v0; v < v1; ++v)
        if (w[v] != 0.0) A.col(v) += w[v] * ts[size_t(j)];
    }
    for (int v = v0; v < v1; ++v) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 4>> M(A.col(v).data());
      const Eigen::Vector3d x = (s.rest_vertices.row(v) + s.pose_offsets.row(v)).transpose();
      s.vertices.row(v) = (M.leftCols<3>() * x + M.col(3)).transpose();
    }
  }
  return s;
}

}  // namespace ks

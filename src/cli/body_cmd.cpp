// `kinesplat body ...`: inspect, pose and generate body models.
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "body/body_model.hpp"
#include "cli/registry.hpp"
#include "core/error.hpp"
#include "core/fileio.hpp"
#include "mesh/trimesh.hpp"

namespace {

struct BodyOpts {
  std::string model, params, out, joints;
  int subdivide = 0;
};

nlohmann::json model_info(const ks::BodyModel& m) {
  nlohmann::json j;
  j["kind"] = m.kind_name();
  j["vertices"] = m.num_vertices();
  j["faces"] = m.faces.rows();
  j["joints"] = m.num_joints();
  j["num_betas"] = m.num_betas;
  j["num_expression"] = m.num_expression;
  j["body_pose_length"] = 3 * m.num_body_pose_joints();
  j["closed_manifold"] = ks::is_closed_manifold(m.faces, m.num_vertices());
  j["euler_characteristic"] = ks::euler_characteristic(m.faces, m.num_vertices());
  const Eigen::Vector3d lo = m.v_template.colwise().minCoeff(),
                        hi = m.v_template.colwise().maxCoeff();
  j["bbox_min"] = {lo.x(), lo.y(), lo.z()};
  j["bbox_max"] = {hi.x(), hi.y(), hi.z()};
  nlohmann::json parts = nlohmann::json::object();
  const auto counts = ks::part_vertex_counts(m.part_labels);
  for (int p = 0; p < ks::kNumParts; ++p)
    parts[std::string(ks::kPartNames[size_t(p)])] = counts[size_t(p)];
  j["parts"] = parts;
  j["joint_names"] = m.joint_names;
  j["parents"] = m.parents;
  return j;
}

ks::cli::CommandGroup group(10, [](CLI::App& app) {
  auto* body = app.add_subcommand("body", "Body models: inspect, pose, generate the default model");
  body->require_subcommand(1);
  auto opts = std::make_shared<BodyOpts>();

  auto* info = body->add_subcommand("info", "JSON summary of a body model (.npz or 'default')");
  info->add_option("MODEL", opts->model, "model .npz (smplx layout) or 'default'")->required();
  info->callback([opts] {
    const ks::BodyModel m = ks::load_body_model(opts->model);
    std::printf("%s\n", model_info(m).dump(2).c_str());
  });

  auto* pose = body->add_subcommand("pose", "Pose a body model and write an OBJ");
  pose->add_option("MODEL", opts->model, "model .npz (smplx layout) or 'default'")->required();
  pose->add_option("--params", opts->params, "PARAMS.json (betas, global_orient, body_pose, ...)");
  pose->add_option("--out", opts->out, "output .obj (vertices in the model's order)")->required();
  pose->add_option("--joints", opts->joints, "also write the posed joints as JSON");
  pose->add_option("--subdivide", opts->subdivide, "Loop subdivision levels applied after posing")
      ->check(CLI::Range(0, 3));
  pose->callback([opts] {
    const ks::BodyModel m = ks::load_body_model(opts->model);
    ks::BodyParams p;
    if (!opts->params.empty()) {
      const nlohmann::json j = ks::read_json(opts->params);
      static const char* known[] = {
          "betas",     "expression", "global_orient",  "body_pose",       "jaw_pose",
          "leye_pose", "reye_pose",  "left_hand_pose", "right_hand_pose", "transl"};
      if (j.is_object())
        for (const auto& [key, value] : j.items()) {
          bool ok = false;
          for (const char* k : known) ok = ok || key == k;
          if (!ok)
            std::fprintf(stderr, "warning: %s: ignoring unknown key '%s'\n", opts->params.c_str(),
                         key.c_str());
        }
      try {
        p = ks::BodyParams::from_json(j, m);
      } catch (const ks::Error& e) {
        throw ks::Error(opts->params + ": " + e.what());
      }
    }
    const ks::BodyState s = ks::body_forward(m, p);
    ks::TriMesh mesh{s.vertices, m.faces};
    if (opts->subdivide > 0) mesh = ks::subdivide(mesh, opts->subdivide, true).mesh;
    if (!opts->joints.empty()) {
      nlohmann::json jj;
      jj["joint_names"] = m.joint_names;
      nlohmann::json arr = nlohmann::json::array();
      for (int k = 0; k < m.num_joints(); ++k)
        arr.push_back({s.joints(k, 0), s.joints(k, 1), s.joints(k, 2)});
      jj["joints"] = arr;
      ks::write_json_atomic(opts->joints, jj);
    }
    ks::write_obj(opts->out, mesh.V, mesh.F);
    std::fprintf(stderr, "wrote %s (%d vertices, %d faces)\n", opts->out.c_str(),
                 int(mesh.V.rows()), int(mesh.F.rows()));
  });

  auto* mk = body->add_subcommand("make-default", "Generate the open default body model (.npz)");
  mk->add_option("--out", opts->out, "output .npz")->required();
  mk->callback([opts] {
    const auto t0 = std::chrono::steady_clock::now();
    const ks::BodyModel m = ks::make_default_body_model();
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ks::save_body_model(opts->out, m);
    std::fprintf(stderr, "wrote %s (%d vertices, %d faces, generated in %.2f s)\n",
                 opts->out.c_str(), m.num_vertices(), int(m.faces.rows()), secs);
  });
});

}  // namespace

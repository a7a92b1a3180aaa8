// `kinesplat render`: render a 3DGS .ply with a camera JSON to a PNG.
#include <cmath>
#include <sstream>
#include <string>

#include "cli/parse.hpp"
#include "cli/registry.hpp"
#include "core/camera.hpp"
#include "core/error.hpp"
#include "gaussians/ply.hpp"
#include "io/image_io.hpp"
#include "raster/rasterizer.hpp"

namespace {

struct Opts {
  std::string scene, camera, out, background = "0,0,0";
  int bits = 8;
};

void run(const Opts& o) {
  if (o.bits != 8 && o.bits != 16) throw ks::Error("--bits must be 8 or 16");
  ks::RasterSettings s;
  s.image_only = true;  // the colour is all it writes (the same image as a full forward's)
  ks::cli::parse_rgb(o.background, "--background", s.background);
  const ks::Camera cam = ks::Camera::load(o.camera);
  const ks::Gaussians g = ks::read_ply(o.scene);
  ks::RasterResult r;
  ks::rasterize_forward(g, cam, s, r);
  ks::write_png(o.out, r.color, o.bits);
}

ks::cli::CommandGroup group(600, [](CLI::App& app) {
  auto* sub = app.add_subcommand("render", "Render a 3DGS .ply scene with a camera to a PNG");
  auto o = std::make_shared<Opts>();
  sub->add_option("scene", o->scene, "3DGS .ply file")->required();
  sub->add_option("--camera", o->camera, "camera JSON (OpenCV pinhole, world-to-camera R|t)")
      ->required();
  sub->add_option("--out", o->out, "output PNG")->required();
  sub->add_option("--background", o->background, "background colour r,g,b in 0-1")
      ->capture_default_str();
  sub->add_option("--bits", o->bits, "bits per channel, 8 or 16")->capture_default_str();
  sub->callback([o] { run(*o); });
});

}  // namespace

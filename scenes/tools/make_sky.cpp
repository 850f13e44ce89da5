// Writes scenes/assets/sky.exr: an equirectangular HDR sky (docs/scene-format.md's mapping, +y up) with a small, very
// bright sun, for the project's sky scene and for hard-case tests of environment importance sampling.
//
// The sky is a smooth gradient from a bright horizon to a deeper zenith over a dim ground; the sun is a disc of
// angular radius `--sun-radius` degrees whose radiance is `--sun-ratio` times the sky's zenith radiance. Each pixel
// stores the average over its footprint (8 x 8 stratified sub-samples), so the disc's edge is anti-aliased and the
// sun's total power does not depend on the map's resolution.
#include "core/image/image.h"
#include "core/util/math.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>

namespace {

using tessera::kPi;
using tessera::Vec3;

// World direction of map coordinate (u, v) per docs/scene-format.md: theta = v pi from +y, phi = u 2 pi,
// phi = atan2(d.x, -d.z).
Vec3 direction(double u, double v) {
  const double theta = v * kPi, phi = u * 2.0 * kPi;
  return Vec3(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)), float(-std::sin(theta) * std::cos(phi)));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Writes an HDR sky with a sun as an equirectangular EXR"};
  std::string out = "scenes/assets/sky.exr";
  int width = 512;
  float sun_ratio = 1e4f, sun_radius_deg = 1.5f, sun_elevation_deg = 35.f, sun_azimuth_deg = 230.f;
  app.add_option("-o,--output", out, "EXR to write");
  app.add_option("--width", width, "Map width (height is half)")->check(CLI::Range(8, 16384));
  app.add_option("--sun-ratio", sun_ratio, "Sun radiance / zenith sky radiance")->check(CLI::PositiveNumber);
  app.add_option("--sun-radius", sun_radius_deg, "Angular radius of the sun disc, degrees")->check(CLI::Range(0.05, 20.0));
  app.add_option("--sun-elevation", sun_elevation_deg, "Sun elevation above the horizon, degrees")->check(CLI::Range(-90.0, 90.0));
  app.add_option("--sun-azimuth", sun_azimuth_deg, "Sun azimuth phi (docs/scene-format.md: atan2(d.x, -d.z)), degrees");
  CLI11_PARSE(app, argc, argv);

  const int height = width / 2;
  const double el = sun_elevation_deg * kPi / 180.0, az = sun_azimuth_deg * kPi / 180.0;
  const Vec3 sun = direction(az / (2.0 * kPi), (kPi / 2.0 - el) / kPi);
  const float cos_sun = std::cos(sun_radius_deg * kPi / 180.f);
  const Vec3 zenith(0.25f, 0.45f, 1.0f), horizon(1.0f, 0.95f, 0.9f), ground(0.18f, 0.16f, 0.14f);
  const Vec3 sun_radiance = sun_ratio * zenith.z * Vec3(1.0f, 0.92f, 0.8f);

  tessera::Image img = tessera::Image::make(width, height);
  constexpr int kSub = 8;
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      Vec3 sum(0.f);
      for (int sy = 0; sy < kSub; ++sy)
        for (int sx = 0; sx < kSub; ++sx) {
          const Vec3 d = direction((x + (sx + 0.5) / kSub) / width, (y + (sy + 0.5) / kSub) / height);
          Vec3 c;
          if (d.y >= 0.f) {
            const float t = std::pow(1.f - d.y, 3.f);  // mostly zenith colour, brightening towards the horizon
            c = glm::mix(zenith, horizon, t);
          } else {
            c = glm::mix(horizon, ground, std::min(1.f, -d.y * 8.f));
          }
          if (glm::dot(d, sun) >= cos_sun) c = sun_radiance;
          sum += c;
        }
      img.set(x, y, sum / float(kSub * kSub));
    }
  tessera::ExrWriteOptions opt;
  opt.metadata = {{"tessera:generator", "scenes/tools/make_sky"},
                  {"tessera:sunRatio", std::to_string(sun_ratio)},
                  {"tessera:sunRadiusDegrees", std::to_string(sun_radius_deg)}};
  try {
    tessera::write_exr(out, img, opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_sky: %s\n", e.what());
    return 1;
  }
  std::printf("%s: %dx%d, sun at elevation %.1f deg, radius %.2f deg, %.0fx the zenith\n", out.c_str(), width, height,
              sun_elevation_deg, sun_radius_deg, sun_ratio);
  return 0;
}

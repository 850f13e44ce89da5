#include "core/render/camera_frame.h"

#include "core/render/scene.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <limits>

namespace tessera {

CameraFrame camera_frame(const nlohmann::json& j) {
  CameraFrame f;
  f.origin = glm::dvec3(0.0, 0.0, 1.0);
  if (!j.is_object() || !j.contains("camera") || !j["camera"].is_object() || !j["camera"].contains("position"))
    return f;
  const nlohmann::json& p = j["camera"]["position"];
  if (!p.is_array() || p.size() != 3) return f;
  glm::dvec3 o;
  for (int i = 0; i < 3; ++i) {
    if (!p[size_t(i)].is_number()) return f;
    o[i] = p[size_t(i)].get<double>();
    if (!std::isfinite(o[i]) || !std::isfinite(float(o[i]))) return f;
  }
  f.origin = o;
  return f;
}

namespace {

// Distance between adjacent floats at magnitude m.
double float_spacing(double m) {
  const float f = float(std::min(m, double(std::numeric_limits<float>::max())));
  return double(std::nextafter(f, std::numeric_limits<float>::infinity())) - double(f);
}

double max_abs(const Vec3& p) { return std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}); }

}  // namespace

std::vector<std::string> precision_warnings(const Scene& s, const std::string& name) {
  size_t small = 0;
  double worst = std::numeric_limits<double>::infinity(), worst_distance = 0;
  const auto check = [&](double feature, double magnitude) {
    const double spacings = feature / float_spacing(magnitude);
    if (spacings >= kMinFeatureSpacings) return;
    ++small;
    if (spacings < worst) {
      worst = spacings;
      worst_distance = magnitude;
    }
  };
  for (const Triangle& t : s.triangles) {
    const double edge = std::sqrt(double(std::min({length_squared(t.p1 - t.p0), length_squared(t.p2 - t.p1),
                                                   length_squared(t.p0 - t.p2)})));
    check(edge, std::max({max_abs(t.p0), max_abs(t.p1), max_abs(t.p2)}));
  }
  for (const Sphere& sp : s.spheres) check(double(sp.radius), max_abs(sp.center) + double(sp.radius));
  if (small == 0) return {};
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%s: %zu primitive(s) have features (edges, radii) under %.0f float spacings at their distance from "
                "the camera (worst: %.2g spacings at %.3g units, spacing %.3g); far from the camera a float cannot "
                "keep them apart, so their shapes are rounded. Bring the camera closer or scale the scene up",
                name.c_str(), small, kMinFeatureSpacings, worst, worst_distance, float_spacing(worst_distance));
  return {buf};
}

}  // namespace tessera

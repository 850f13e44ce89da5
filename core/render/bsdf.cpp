#include "core/render/bsdf.h"

#include "core/render/fresnel.h"
#include "core/render/integrator.h"

#include <cmath>

namespace tessera {

Bsdf::Bsdf(const Material& m, const Vec3& ns, const Vec3& ng, const Vec3& reflectance)
    : kind_(m.kind), frame_(Frame::from_z(ns)), ng_(ng), reflectance_(reflectance), m_(&m),
      beckmann_{m.alpha_x, m.alpha_y} {}

Vec3 Bsdf::local(const Vec3& w, float side) const {
  Vec3 l = frame_.to_local(w);
  l.z *= side;
  return l;
}

Vec3 Bsdf::f(const Vec3& wo, const Vec3& wi) const {
  float pdf;
  return f(wo, wi, &pdf);
}

float Bsdf::pdf(const Vec3& wo, const Vec3& wi) const {
  float pdf;
  f(wo, wi, &pdf);
  return pdf;
}

Vec3 Bsdf::f(const Vec3& wo, const Vec3& wi, float* pdf) const {
  *pdf = 0.f;
  if (!same_side(wo, wi)) return Vec3(0.f);
  const float side = side_of(wo);
  // The local z of both directions (local()'s, to the bit) decides diffuse reflection; a lobe needs all of them.
  const float lo_z = glm::dot(wo, frame_.n) * side, li_z = glm::dot(wi, frame_.n) * side;
  if (!(lo_z > 0.f) || !(li_z > 0.f)) return Vec3(0.f);
  switch (kind_) {
    case MaterialKind::kDiffuse:
      if (side < 0.f && !m_->twosided) return Vec3(0.f);
      *pdf = li_z * kInvPi;
      return reflectance_ * kInvPi;
    case MaterialKind::kRoughConductor: {
      const Vec3 lo = local(wo, side), li = local(wi, side);
      const Vec3 m = glm::normalize(lo + li);
      const Vec3 F = fresnel_conductor(glm::dot(lo, m), m_->eta_t / m_->eta_i, m_->k / m_->eta_i);
      *pdf = beckmann_.pdf_m(m) / (4.f * glm::dot(lo, m));
      return reflectance_ * F * (beckmann_.D(m) * beckmann_.G(lo, li) / (4.f * lo.z * li.z));
    }
    default:
      return Vec3(0.f);
  }
}

std::optional<BSDFSample> Bsdf::sample(const Vec3& wo, float uc, Vec2 u) const {
  const Vec3 ns = frame_.n;
  switch (kind_) {
    case MaterialKind::kDiffuse:
    case MaterialKind::kRoughConductor: {
      const float side = side_of(wo);
      const Vec3 lo = local(wo, side);
      if (!(lo.z > 0.f)) return std::nullopt;
      Vec3 li;
      if (kind_ == MaterialKind::kDiffuse) {
        if (side < 0.f && !m_->twosided) return std::nullopt;
        li = sample_cosine_hemisphere(u);
      } else {
        const Vec3 m = beckmann_.sample_m(u);
        const float om = glm::dot(lo, m);
        if (!(om > 0.f)) return std::nullopt;
        li = 2.f * om * m - lo;
      }
      if (!(li.z > 0.f)) return std::nullopt;
      li.z *= side;
      const Vec3 wi = frame_.to_world(li);
      BSDFSample s{Vec3(0.f), wi, 0.f, false};
      s.f = f(wo, wi, &s.pdf);
      if (!(s.pdf > 0.f)) return std::nullopt;
      return s;
    }
    case MaterialKind::kRefraction: {
      Vec3 wi;
      if (!refract(wo, ns, m_->eta, &wi)) wi = reflect(wo, glm::dot(wo, ns) > 0.f ? ns : -ns);
      return BSDFSample{Vec3(1.f / std::abs(glm::dot(wi, ns))), wi, 1.f, true};
    }
    case MaterialKind::kGlass: {
      const float F = fresnel_dielectric(glm::dot(wo, ns), m_->eta);
      Vec3 wt;
      if (uc < F || !refract(wo, ns, m_->eta, &wt)) {
        const Vec3 wi = reflect(wo, glm::dot(wo, ns) > 0.f ? ns : -ns);
        // Under total internal reflection F = 1 (refract fails there too, whatever uc was).
        return BSDFSample{m_->reflect_tint * (F / std::abs(glm::dot(wi, ns))), wi, F, true};
      }
      return BSDFSample{m_->transmit_tint * ((1.f - F) / std::abs(glm::dot(wt, ns))), wt, 1.f - F, true};
    }
    case MaterialKind::kNone:
      break;
  }
  return std::nullopt;
}

}  // namespace tessera

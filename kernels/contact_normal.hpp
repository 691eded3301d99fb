// Normal contact laws. Each returns the elastic force magnitude and the damping coefficients of
// the contact, plus the tangential stiffness the history law uses, so that the step kernel is
// written once for both laws (the law is a template tag: no branch per contact).
#pragma once

#include "kernels/dem_types.hpp"

namespace pdsim {

struct NormalResponse {
  double elastic;            // N, repulsive elastic force
  double damping;            // N s/m, normal damping coefficient (Fn = elastic - damping * vn)
  double tangent_stiffness;  // N/m, Mindlin or linear tangential spring
  double tangent_damping;    // N s/m
};

// Linear spring-dashpot: Fn = k d + c vn, c = 2 sqrt(m* k)|ln e|/sqrt(pi^2 + ln^2 e)
// (restitution independent of impact speed); kt = 2/7 k (Silbert et al. 2001).
struct LinearNormal {
  static constexpr const char* name = "linear";
  PDSIM_HD static NormalResponse respond(double overlap, double, double mass_eff, bool,
                                         const ContactParams& p) {
    const double k = p.linear_stiffness;
    const double kt = p.tangential_ratio * k;
    return {k * overlap, p.damping_factor * sqrt(mass_eff * k), kt,
            p.damping_factor * sqrt(mass_eff * kt)};
  }
};

// Hertz with Tsuji damping: Fn = 4/3 E* sqrt(R*) d^1.5 - 2 sqrt(5/6) beta sqrt(Sn m*) vn,
// Sn = 2 E* sqrt(R* d); Mindlin kt = 8 G* sqrt(R* d) (Tsuji et al. 1992; LIGGGHTS hertz).
struct HertzNormal {
  static constexpr const char* name = "hertz";
  PDSIM_HD static NormalResponse respond(double overlap, double radius_eff, double mass_eff,
                                         bool wall, const ContactParams& p) {
    const double contact_radius = sqrt(radius_eff * overlap);
    const double modulus = wall ? p.hertz_modulus_pw : p.hertz_modulus_pp;
    const double shear = wall ? p.shear_modulus_pw : p.shear_modulus_pp;
    const double sn = 2.0 * modulus * contact_radius;
    const double kt = 8.0 * shear * contact_radius;
    return {(2.0 / 3.0) * sn * overlap, p.damping_factor * sqrt(sn * mass_eff), kt,
            p.damping_factor * sqrt(kt * mass_eff)};
  }
};

}  // namespace pdsim

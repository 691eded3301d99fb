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
  static constexpr double kEnergyRatio = 0.5;  // spring energy / (elastic force x overlap)
  PDSIM_HD static NormalResponse respond(double overlap, double, double mass_eff, bool,
                                         const ContactParams& p) {
    const double k = p.linear_stiffness;
    const double kt = p.tangential_ratio * k;
    return {k * overlap, p.damping_factor * sqrt(mass_eff * k), kt,
            p.damping_factor * sqrt(mass_eff * kt)};
  }
};

// Hertz with Tsuji damping: Fn = 4/3 E* sqrt(R*) d^1.5 - 2 sqrt(5/6) beta sqrt(Sn m*) vn,
// Sn = 2 E* a with a = sqrt(R* d); Mindlin kt = 8 G* a, damped by 2 sqrt(5/6) beta sqrt(kt m*)
// (Tsuji et al. 1992; LIGGGHTS hertz). Both dampings are a constant times sqrt(a m*): two roots
// per contact instead of three.
struct HertzNormal {
  static constexpr const char* name = "hertz";
  static constexpr double kEnergyRatio = 0.4;  // U = 8/15 E* sqrt(R*) d^2.5 = 2/5 Fn d
  PDSIM_HD static NormalResponse respond(double overlap, double radius_eff, double mass_eff,
                                         bool wall, const ContactParams& p) {
    const double contact_radius = sqrt(radius_eff * overlap);
    const double root = sqrt(contact_radius * mass_eff);
    const double modulus = wall ? p.hertz_modulus_pw : p.hertz_modulus_pp;
    const double shear = wall ? p.shear_modulus_pw : p.shear_modulus_pp;
    return {(4.0 / 3.0) * modulus * contact_radius * overlap,
            (wall ? p.normal_root_pw : p.normal_root_pp) * root, 8.0 * shear * contact_radius,
            (wall ? p.tangent_root_pw : p.tangent_root_pp) * root};
  }
};

// `p` with the Hertz damping constants derived from its moduli and damping factor.
inline ContactParams with_damping_roots(ContactParams p) {
  p.normal_root_pp = p.damping_factor * std::sqrt(2.0 * p.hertz_modulus_pp);
  p.normal_root_pw = p.damping_factor * std::sqrt(2.0 * p.hertz_modulus_pw);
  p.tangent_root_pp = p.damping_factor * std::sqrt(8.0 * p.shear_modulus_pp);
  p.tangent_root_pw = p.damping_factor * std::sqrt(8.0 * p.shear_modulus_pw);
  return p;
}

}  // namespace pdsim

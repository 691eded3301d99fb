// Hertz with Tsuji damping: Fn = 4/3 E* sqrt(R*) d^1.5 - 2 sqrt(5/6) beta sqrt(Sn m*) vn,
// Sn = 2 E* a with a = sqrt(R* d); Mindlin kt = 8 G* a, damped by 2 sqrt(5/6) beta sqrt(kt m*)
// (Tsuji et al. 1992; LIGGGHTS hertz). All of it: the kernels' response, its constants from
// the deck, its time step and its deck keys.
#pragma once

#include <cmath>

#include "kernels/normal_law.hpp"

namespace pdsim {

// Restitution-consistent damping factor (Tsuji et al., Powder Technol. 71, 1992):
// c = factor sqrt(Sn m*).
inline double hertz_damping_factor(double restitution) {
  const double l = std::log(restitution);
  const double beta = l / std::sqrt(l * l + kPi * kPi);
  return -2.0 * std::sqrt(5.0 / 6.0) * beta;
}

// Hertz-Mindlin constants of one material on both sides of every contact (particle-particle and
// particle-wall): E* = E / (2 (1 - nu^2)), G* = G / (2 (2 - nu)), G = E / (2 (1 + nu)).
inline ContactParams hertz_contact(double young, double poisson, double restitution,
                                   double friction) {
  ContactParams p;
  p.damping_factor = hertz_damping_factor(restitution);
  p.hertz_modulus_pp = p.hertz_modulus_pw = young / (2 * (1 - poisson * poisson));
  const double shear = young / (2 * (1 + poisson));
  p.shear_modulus_pp = p.shear_modulus_pw = shear / (2 * (2 - poisson));
  p.friction = friction;
  return p;
}

// Rayleigh time pi r sqrt(rho/G) / (0.1631 nu + 0.8766).
inline double rayleigh_time(double radius, double density, double young, double poisson) {
  const double shear = young / (2 * (1 + poisson));
  return kPi * radius * std::sqrt(density / shear) / (0.1631 * poisson + 0.8766);
}

struct HertzNormal {
  static constexpr const char* name = "hertz";
  static constexpr double kEnergyRatio = 0.4;  // U = 8/15 E* sqrt(R*) d^2.5 = 2/5 Fn d
  // Both dampings are a constant times sqrt(a m*): two roots per contact instead of three.
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

  template <class Spec>
  static ContactParams params(const Spec& c) {
    return hertz_contact(c.young, c.poisson, c.restitution, c.friction);
  }
  // dt: 0.15 of the Rayleigh time of the smallest particle, limit 0.4 of it; the contact time
  // of a binary impact at 1 m/s, 2.87 (m*^2 / (R* E*^2 v))^(1/5) (Johnson 1985), for check.
  template <class Spec>
  static TimeStepRule time_step(const Spec& c, const ContactParams& p, double r_min,
                                double density_min, double mass_min) {
    TimeStepRule t;
    t.rayleigh_time = rayleigh_time(r_min, density_min, c.young, c.poisson);
    const double e_star = p.hertz_modulus_pp;
    t.contact_time =
        2.87 * std::pow(std::pow(0.5 * mass_min, 2) / (0.5 * r_min * e_star * e_star), 0.2);
    t.basis_time = t.rayleigh_time;
    t.basis = "Rayleigh time";
    t.default_safety = 0.15;
    t.dt_limit = 0.4 * t.rayleigh_time;
    t.contact_note = " (Hertz, binary impact at 1 m/s)";
    return t;
  }
  template <class Spec>
  static MissingKey missing(const Spec& c) {
    return c.young == 0 ? MissingKey{"young", "a positive number (Pa)"} : MissingKey{};
  }
};

}  // namespace pdsim

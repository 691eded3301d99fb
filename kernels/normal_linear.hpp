// The linear spring-dashpot normal law: Fn = k d + c vn, c = 2 sqrt(m* k)|ln e|/sqrt(pi^2 +
// ln^2 e) (restitution independent of impact speed); kt = 2/7 k (Silbert et al. 2001). All of
// it: the kernels' response, its constants from the deck, its time step and its deck keys.
#pragma once

#include <cmath>

#include "kernels/normal_law.hpp"

namespace pdsim {

// Restitution-consistent damping factor (e independent of impact speed): c = factor sqrt(m* k).
inline double linear_damping_factor(double restitution) {
  const double l = std::log(restitution);
  return 2.0 * std::fabs(l) / std::sqrt(kPi * kPi + l * l);
}

// Exact contact time of the linear spring-dashpot: pi / sqrt(k/m* - (c/2m*)^2).
inline double linear_contact_time(double stiffness, double mass_eff, double restitution) {
  const double c = linear_damping_factor(restitution) * std::sqrt(mass_eff * stiffness);
  const double half = c / (2 * mass_eff);
  return kPi / std::sqrt(stiffness / mass_eff - half * half);
}

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

  // The kernels' constants from the deck's [contact] (a ContactSpec, kernels/contact_laws.hpp).
  template <class Spec>
  static ContactParams params(const Spec& c) {
    ContactParams p;
    p.linear_stiffness = c.stiffness;
    p.damping_factor = linear_damping_factor(c.restitution);
    p.friction = c.friction;
    return p;
  }
  // dt: 0.02 of the exact contact time of the lightest pair (mass_min each), limit 1/8 of it.
  template <class Spec>
  static TimeStepRule time_step(const Spec& c, const ContactParams&, double, double,
                                double mass_min) {
    TimeStepRule t;
    t.contact_time = linear_contact_time(c.stiffness, 0.5 * mass_min, c.restitution);
    t.basis_time = t.contact_time;
    t.basis = "linear contact time";
    t.default_safety = 0.02;
    t.dt_limit = t.contact_time / 8;
    return t;
  }
  template <class Spec>
  static MissingKey missing(const Spec& c) {
    return c.stiffness == 0 ? MissingKey{"stiffness", "a positive number (N/m)"} : MissingKey{};
  }
};

}  // namespace pdsim

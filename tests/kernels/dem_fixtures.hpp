// Shared set-ups for the DEM engine tests: steel spheres, contact constants built from the
// laws' restitution-consistent dampings (kernels/normal_linear.hpp, kernels/normal_hertz.hpp)
// and a driver that follows one impact step by step with the container at rest at the origin.
#pragma once

#include <cmath>
#include <stdexcept>
#include <vector>

#include "kernels/engine.hpp"
#include "src/scene.hpp"

namespace pdsim::fixtures {

constexpr double kSteelDensity = 7800.0;  // kg/m^3
constexpr double kSteelYoung = 2.0e11;    // Pa
constexpr double kSteelPoisson = 0.3;

inline double ball_mass(double radius, double density) {
  return density * 4.0 / 3.0 * kPi * radius * radius * radius;
}

inline ContactParams linear_contact(double stiffness, double restitution, double friction) {
  ContactParams p;
  p.linear_stiffness = stiffness;
  p.damping_factor = linear_damping_factor(restitution);
  p.friction = friction;
  return p;
}

// Undamped Hertz impact duration at approach speed v (Johnson 1985, Contact Mechanics, ch. 11):
// t_c = 2.868 (m*^2 / (R* E*^2 v))^(1/5).
inline double hertz_contact_time(double mass_eff, double radius_eff, double modulus, double speed) {
  return 2.868 *
         std::pow(mass_eff * mass_eff / (radius_eff * modulus * modulus * speed), 1.0 / 5.0);
}

// Steel spheres in a box of half edges `half_size` centred at the origin; no gravity, one thread.
inline EngineConfig steel_box(Vec3 half_size, NormalModel normal, TangentialModel tangential,
                              const ContactParams& contact, double dt_s) {
  EngineConfig c;
  c.backend = Backend::cpu;
  c.threads = 1;
  c.shape = WallShape::box;
  c.geometry.half_size = half_size;
  c.density = kSteelDensity;
  c.normal = normal;
  c.tangential = tangential;
  c.contact = contact;
  c.dt = dt_s;
  return c;
}

inline void add_particle(EngineConfig& c, double radius, Vec3 position, Vec3 velocity,
                         Vec3 spin = {}) {
  c.radius.push_back(radius);
  c.particles.push_back({position, velocity, spin});
}

// One step with the container at rest at the origin.
inline const StepTotals& step(DemEngine& engine, double dt_s) {
  const StepTotals& totals = engine.compute(ContainerKinematics{}, dt_s);
  engine.accept();
  return totals;
}

struct ImpactRecord {
  std::vector<ParticleState> before, after;  // last state before the contact, first after it
  int steps_in_contact = 0;
  double contact_time = 0;  // s, between the zero crossings of the interpolated overlap
  double max_overlap = 0;   // m
  double dissipated_normal = 0, dissipated_tangential = 0;  // J, summed over the steps
};

// Steps until the bodies have touched and separated again; `overlap(particles)` is positive
// while they touch. Linear interpolation of the overlap between steps places the start and
// the end of the contact to O(dt^2), so the contact time is not quantised to whole steps.
template <class Overlap>
ImpactRecord follow_impact(DemEngine& engine, double dt_s, Overlap overlap, int max_steps) {
  ImpactRecord r;
  r.before = engine.particles();
  double previous = overlap(r.before);
  if (previous > 0) throw std::logic_error("follow_impact: the bodies start in contact");
  double start = -1;
  for (int n = 1; n <= max_steps; ++n) {
    const StepTotals& totals = step(engine, dt_s);
    r.dissipated_normal += totals.tally.normal;
    r.dissipated_tangential += totals.tally.tangential;
    std::vector<ParticleState> now = engine.particles();
    const double current = overlap(now);
    const double crossing = (n - 1 + previous / (previous - current)) * dt_s;
    if (current > 0) {
      if (start < 0) start = crossing;
      ++r.steps_in_contact;
      r.max_overlap = std::fmax(r.max_overlap, current);
    } else if (start >= 0) {
      r.contact_time = crossing - start;
      r.after = std::move(now);
      return r;
    } else {
      r.before = std::move(now);
    }
    previous = current;
  }
  throw std::logic_error("follow_impact: the impact did not end within max_steps");
}

}  // namespace pdsim::fixtures

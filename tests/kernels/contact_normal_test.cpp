// Normal contact laws (kernels/contact_normal.hpp) through the engine: head-on binary and wall
// impacts against the closed-form restitution and contact time (linear: the damped oscillator;
// Hertz: Tsuji et al. 1992 damping, Johnson 1985 contact time).
//
// The linear dashpot force jumps to c v at the first and last step of a contact, so the
// measured restitution carries an O(dt/tc) error (about 2e-2 x e at dt = tc/100, ten times less
// at tc/1000); the Tsuji dashpot vanishes with the overlap and converges faster (its continuous
// solution returns the deck e to 1e-7, by RK4 integration of the Hertz-Tsuji law). Each case runs
// at both resolutions: the coarse bound is what production steps give, the fine bound shows
// convergence to the exact value. A wrong damping formula (e.g. sqrt(5/6) missing in Tsuji's
// form, or ln^2 e missing under the root) moves e by 2e-2 to 3e-2 and fails both.
#include "kernels/contact_normal.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <functional>

#include "tests/kernels/dem_fixtures.hpp"
#include "tests/support/validation_row.hpp"

namespace pdsim {
namespace {

using namespace fixtures;

constexpr double kRadius = 2.5e-3;    // m, a 5 mm steel ball
constexpr double kStiffness = 1.0e5;  // N/m, linear law
constexpr double kHalfBox = 0.05;     // m, walls far from the pair

// Surface gap before the impact: at most 0.37 R and at most 371.83 steps of approach, so that
// slow impacts at fine steps stay cheap and the contact starts at an arbitrary phase of a step.
double initial_gap(double speed, double dt_s) {
  return std::fmin(0.37 * kRadius, 371.83 * speed * dt_s);
}

struct Impact {
  double restitution;     // -v_rel_after / v_rel_before along the normal
  double contact_time;    // s
  double momentum_error;  // |p_after - p_before| / |p_before| (pair only)
  double energy_balance;  // (kinetic loss - sum of dissipated_normal) / kinetic loss
};

double kinetic(const std::vector<ParticleState>& p, double mass) {
  double sum = 0;
  for (const auto& q : p) sum += 0.5 * mass * dot(q.velocity, q.velocity);
  return sum;
}

Impact measured(const ImpactRecord& r, double restitution, double mass, double v_rel_after,
                double v_rel_before) {
  Impact out{-v_rel_after / v_rel_before, r.contact_time, 0, 0};
  const double loss = kinetic(r.before, mass) - kinetic(r.after, mass);
  if (restitution < 1) out.energy_balance = (loss - r.dissipated_normal) / loss;
  return out;
}

// Sphere A at `speed` along +x hits sphere B at rest, far from the walls.
Impact pair_impact(NormalModel normal, const ContactParams& contact, double restitution,
                   double speed, double dt_s) {
  EngineConfig c =
      steel_box({kHalfBox, kHalfBox, kHalfBox}, normal, TangentialModel::none, contact, dt_s);
  const double gap = initial_gap(speed, dt_s);
  add_particle(c, kRadius, {-kRadius - 0.5 * gap, 0, 0}, {speed, 0, 0});
  add_particle(c, kRadius, {kRadius + 0.5 * gap, 0, 0}, {});
  auto engine = make_engine(c);
  const auto overlap = [](const std::vector<ParticleState>& p) {
    return 2 * kRadius - norm(p[1].position - p[0].position);
  };
  const ImpactRecord r = follow_impact(*engine, dt_s, overlap, 100000);
  const double mass = ball_mass(kRadius, kSteelDensity);
  Impact out = measured(r, restitution, mass, r.after[0].velocity.x - r.after[1].velocity.x,
                        r.before[0].velocity.x - r.before[1].velocity.x);
  const Vec3 p_before = mass * (r.before[0].velocity + r.before[1].velocity);
  const Vec3 p_after = mass * (r.after[0].velocity + r.after[1].velocity);
  out.momentum_error = norm(p_after - p_before) / norm(p_before);
  return out;
}

// Sphere falls at `speed` onto the floor z = -kHalfBox (no gravity).
Impact wall_impact(NormalModel normal, const ContactParams& contact, double restitution,
                   double speed, double dt_s) {
  EngineConfig c =
      steel_box({kHalfBox, kHalfBox, kHalfBox}, normal, TangentialModel::none, contact, dt_s);
  const double gap = initial_gap(speed, dt_s);
  add_particle(c, kRadius, {0.01, -0.02, -kHalfBox + kRadius + gap}, {0, 0, -speed});
  auto engine = make_engine(c);
  const auto overlap = [](const std::vector<ParticleState>& p) {
    return kRadius - (p[0].position.z + kHalfBox);
  };
  const ImpactRecord r = follow_impact(*engine, dt_s, overlap, 100000);
  return measured(r, restitution, ball_mass(kRadius, kSteelDensity), r.after[0].velocity.z,
                  r.before[0].velocity.z);
}

struct Resolution {
  double steps_per_contact;
  double restitution_tolerance;   // absolute
  double contact_time_tolerance;  // relative
  double energy_tolerance;        // relative
};

TEST_CASE("linear law: restitution and contact time of binary and wall impacts") {
  const double mass = ball_mass(kRadius, kSteelDensity);
  double worst_e = 0, worst_tc = 0;  // at 1000 steps a contact
  for (const Resolution res :
       {Resolution{100, 1e-2, 1e-2, 2e-2}, Resolution{1000, 1e-3, 1e-3, 2e-3}})
    for (bool wall : {false, true})
      for (double e : {0.3, 0.6, 0.9})
        for (double speed : {0.1, 1.0, 5.0}) {
          CAPTURE(res.steps_per_contact);
          CAPTURE(wall);
          CAPTURE(e);
          CAPTURE(speed);
          const double mass_eff = wall ? mass : 0.5 * mass;
          const double tc = linear_contact_time(kStiffness, mass_eff, e);
          const double dt = tc / res.steps_per_contact;
          const ContactParams contact = linear_contact(kStiffness, e, 0);
          const Impact r = wall ? wall_impact(NormalModel::linear, contact, e, speed, dt)
                                : pair_impact(NormalModel::linear, contact, e, speed, dt);
          CHECK(std::fabs(r.restitution - e) < res.restitution_tolerance);
          CHECK(std::fabs(r.contact_time / tc - 1) < res.contact_time_tolerance);
          CHECK(std::fabs(r.energy_balance) < res.energy_tolerance);
          // Each particle computes its half of the pair force: antisymmetric to the last bit.
          if (!wall) CHECK(r.momentum_error < 1e-13);
          if (res.steps_per_contact == 1000) {
            worst_e = std::max(worst_e, std::fabs(r.restitution - e));
            worst_tc = std::max(worst_tc, std::fabs(r.contact_time / tc - 1));
          }
        }
  validation_bound("linear law, pair and wall impacts, e 0.3-0.9, 0.1-5 m/s: largest |e - e_set|",
                   "the law's restitution (closed form)", 1e-3, worst_e, "");
  validation_bound("linear law, pair and wall impacts: largest |t_c / t_c,exact - 1|",
                   "the damped oscillator's contact time (closed form)", 1e-3, worst_tc, "");
}

TEST_CASE("hertz law with Tsuji damping: velocity-independent restitution, Hertz contact time") {
  const double mass = ball_mass(kRadius, kSteelDensity);
  double worst_e = 0, worst_tc = 0;  // at 1000 steps a contact
  for (const Resolution res :
       {Resolution{100, 5e-3, 5e-4, 2e-2}, Resolution{1000, 5e-4, 5e-4, 2e-3}})
    for (bool wall : {false, true})
      for (double e : {0.3, 0.6, 0.9, 1.0})
        for (double speed : {0.1, 1.0, 5.0}) {
          CAPTURE(res.steps_per_contact);
          CAPTURE(wall);
          CAPTURE(e);
          CAPTURE(speed);
          const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, e, 0);
          const double tc =
              wall ? hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, speed)
                   : hertz_contact_time(0.5 * mass, 0.5 * kRadius, contact.hertz_modulus_pp, speed);
          const double dt = tc / res.steps_per_contact;
          const Impact r = wall ? wall_impact(NormalModel::hertz, contact, e, speed, dt)
                                : pair_impact(NormalModel::hertz, contact, e, speed, dt);
          CHECK(std::fabs(r.restitution - e) < res.restitution_tolerance);
          CHECK(std::fabs(r.energy_balance) < res.energy_tolerance);
          if (!wall) CHECK(r.momentum_error < 1e-13);
          // Johnson's time is for the undamped contact (2.868 is rounded to 4 digits).
          if (e == 1.0) CHECK(std::fabs(r.contact_time / tc - 1) < res.contact_time_tolerance);
          if (res.steps_per_contact == 1000) {
            worst_e = std::max(worst_e, std::fabs(r.restitution - e));
            if (e == 1.0) worst_tc = std::max(worst_tc, std::fabs(r.contact_time / tc - 1));
          }
        }
  validation_bound(
      "Hertz-Tsuji law, pair and wall impacts, e 0.3-1, 0.1-5 m/s: largest |e - e_set|",
      "Tsuji's velocity-independent restitution", 5e-4, worst_e, "");
  validation_bound("Hertz law, elastic impacts: largest |t_c / t_c,Hertz - 1|",
                   "Hertz contact time (Johnson 1985)", 5e-4, worst_tc, "");
}

TEST_CASE("linear law: the normal tally is the dashpot's work over the discrete trajectory") {
  // The engine advances x' = x + dt v' with v' = v + dt F(x, v) / m: the force at step n acts
  // while the bodies move from the previous step's midpoint to this one's, dt (v_n + v_n+1)/2
  // (the displacement whose work changes 1/2 m v^2 exactly). The dashpot's work, summed from
  // the recorded states, is the scheme's exact loss; the former tally c vn^2 dt was 1.2 to 7.2 %
  // high at 20 steps per contact, 0.13 to 1.2 % at 100.
  const double mass = ball_mass(kRadius, kSteelDensity), speed = 1.0;
  for (bool wall : {false, true})
    for (double e : {0.3, 0.6, 0.9})
      for (double steps_per_contact : {20.0, 100.0}) {
        CAPTURE(wall);
        CAPTURE(e);
        CAPTURE(steps_per_contact);
        const double mass_eff = wall ? mass : 0.5 * mass;
        const double dt = linear_contact_time(kStiffness, mass_eff, e) / steps_per_contact;
        const ContactParams contact = linear_contact(kStiffness, e, 0);
        EngineConfig c = steel_box({kHalfBox, kHalfBox, kHalfBox}, NormalModel::linear,
                                   TangentialModel::none, contact, dt);
        // The bodies' separation along the normal, its rate, and the overlap.
        using State = std::vector<ParticleState>;
        std::function<double(const State&)> separation, rate, overlap;
        if (wall) {
          add_particle(c, kRadius, {0, 0, -kHalfBox + kRadius + 10.3 * speed * dt}, {0, 0, -speed});
          separation = [](const State& p) { return p[0].position.z; };
          rate = [](const State& p) { return p[0].velocity.z; };
          overlap = [&](const State& p) { return kRadius - (separation(p) + kHalfBox); };
        } else {
          add_particle(c, kRadius, {-kRadius - 5.15 * speed * dt, 0, 0}, {speed, 0, 0});
          add_particle(c, kRadius, {kRadius + 5.15 * speed * dt, 0, 0}, {});
          separation = [](const State& p) { return p[1].position.x - p[0].position.x; };
          rate = [](const State& p) { return p[1].velocity.x - p[0].velocity.x; };
          overlap = [&](const State& p) { return 2 * kRadius - separation(p); };
        }
        auto engine = make_engine(c);
        std::vector<State> states{engine->particles()};
        double tally = 0;
        for (int n = 0; n < 40 + 2 * static_cast<int>(steps_per_contact); ++n) {
          tally += step(*engine, dt).tally.normal;
          states.push_back(engine->particles());
        }
        const double damping = contact.damping_factor * std::sqrt(mass_eff * kStiffness);
        double work = 0;
        for (std::size_t n = 1; n + 1 < states.size(); ++n) {
          if (overlap(states[n]) <= 0) continue;
          const double vn = rate(states[n]);
          work += damping * vn * 0.5 * (separation(states[n + 1]) - separation(states[n - 1]));
        }
        REQUIRE(overlap(states.back()) < 0);  // the impact is over
        CHECK(work > 0.05 * 0.5 * mass_eff * speed * speed);
        CHECK(std::fabs(tally - work) <= 1e-9 * work);
      }
}

TEST_CASE("the step is velocity Verlet as LAMMPS runs it: same trajectory, second order") {
  // LAMMPS's velocity Verlet (fix nve): v += dt/2 F/m; x += dt v; F = F(x, v) with the
  // half-step v; v += dt/2 F/m. Written here for a Hertz-Tsuji pair (kernels/normal_hertz.hpp),
  // it is a second-order step; the engine's semi-implicit Euler (v += dt F/m, x += dt v) must
  // follow the same positions, its stored velocity the half-step one and the full-step velocity
  // the mean of two stored ones. An Euler step that moved x before v would miss by dt times the
  // velocity change a step, 1e-3 of the overlap at 50 steps a contact.
  const double mass = ball_mass(kRadius, kSteelDensity), speed = 1.0, e = 0.6;
  const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, e, 0);
  const double modulus = contact.hertz_modulus_pp, radius_eff = 0.5 * kRadius;
  const double mass_eff = 0.5 * mass;
  const double beta = std::log(e) / std::sqrt(std::log(e) * std::log(e) + kPi * kPi);
  const double tc = hertz_contact_time(mass_eff, radius_eff, modulus, speed);
  // Repulsive force of the pair at overlap d, overlap rate dd (> 0 approaching).
  const auto force = [&](double d, double dd) {
    if (d <= 0) return 0.0;
    const double stiffness = 2 * modulus * std::sqrt(radius_eff * d);  // Sn
    return 4.0 / 3.0 * modulus * std::sqrt(radius_eff) * std::pow(d, 1.5) -
           2 * std::sqrt(5.0 / 6.0) * beta * std::sqrt(stiffness * mass_eff) * dd;
  };
  std::vector<double> balance;  // (kinetic loss - normal tally) / kinetic loss, per dt
  double worst_relative = 0;    // largest position difference / deepest overlap
  for (double steps_per_contact : {25.0, 50.0, 100.0, 200.0}) {
    CAPTURE(steps_per_contact);
    const double dt = tc / steps_per_contact;
    EngineConfig c = steel_box({kHalfBox, kHalfBox, kHalfBox}, NormalModel::hertz,
                               TangentialModel::none, contact, dt);
    const double gap = 7.3 * speed * dt;
    add_particle(c, kRadius, {-kRadius - 0.5 * gap, 0, 0}, {speed, 0, 0});
    add_particle(c, kRadius, {kRadius + 0.5 * gap, 0, 0}, {});
    auto engine = make_engine(c);
    double x[2] = {-kRadius - 0.5 * gap, kRadius + 0.5 * gap}, v[2] = {speed, 0};
    double f = 0;  // on body 1, along +x (apart at the start)
    double previous_v[2] = {speed, 0};
    double worst_x = 0, worst_v = 0, deepest = 0, tally = 0;
    std::vector<ParticleState> before = engine->particles(), now = before;
    const int steps = 20 + 2 * static_cast<int>(steps_per_contact);
    for (int n = 0; n < steps; ++n) {
      v[0] -= 0.5 * dt * f / mass;
      v[1] += 0.5 * dt * f / mass;
      x[0] += dt * v[0];
      x[1] += dt * v[1];
      f = force(2 * kRadius - (x[1] - x[0]), v[0] - v[1]);
      v[0] -= 0.5 * dt * f / mass;  // full-step velocities
      v[1] += 0.5 * dt * f / mass;
      tally += step(*engine, dt).tally.normal;
      const std::vector<ParticleState> next = engine->particles();
      deepest = std::max(deepest, 2 * kRadius - (x[1] - x[0]));
      for (int i = 0; i < 2; ++i) {
        worst_x = std::max(worst_x, std::fabs(next[i].position.x - x[i]));
        // Velocity Verlet's full-step velocity after n steps is the mean of the engine's
        // stored velocities after n and n + 1 steps: compared one step late.
        worst_v = std::max(
            worst_v, std::fabs(0.5 * (now[i].velocity.x + next[i].velocity.x) - previous_v[i]));
        previous_v[i] = v[i];
      }
      now = next;
    }
    REQUIRE(deepest > 1e-7);
    REQUIRE(2 * kRadius < x[1] - x[0]);  // the impact is over
    CHECK(worst_x < 1e-9 * deepest);
    worst_relative = std::max(worst_relative, worst_x / deepest);
    CHECK(worst_v < 1e-9 * speed);
    const double loss = kinetic(before, mass) - kinetic(now, mass);
    balance.push_back((loss - tally) / loss);
    MESSAGE("steps a contact " << steps_per_contact << ": largest position difference "
                               << worst_x / deepest << " of the overlap, energy balance "
                               << balance.back());
  }
  // The tally counts the dashpot's work at the mid-step velocity: what is left is the step's
  // own error, second order: each halving of dt divides it by about 4 (measured 4.0-4.3).
  for (std::size_t k = 0; k + 1 < balance.size(); ++k) {
    CHECK(balance[k] > 0);
    CHECK(balance[k] / balance[k + 1] > 3.5);
    CHECK(balance[k] / balance[k + 1] < 4.6);
  }
  const double order = std::log2(balance.front() / balance.back()) / 3;  // 3 halvings
  validation_bound(
      "Hertz-Tsuji pair impact, 25-200 steps a contact: largest position difference "
      "from velocity Verlet, over the deepest overlap",
      "LAMMPS's velocity Verlet (fix nve), from the Hertz-Tsuji law", 1e-9, worst_relative, "");
  validation_row(
      "Hertz-Tsuji pair impact, e 0.6: order in dt of the energy balance, 25-200 steps "
      "a contact",
      "velocity Verlet is a second-order step", 2.0, order, 0.1, "");
}

}  // namespace
}  // namespace pdsim

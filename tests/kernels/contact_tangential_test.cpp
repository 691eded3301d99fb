// Tangential contact laws (kernels/contact_tangential.hpp) through the engine: oblique impacts
// of a sphere on the floor against rigid-body impulse theory (Maw, Barber & Fawcett 1976).
#include "kernels/contact_tangential.hpp"

#include <doctest/doctest.h>

#include <cmath>

#include "tests/kernels/dem_fixtures.hpp"

namespace pdsim {
namespace {

using namespace fixtures;

constexpr double kRadius = 2.5e-3;  // m
constexpr double kHalfBox = 0.05;   // m
constexpr double kFriction = 0.3;
constexpr double kRestitution = 0.9;  // see the gross-sliding case

struct Oblique {
  double normal_speed_after;      // m/s, rebound speed along +z
  double tangential_speed_after;  // m/s, centre velocity along x
  double spin_after;              // rad/s, about y (positive reduces the slip at the contact)
  double slip_after;              // m/s, contact-point velocity v_x - omega_y R
};

// Sphere hits the floor (z = -kHalfBox) with normal speed vn and tangential speed vt along x.
Oblique floor_impact(NormalModel normal, TangentialModel tangential, double vn, double vt) {
  const ContactParams contact =
      normal == NormalModel::hertz
          ? hertz_contact(kSteelYoung, kSteelPoisson, kRestitution, kFriction)
          : linear_contact(1e5, kRestitution, kFriction);
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double tc = normal == NormalModel::hertz
                        ? hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, vn)
                        : linear_contact_time(contact.linear_stiffness, mass, kRestitution);
  const double dt = tc / 200;
  EngineConfig c = steel_box({kHalfBox, kHalfBox, kHalfBox}, normal, tangential, contact, dt);
  const double gap = 0.2 * kRadius;
  add_particle(c, kRadius, {-0.02, 0, -kHalfBox + kRadius + gap}, {vt, 0, -vn});
  auto engine = make_engine(c);
  const auto overlap = [](const std::vector<ParticleState>& p) {
    return kRadius - (p[0].position.z + kHalfBox);
  };
  const ImpactRecord r =
      follow_impact(*engine, dt, overlap, static_cast<int>(gap / vn / dt) + 1000000);
  const ParticleState& a = r.after[0];
  return {a.velocity.z, a.velocity.x, a.spin.y, a.velocity.x - a.spin.y * kRadius};
}

const char* law_name(NormalModel normal, TangentialModel tangential) {
  if (normal == NormalModel::linear)
    return tangential == TangentialModel::directional ? "linear/directional" : "linear/history";
  return tangential == TangentialModel::directional ? "hertz/directional" : "hertz/history";
}

TEST_CASE("oblique impact, gross sliding: friction impulse mu (1 + e) vn") {
  // Sliding lasts the whole contact when vt > 7/2 mu (1 + e) vn (= 1.995 vn here). Then
  // J_t = mu J_n with J_n = m (1 + e) vn, and with I = 2/5 m R^2 the spin after is
  // 5 J_t / (2 m R). e = 0.9 keeps the dashpot's tensile tail (where |Fn| still feeds the
  // Coulomb bound) below 0.3 % of the normal impulse.
  const double vn = 1.0, vt = 4.0;
  const double impulse_per_mass = kFriction * (1 + kRestitution) * vn;  // m/s
  for (auto normal : {NormalModel::linear, NormalModel::hertz})
    for (auto tangential : {TangentialModel::directional, TangentialModel::history}) {
      CAPTURE(law_name(normal, tangential));
      const Oblique o = floor_impact(normal, tangential, vn, vt);
      CHECK((vt - o.tangential_speed_after) / impulse_per_mass == doctest::Approx(1).epsilon(5e-3));
      CHECK(o.spin_after * kRadius / (2.5 * impulse_per_mass) == doctest::Approx(1).epsilon(5e-3));
      CHECK(o.normal_speed_after == doctest::Approx(kRestitution * vn).epsilon(1e-3));
    }
}

TEST_CASE("oblique impact, small vt/vn: directional Coulomb ends rolling at 5/7 vt") {
  // Sliding stops when the contact point comes to rest: v_t' = vt - J_t/m and
  // omega' R = 5 J_t / (2 m) give v_t' = omega' R = 5/7 vt (Maw, Barber & Fawcett 1976).
  const double vn = 1.0, vt = 0.5;
  for (auto normal : {NormalModel::linear, NormalModel::hertz}) {
    CAPTURE(law_name(normal, TangentialModel::directional));
    const Oblique o = floor_impact(normal, TangentialModel::directional, vn, vt);
    CHECK(std::fabs(o.slip_after) < 5e-3 * vt);
    CHECK(o.tangential_speed_after / vt == doctest::Approx(5.0 / 7.0).epsilon(5e-3));
  }
}

TEST_CASE("oblique impact, small vt/vn: Mindlin history stays within the energy bound") {
  // The tangential spring stores energy and gives it back (tangential restitution: the spin
  // may overshoot and reverse the slip), so the rolling 5/7 law does not hold; what remains is
  // that friction neither reverses the centre's motion nor creates energy.
  const double vn = 1.0, vt = 0.5;
  for (auto normal : {NormalModel::linear, NormalModel::hertz}) {
    CAPTURE(law_name(normal, TangentialModel::history));
    const Oblique o = floor_impact(normal, TangentialModel::history, vn, vt);
    CHECK(std::fabs(o.tangential_speed_after) <= vt);
    CHECK(o.tangential_speed_after > 0);
    // Tangential plus rotational kinetic energy after is at most the tangential energy before.
    const double mass = ball_mass(kRadius, kSteelDensity);
    const double inertia = 0.4 * mass * kRadius * kRadius;
    const double after = 0.5 * mass * o.tangential_speed_after * o.tangential_speed_after +
                         0.5 * inertia * o.spin_after * o.spin_after;
    CHECK(after <= 0.5 * mass * vt * vt);
  }
}

// The tangential law alone on a contact point of tangent mass m_t, advanced as the engine
// advances bodies (v' = v + dt F / m_t; the history integrates v): per step, the leapfrog energy
// 1/2 m_t v^2 + 1/2 kt xi . (xi + dt v) (xi the history before the step), which an undamped
// stuck spring conserves exactly, and the law's tally.
struct TangentRun {
  double initial_energy = 0, final_energy = 0;  // J
  Dissipation tally;                            // J, the law's dissipation in [kTangential]
  double damper_work = 0;    // J, sum of ct v . (v + v') / 2 dt over the trajectory
  double largest_force = 0;  // N
};

TangentRun tangent_oscillator(double restitution, double normal_force, double v0,
                              int steps_per_period, int periods) {
  const double mass = ball_mass(kRadius, kSteelDensity);
  const ContactParams p = linear_contact(1e5, restitution, kFriction);
  const NormalResponse r = LinearNormal::respond(1e-6, kRadius, mass, true, p);
  const double tangent_mass = 2.0 / 7.0 * mass;
  const double dt = 2 * kPi / std::sqrt(r.tangent_stiffness / tangent_mass) / steps_per_period;
  const Vec3 normal{0, 0, 1};
  Vec3 xi{}, v{v0, 0, 0};
  auto energy = [&] {
    return 0.5 * tangent_mass * dot(v, v) + 0.5 * r.tangent_stiffness * dot(xi, xi + dt * v);
  };
  TangentRun run;
  run.initial_energy = energy();
  for (int n = 0; n < steps_per_period * periods; ++n) {
    const Vec3 f =
        MindlinHistory::force(&xi, normal, v, r, normal_force, tangent_mass, dt, p, run.tally);
    const Vec3 v_next = v + (dt / tangent_mass) * f;
    run.damper_work += r.tangent_damping * dot(v, 0.5 * (v + v_next)) * dt;
    run.largest_force = std::fmax(run.largest_force, norm(f));
    v = v_next;
  }
  run.final_energy = energy();
  return run;
}

TEST_CASE("Mindlin history: a stuck undamped spring tallies zero") {
  // 24 steps per period, 20 periods, |F| far below mu |Fn|. The former tally (work minus the
  // change of 1/2 kt xi^2) counted 1/2 kt dt^2 v^2 per step: 17 times the spring's energy here.
  const TangentRun run = tangent_oscillator(1.0, 1.0, 1e-3, 24, 20);
  REQUIRE(run.largest_force < 0.1 * kFriction);
  CHECK(std::fabs(run.final_energy - run.initial_energy) <= 1e-12 * run.initial_energy);
  CHECK(std::fabs(run.tally.tangential) <= 1e-12 * run.initial_energy);
}

TEST_CASE("Mindlin history: damped and sliding contacts tally the scheme's exact loss") {
  struct Case {
    double restitution, normal_force, v0;  // -, N, m/s
    bool slides;
  };
  // Stuck and damped; sliding undamped (all the loss is the Coulomb cap's); sliding and damped.
  for (const Case c :
       {Case{0.6, 1.0, 1e-3, false}, Case{1.0, 5e-3, 1e-3, true}, Case{0.6, 1.0, 1.0, true}})
    for (int steps : {24, 96}) {
      CAPTURE(c.restitution);
      CAPTURE(c.v0);
      CAPTURE(steps);
      const TangentRun run = tangent_oscillator(c.restitution, c.normal_force, c.v0, steps, 20);
      CHECK((run.largest_force >= kFriction * c.normal_force * (1 - 1e-12)) == c.slides);
      const double loss = run.initial_energy - run.final_energy;
      CHECK(loss > 0.1 * run.initial_energy);
      CHECK(std::fabs(run.tally.tangential - loss) <= 1e-9 * run.initial_energy);
      // Stuck, all of it is the dashpot's work over the mid-step velocity.
      if (!c.slides) CHECK(std::fabs(run.damper_work - loss) <= 1e-9 * run.initial_energy);
    }
}

TEST_CASE("directional Coulomb: the slip stops without reversing, at any mu Fn dt / (m v)") {
  // A contact point of tangent mass m_t sliding at v0: each step takes mu Fn dt / m_t off the
  // slip until the last, which stops it exactly. The tally is then all the kinetic energy.
  const double tangent_mass = 1e-4, v0 = 1e-3, dt = 1e-5;
  ContactParams p;
  p.friction = kFriction;
  const Vec3 normal{0, 0, 1};
  for (double ratio : {0.01, 0.7, 3.0, 1e3}) {  // mu Fn dt / (m_t v0)
    CAPTURE(ratio);
    const double normal_force = ratio * tangent_mass * v0 / (kFriction * dt);
    Vec3 v{v0, 0, 0};
    Dissipation tally;
    double smallest = v0;
    int moving = 0;
    for (int n = 0; n < 300; ++n) {
      const Vec3 f = DirectionalCoulomb::force(nullptr, normal, v, {}, normal_force, tangent_mass,
                                               dt, p, tally);
      v += (dt / tangent_mass) * f;
      smallest = std::fmin(smallest, v.x);
      if (v.x != 0) ++moving;
    }
    CHECK(smallest == 0);  // stopped exactly, never reversed
    CHECK(moving == static_cast<int>(std::ceil(1 / ratio)) - 1);
    CHECK(tally.tangential == doctest::Approx(0.5 * tangent_mass * v0 * v0).epsilon(1e-12));
  }
}

TEST_CASE("directional Coulomb: a sliding sphere ends rolling, and stays so, at a coarse step") {
  // The sphere rests on the floor (gravity, at the equilibrium overlap) sliding at v0 without
  // spin. Friction stops the slip with v = 5/7 v0 (as in the impact case above), taking
  // 1/7 m v0^2; then the contact point stays at rest. At this step mu m g dt / (2/7 m v_s)
  // is 4.6 for v_s = 1e-5 m/s, beyond the former explicit viscous regularisation's limit of 2.
  const double mass = ball_mass(kRadius, kSteelDensity), stiffness = 1e5, gravity = 9.81;
  const double v0 = 1e-3;
  const ContactParams contact = linear_contact(stiffness, kRestitution, kFriction);
  const double dt = linear_contact_time(stiffness, mass, kRestitution) / 50;
  EngineConfig c = steel_box({kHalfBox, kHalfBox, kHalfBox}, NormalModel::linear,
                             TangentialModel::directional, contact, dt);
  c.gravity = Vec3{0, 0, -gravity};
  add_particle(c, kRadius, {0, 0, -kHalfBox + kRadius - mass * gravity / stiffness}, {v0, 0, 0});
  auto engine = make_engine(c);
  double tally = 0, normal_tally = 0, largest_late_slip = 0, smallest_slip = v0;
  for (int n = 0; n < 3000; ++n) {
    const StepTotals& t = step(*engine, dt);
    tally += t.tally.tangential;
    normal_tally += t.tally.normal;
    const ParticleState p = engine->particles()[0];
    const double slip = p.velocity.x - p.spin.y * kRadius;
    smallest_slip = std::fmin(smallest_slip, slip);
    if (n >= 1000) largest_late_slip = std::fmax(largest_late_slip, std::fabs(slip));
  }
  const ParticleState p = engine->particles()[0];
  CHECK(smallest_slip >= -1e-12 * v0);
  CHECK(largest_late_slip <= 1e-12 * v0);
  CHECK(p.velocity.x / v0 == doctest::Approx(5.0 / 7.0).epsilon(1e-9));
  CHECK(tally == doctest::Approx(mass * v0 * v0 / 7).epsilon(1e-9));
  CHECK(std::fabs(normal_tally) <= 1e-6 * tally);  // the normal force balances the weight
}

}  // namespace
}  // namespace pdsim

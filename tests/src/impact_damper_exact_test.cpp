// The exact impact-damper reference against conservation laws, textbook oscillator solutions,
// the coexisting regimes of a single ball on Saeki's primary at 15 Hz and the symmetric
// two-impact closed form (Masri & Caughey 1966).
#include "tests/support/impact_damper_exact.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <vector>

namespace {

using pdsim::reference::first_harmonic_amplitude;
using pdsim::reference::ImpactDamperParams;
using pdsim::reference::ImpactDamperState;
using pdsim::reference::ImpactDamperTrace;
using pdsim::reference::simulate_free_decay;
using pdsim::reference::simulate_impact_damper;

constexpr double kTwoPi = 6.28318530717958647692;

// Masri & Caughey's single-ball impact damper on Saeki's (2002) primary system (the ball and
// primary of tests/src/coupling_test.cpp), forced: M = 2.37 kg, K = 21.5 kN/m, zeta = 0.01,
// F0 = 2 N, 0.110 kg ball, e = 0.6, clearance 10 mm, 15 Hz.
ImpactDamperParams saeki_ball_case() {
  ImpactDamperParams p;
  p.M = 2.37;
  p.K = 21500;
  p.C = 2 * 0.01 * std::sqrt(p.K * p.M);
  p.m = 0.110;
  p.e = 0.6;
  p.clearance = 0.010;
  p.F0 = 2;
  p.frequency = 15;
  return p;
}

double mechanical_energy(const ImpactDamperParams& p, const ImpactDamperTrace& tr, std::size_t i) {
  return 0.5 * p.M * tr.v[i] * tr.v[i] + 0.5 * p.K * tr.x[i] * tr.x[i] +
         0.5 * p.m * tr.vb[i] * tr.vb[i];
}

// F0 / |K - M Omega^2 + i C Omega| and its phase lag (receptance of a damped SDOF).
std::complex<double> receptance(const ImpactDamperParams& p) {
  const double omega = kTwoPi * p.frequency;
  return 1.0 / std::complex<double>(p.K - p.M * omega * omega, p.C * omega);
}

}  // namespace

TEST_CASE(
    "impact law keeps momentum, reverses the relative velocity by e, loses (1-e^2)/2 mu w^2") {
  struct Impact {
    double M, m, e, v, vb;
  };
  for (const Impact& c : {Impact{2.37, 0.110, 0.6, 0.21, -0.4}, Impact{1.0, 1.0, 1.0, -3.0, 5.0},
                          Impact{5.0, 0.01, 0.0, 1e-3, 2.0}, Impact{0.3, 7.0, 0.9, 4.0, -1.5}}) {
    const auto after = pdsim::reference::impact_velocities(c.M, c.m, c.e, c.v, c.vb);
    const double momentum = c.M * c.v + c.m * c.vb;
    const double scale = c.M * std::abs(c.v) + c.m * std::abs(c.vb);
    CHECK(std::abs(c.M * after.v + c.m * after.vb - momentum) <= 4e-16 * scale);
    CHECK(std::abs((after.vb - after.v) + c.e * (c.vb - c.v)) <= 1e-15 * std::abs(c.vb - c.v));
    const double kinetic_loss = 0.5 * c.M * (c.v * c.v - after.v * after.v) +
                                0.5 * c.m * (c.vb * c.vb - after.vb * after.vb);
    const double reduced_mass = c.m * c.M / (c.m + c.M);
    const double expected = 0.5 * (1 - c.e * c.e) * reduced_mass * (c.vb - c.v) * (c.vb - c.v);
    CHECK(std::abs(kinetic_loss - expected) <= 1e-13 * 0.5 * scale * std::abs(c.vb - c.v));
  }
}

TEST_CASE("elastic ball, undamped unforced primary: energy constant to 1e-10 over 100 impacts") {
  ImpactDamperParams p = saeki_ball_case();
  p.C = 0;
  p.e = 1;
  const double x0 = 0.02;  // m, four times the half clearance: an impact every half swing
  const ImpactDamperTrace tr = simulate_free_decay(p, x0, 3.0, 1e-4);
  REQUIRE(tr.impact_times.size() >= 100);
  const double e0 = 0.5 * p.K * x0 * x0;
  double worst = 0;
  for (std::size_t i = 0; i < tr.t.size(); ++i)
    worst = std::max(worst, std::abs(mechanical_energy(p, tr, i) - e0) / e0);
  CHECK(worst <= 1e-10);
  CHECK(tr.dissipated <= 1e-12 * e0);
}

TEST_CASE("inelastic ball, undamped unforced primary: energy lost equals the impact losses") {
  ImpactDamperParams p = saeki_ball_case();
  p.C = 0;
  for (double restitution : {0.6, 0.0}) {
    CAPTURE(restitution);
    p.e = restitution;
    const double x0 = 0.02;
    const ImpactDamperTrace tr = simulate_free_decay(p, x0, 3.0, 1e-4);
    const double e0 = 0.5 * p.K * x0 * x0;
    REQUIRE(tr.impact_times.size() >= 10);
    // With e = 0 the ball rides on the walls: the riding phases enter the balance.
    if (restitution == 0) CHECK(tr.sticking_phases >= 1);
    CHECK(tr.dissipated >= 0.5 * e0);
    CHECK(std::abs(e0 - mechanical_energy(p, tr, tr.t.size() - 1) - tr.dissipated) <= 1e-10 * e0);
  }
}

TEST_CASE("plastic ball rides on the wall and leaves it when the wall decelerates") {
  // e = 0: the first impact is plastic; the ball then rides on the upper wall with M + m until
  // the primary passes x = 0 (x'' changes sign) and flies off at the common speed.
  ImpactDamperParams p = saeki_ball_case();
  p.C = 0;
  p.e = 0;
  const double x0 = 0.02, half = 0.5 * p.clearance;
  const ImpactDamperTrace tr = simulate_free_decay(p, x0, 0.2, 1e-5);
  REQUIRE(tr.impact_times.size() >= 2);
  // Ball at rest at x0, primary x0 cos(wn t): contact when x0 (1 - cos(wn t1)) = d/2.
  const double omega_n = std::sqrt(p.K / p.M), omega_c = std::sqrt(p.K / (p.M + p.m));
  const double t1 = std::acos(1 - half / x0) / omega_n;
  CHECK(std::abs(tr.impact_times[0] - t1) <= 1e-12);
  const double v1 = -x0 * omega_n * std::sin(omega_n * t1);
  const double reduced_mass = p.m * p.M / (p.m + p.M);
  const double common_v = p.M * v1 / (p.M + p.m);
  // Riding: x = x1 cos(wc tau) + (vc / wc) sin(wc tau) = A cos(wc tau - phase) reaches 0 at speed
  // A wc.
  const double x1 = x0 - half;
  const double amplitude = std::hypot(x1, common_v / omega_c);
  const double t_leave = t1 + (kTwoPi / 4 + std::atan2(common_v / omega_c, x1)) / omega_c;
  const double leave_speed = -amplitude * omega_c;
  std::size_t checked = 0;
  for (std::size_t i = 0; i < tr.t.size(); ++i) {
    if (tr.t[i] <= t_leave || tr.t[i] >= tr.impact_times[1]) continue;
    CHECK(std::abs(tr.vb[i] - leave_speed) <= 1e-12 * std::abs(leave_speed));
    ++checked;
  }
  CHECK(checked >= 10);
  // The first impact's loss is mu v1^2 / 2; later ones add to it.
  CHECK(tr.dissipated >= 0.5 * reduced_mass * v1 * v1 * (1 - 1e-12));
}

TEST_CASE("no contact, undamped: forced response from rest matches the textbook solution") {
  // Rao, Mechanical Vibrations: x = F0 / (K - M W^2) (sin W t - (W / wn) sin wn t) from rest.
  ImpactDamperParams p = saeki_ball_case();
  p.C = 0;
  p.clearance = 1.0;  // m: the ball never reaches a wall
  p.frequency = 12;
  const double omega = kTwoPi * p.frequency, omega_n = std::sqrt(p.K / p.M);
  const double static_amplitude = p.F0 / (p.K - p.M * omega * omega);
  const ImpactDamperTrace tr = simulate_impact_damper(p, {}, 2.0, 1e-4);
  CHECK(tr.impact_times.empty());
  double worst = 0;
  for (std::size_t i = 0; i < tr.t.size(); ++i) {
    const double t = tr.t[i];
    const double expected =
        static_amplitude * (std::sin(omega * t) - omega / omega_n * std::sin(omega_n * t));
    worst = std::max(worst, std::abs(tr.x[i] - expected));
  }
  CHECK(worst <= 1e-9 * std::abs(static_amplitude));
}

TEST_CASE("massless ball: the primary follows the damped receptance although the ball bounces") {
  ImpactDamperParams p = saeki_ball_case();
  p.m = 0;              // the ball cannot push the primary
  p.clearance = 0.001;  // m, well inside the 3.2 mm swing: many impacts
  p.e = 0.8;
  const std::complex<double> h = receptance(p);
  const double amplitude = p.F0 * std::abs(h), lag = -std::arg(h);
  const double omega = kTwoPi * p.frequency;
  // Start on the steady state x = X sin(W t - lag), so no transient is excited.
  const ImpactDamperState start{0, -amplitude * std::sin(lag), amplitude * omega * std::cos(lag),
                                -amplitude * std::sin(lag), 0};
  const ImpactDamperTrace tr = simulate_impact_damper(p, start, 2.0, 1e-4);
  CHECK(tr.impact_times.size() >= 50);
  double worst = 0;
  for (std::size_t i = 0; i < tr.t.size(); ++i)
    worst = std::max(worst, std::abs(tr.x[i] - amplitude * std::sin(omega * tr.t[i] - lag)));
  CHECK(worst <= 1e-9 * amplitude);
  for (std::size_t i = 0; i < tr.t.size(); ++i)
    REQUIRE(std::abs(tr.xb[i] - tr.x[i]) <= 0.5 * p.clearance * (1 + 1e-9));
}

TEST_CASE("free decay without contact matches the damped free response") {
  // x = X0 e^{-zeta wn t} (cos wd t + zeta / sqrt(1 - zeta^2) sin wd t), released from rest.
  ImpactDamperParams p = saeki_ball_case();
  const double zeta = 0.05;
  p.C = 2 * zeta * std::sqrt(p.K * p.M);
  p.clearance = 1.0;
  const double x0 = 0.004, omega_n = std::sqrt(p.K / p.M);
  const double omega_d = omega_n * std::sqrt(1 - zeta * zeta);
  const ImpactDamperTrace tr = simulate_free_decay(p, x0, 1.0, 1e-4);
  CHECK(tr.impact_times.empty());
  double worst = 0;
  for (std::size_t i = 0; i < tr.t.size(); ++i) {
    const double t = tr.t[i];
    const double expected =
        x0 * std::exp(-zeta * omega_n * t) *
        (std::cos(omega_d * t) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(omega_d * t));
    worst = std::max(worst, std::abs(tr.x[i] - expected));
  }
  CHECK(worst <= 1e-9 * x0);
  CHECK(tr.xb.front() == doctest::Approx(x0));  // ball starts at the slot centre
}

TEST_CASE("grazing contacts 1e-9 and 1e-12 of the swing deep are found at their analytic time") {
  // Undamped, unforced primary x = X0 sin(wn t + 0.3), ball at rest at 0: the relative position
  // -x reaches the lower wall when sin(wn t + 0.3) = d / (2 X0). At depth 1e-9 the gap is negative
  // for 2 sqrt(2e-9) / wn = 1e-6 s, at 1e-12 for 3e-8 s, midway between the search's first
  // samples (T/32 = 2e-3 s apart). The found time is late by the gap's round-off floor
  // (~1e-16 m) over the closing speed.
  ImpactDamperParams p = saeki_ball_case();
  p.C = 0;
  p.F0 = 0;
  p.e = 1;
  const double x0 = 0.005, phase = 0.3, omega_n = std::sqrt(p.K / p.M);
  const ImpactDamperState start{0, x0 * std::sin(phase), x0 * omega_n * std::cos(phase), 0, 0};
  struct Graze {
    double depth, time_tolerance_s;
  };
  for (const Graze& g :
       {Graze{1e-9, 1e-10}, Graze{1e-12, 1e-9}, Graze{-1e-12, 0}, Graze{-1e-9, 0}}) {
    CAPTURE(g.depth);
    p.clearance = 2 * x0 * (1 - g.depth);
    const ImpactDamperTrace tr = simulate_impact_damper(p, start, kTwoPi / 2 / omega_n, 1e-4);
    if (g.depth < 0) {
      CHECK(tr.impact_times.empty());
      continue;
    }
    REQUIRE(tr.impact_times.size() == 1);
    const double contact = (std::asin(0.5 * p.clearance / x0) - phase) / omega_n;
    CHECK(std::abs(tr.impact_times[0] - contact) <= g.time_tolerance_s);
  }
}

TEST_CASE("ball on Saeki's primary at 15 Hz: from the slot centre 3.24 mm, from a wall irregular") {
  const ImpactDamperParams p = saeki_ball_case();
  const double period = 1 / p.frequency;
  const double dt = period / 64;
  // Ball at rest at the centre: the 3.24 mm swing never reaches a wall (d/2 = 5 mm), so the
  // primary settles on the receptance F0 / |K - M W^2 + i C W| = 3.2365 mm: the 3.24 mm regime
  // is the motion without impacts.
  const ImpactDamperTrace centre = simulate_impact_damper(p, {}, 300 * period, dt);
  const double settled = first_harmonic_amplitude(centre.t, centre.x, p.frequency, 250 * period);
  MESSAGE("ball at the centre: first harmonic over periods 250-300 = " << settled * 1e3 << " mm");
  CHECK(centre.impact_times.empty());
  CHECK(std::abs(settled - 3.24e-3) <= 0.01 * 3.24e-3);
  CHECK(std::abs(settled - p.F0 * std::abs(receptance(p))) <= 1e-6 * settled);

  // Ball at rest against the lower wall: impacts and chattering, an irregular motion whose
  // amplitude wanders from window to window (chaotic, so round-off decides the exact value).
  // Another exact event-driven model read 1.09 mm; a 200-period window lands between 0.8 and
  // 1.6 mm.
  const ImpactDamperState wall{0, 0, 0, -0.5 * p.clearance, 0};
  const ImpactDamperTrace irregular = simulate_impact_damper(p, wall, 300 * period, dt);
  const double late = first_harmonic_amplitude(irregular.t, irregular.x, p.frequency, 100 * period);
  MESSAGE("ball on the lower wall: first harmonic over periods 100-300 = "
          << late * 1e3 << " mm, " << irregular.impact_times.size() << " impacts");
  CHECK(irregular.impact_times.size() >= 300);
  CHECK(late >= 0.8e-3);
  CHECK(late <= 1.6e-3);
}

TEST_CASE("symmetric two-impact motion: a periodic orbit of the event model that attracts") {
  // Non-dimensional, as Masri & Caughey present it: wn = 1, mu = m/M = 0.1, e = 0.8,
  // zeta = 0.05, W / wn = 1.2, clearance 5 static deflections F0/K. Every start below ends on the
  // same motion, the evidence that it is the unique attractor here.
  const ImpactDamperParams p{1, 1, 0.1, 0.1, 0.8, 5, 1, 1.2 / kTwoPi};
  const double period = 1 / p.frequency, half_period = 0.5 * period;
  const auto motions = pdsim::reference::symmetric_two_impact_motions(p);
  REQUIRE(motions.size() == 2);

  // Each admissible candidate is an orbit of the event-driven model: started just after its
  // upper-wall impact, the next impact comes T/2 later. One of the two is unstable (its error grows
  // about 60 times per impact), so only the first impact is compared for all candidates.
  for (const auto& motion : motions) {
    if (!motion.admissible) continue;
    const ImpactDamperState& s = motion.after_impact;
    const ImpactDamperTrace tr = simulate_impact_damper(p, s, s.t + period, period / 1024);
    REQUIRE(!tr.impact_times.empty());
    CHECK(std::abs(tr.impact_times[0] - (s.t + half_period)) <= 1e-11 * period);
  }

  // From rest with the ball anywhere in the slot the motion converges to one of them: equally
  // spaced impacts at its phase, and its closed-form first harmonic.
  const pdsim::reference::SymmetricTwoImpactMotion* attractor = nullptr;
  for (double ball : {0.0, 0.5, -0.5, 0.9, -1.0}) {
    CAPTURE(ball);
    const ImpactDamperState start{0, 0, 0, ball * 0.5 * p.clearance, 0};
    const ImpactDamperTrace tr = simulate_impact_damper(p, start, 200 * period, period / 1024);
    const std::size_t n = tr.impact_times.size();
    REQUIRE(n >= 20);
    const pdsim::reference::SymmetricTwoImpactMotion* reached = nullptr;
    for (const auto& motion : motions) {
      const double offset = std::fmod(tr.impact_times[n - 1] - motion.after_impact.t, half_period);
      if (motion.admissible && std::min(offset, half_period - offset) <= 1e-9 * period)
        reached = &motion;
    }
    REQUIRE(reached != nullptr);
    if (attractor == nullptr) attractor = reached;
    CHECK(reached == attractor);
    for (std::size_t k = n - 20; k < n; ++k)
      CHECK(std::abs(tr.impact_times[k] - tr.impact_times[k - 1] - half_period) <= 1e-9 * period);
    const double amplitude = first_harmonic_amplitude(tr.t, tr.x, p.frequency, 190 * period);
    CHECK(std::abs(amplitude - attractor->first_harmonic) <= 1e-5 * attractor->first_harmonic);
  }

  // Started on the attractor, the model stays on it: ten impacts T/2 apart to round-off.
  const ImpactDamperState& s = attractor->after_impact;
  const ImpactDamperTrace tr = simulate_impact_damper(p, s, s.t + 5.25 * period, period / 1024);
  REQUIRE(tr.impact_times.size() == 10);
  for (std::size_t k = 0; k < 10; ++k)
    CHECK(std::abs(tr.impact_times[k] - (s.t + static_cast<double>(k + 1) * half_period)) <=
          1e-12 * period);
  CHECK(std::abs(first_harmonic_amplitude(tr.t, tr.x, p.frequency, s.t) -
                 attractor->first_harmonic) <= 1e-5 * attractor->first_harmonic);
}

TEST_CASE("the reference rejects inputs outside its model") {
  ImpactDamperParams p = saeki_ball_case();
  CHECK_THROWS_AS(simulate_impact_damper(p, {0, 0, 0, 0.006, 0}, 1, 1e-3), std::invalid_argument);
  p.C = 2.5 * std::sqrt(p.K * p.M);  // overdamped
  CHECK_THROWS_AS(simulate_impact_damper(p, {}, 1, 1e-3), std::invalid_argument);
  p = saeki_ball_case();
  p.e = 1.5;
  CHECK_THROWS_AS(simulate_impact_damper(p, {}, 1, 1e-3), std::invalid_argument);
}

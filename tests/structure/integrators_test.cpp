// Time integrators against the analytic response of damped linear oscillators.
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <complex>
#include <memory>
#include <vector>

#include "io/deck.hpp"
#include "src/scene.hpp"
#include "structure/structure.hpp"

namespace pdsim {
namespace {

// Saeki's (2002) primary system (as examples/saeki_250.toml) with light damping.
constexpr double kMass = 2.37, kStiffness = 21500.0, kDampingRatio = 0.02;

LinearStructure sdof(double damping_ratio) {
  Deck deck;
  deck.structure.kind = StructureKind::sdof;
  deck.structure.mass = kMass;
  deck.structure.stiffness = kStiffness;
  deck.structure.damping = 2 * damping_ratio * std::sqrt(kStiffness * kMass);
  return build_structure(deck);
}

// Free decay from x0 at rest: x(t) = x0 e^{-zeta w t} (cos wd t + zeta / sqrt(1 - zeta^2)
// sin wd t) and its derivative (Rao, Mechanical Vibrations, underdamped free vibration, v0 = 0).
struct FreeDecay {
  double x0, zeta, omega;
  double damped() const { return omega * std::sqrt(1 - zeta * zeta); }
  double displacement(double t) const {
    const double wd = damped();
    return x0 * std::exp(-zeta * omega * t) *
           (std::cos(wd * t) + zeta / std::sqrt(1 - zeta * zeta) * std::sin(wd * t));
  }
  double velocity(double t) const {
    return -x0 * omega / std::sqrt(1 - zeta * zeta) * std::exp(-zeta * omega * t) *
           std::sin(damped() * t);
  }
};

struct History {
  std::vector<double> time, displacement, velocity;
};

History free_decay(IntegratorKind kind, double h, double duration, const FreeDecay& reference) {
  const LinearStructure s = sdof(reference.zeta);
  auto integrator = make_integrator(s, kind, h);
  integrator->q(0) = reference.x0;
  const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(1);
  History out;
  const auto steps = static_cast<long>(std::lround(duration / h));
  for (long k = 0; k <= steps; ++k) {
    out.time.push_back(static_cast<double>(k) * h);
    out.displacement.push_back(integrator->q(0));
    out.velocity.push_back(integrator->v(0));
    integrator->step(h, no_load);
  }
  return out;
}

double max_error_over_x0(const History& run, const FreeDecay& reference) {
  double worst = 0;
  for (std::size_t k = 0; k < run.time.size(); ++k) {
    worst = std::max(worst, std::abs(run.displacement[k] - reference.displacement(run.time[k])));
    worst = std::max(worst,
                     std::abs(run.velocity[k] - reference.velocity(run.time[k])) / reference.omega);
  }
  return worst / reference.x0;
}

// Maxima of x(t): where v goes from + to -, x from the cubic Hermite interpolant at the
// linearly interpolated zero of v (error O(h^4) since x' = 0 there).
std::vector<double> peaks(const History& run) {
  std::vector<double> out;
  for (std::size_t k = 0; k + 1 < run.time.size(); ++k) {
    const double v0 = run.velocity[k], v1 = run.velocity[k + 1];
    if (!(v0 > 0 && v1 <= 0)) continue;
    const double h = run.time[k + 1] - run.time[k], s = v0 / (v0 - v1);
    const double x0 = run.displacement[k], x1 = run.displacement[k + 1];
    const double h00 = 2 * s * s * s - 3 * s * s + 1, h10 = s * s * s - 2 * s * s + s,
                 h01 = -2 * s * s * s + 3 * s * s, h11 = s * s * s - s * s;
    out.push_back(h00 * x0 + h10 * h * v0 + h01 * x1 + h11 * h * v1);
  }
  return out;
}

const FreeDecay kDecay{1e-3, kDampingRatio, std::sqrt(kStiffness / kMass)};
const double kPeriod = 2 * kPi / kDecay.damped();

TEST_CASE("exact propagator: sdof free decay and logarithmic decrement") {
  const History run = free_decay(IntegratorKind::exact, 1e-4, 10 * kPeriod, kDecay);
  CHECK(max_error_over_x0(run, kDecay) < 1e-9);

  // delta = ln(x_k / x_{k+1}) = 2 pi zeta / sqrt(1 - zeta^2) (Rao, logarithmic decrement).
  const double decrement = 2 * kPi * kDampingRatio / std::sqrt(1 - kDampingRatio * kDampingRatio);
  const std::vector<double> x = peaks(run);
  REQUIRE(x.size() >= 9u);  // the peak at t = 0 has no + to - change before it
  for (std::size_t k = 0; k + 1 < x.size(); ++k) {
    CHECK(std::log(x[k] / x[k + 1]) == doctest::Approx(decrement).epsilon(1e-6));
  }
}

TEST_CASE("CVODE: sdof free decay and logarithmic decrement") {
  // Restarted every step, CVODE commits an error of about rtol (1e-10) x0 per step; 6,600
  // steps of 1e-4 s leave about 1e-6.
  const History run = free_decay(IntegratorKind::cvode, 1e-4, 10 * kPeriod, kDecay);
  CHECK(max_error_over_x0(run, kDecay) < 2e-6);
  const double decrement = 2 * kPi * kDampingRatio / std::sqrt(1 - kDampingRatio * kDampingRatio);
  const std::vector<double> x = peaks(run);
  REQUIRE(x.size() >= 9u);
  for (std::size_t k = 0; k + 1 < x.size(); ++k) {
    CHECK(std::log(x[k] / x[k + 1]) == doctest::Approx(decrement).epsilon(1e-5));
  }
}

// Steady-state first harmonic of x under F0 cos(w t), the load sampled at each step's midpoint,
// from a DFT over the last `average` whole periods after `settle` periods.
std::complex<double> harmonic_response(IntegratorKind kind, const LinearStructure& s, double omega,
                                       double force) {
  const int steps_per_period = 400, settle = 30, average = 5;
  const double h = 2 * kPi / omega / steps_per_period;
  auto integrator = make_integrator(s, kind, h);
  Eigen::VectorXd load(1);
  std::complex<double> sum = 0;
  for (int k = 0; k < (settle + average) * steps_per_period; ++k) {
    load(0) = force * std::cos(omega * (k + 0.5) * h);
    integrator->step(h, load);
    if (k >= settle * steps_per_period) {
      const double t = (k + 1) * h;
      sum += integrator->q(0) * std::exp(std::complex<double>(0, -omega * t));
    }
  }
  return 2.0 * sum / static_cast<double>(average * steps_per_period);
}

TEST_CASE("sdof steady-state harmonic response matches the receptance") {
  const double zeta = 0.05, force = 2.0;
  const LinearStructure s = sdof(zeta);
  const double c = 2 * zeta * std::sqrt(kStiffness * kMass),
               omega_n = std::sqrt(kStiffness / kMass);
  for (const IntegratorKind kind : {IntegratorKind::exact, IntegratorKind::cvode}) {
    for (const double ratio : {0.8, 1.0, 1.3}) {
      const double omega = ratio * omega_n;
      // X / F = 1 / (K - M w^2 + i c w) (Rao, harmonic response of a damped system).
      const std::complex<double> receptance =
          1.0 / std::complex<double>(kStiffness - kMass * omega * omega, c * omega);
      const std::complex<double> x = harmonic_response(kind, s, omega, force);
      CAPTURE(ratio);
      CAPTURE(static_cast<int>(kind));
      CHECK(std::abs(x) / force == doctest::Approx(std::abs(receptance)).epsilon(1e-3));
      CHECK(std::abs(std::arg(x) - std::arg(receptance)) < 1e-3);
    }
  }
}

TEST_CASE("kick adds impulse / M to the velocity") {
  for (const IntegratorKind kind : {IntegratorKind::exact, IntegratorKind::cvode}) {
    auto integrator = make_integrator(sdof(kDampingRatio), kind, 1e-4);
    integrator->v(0) = 0.25;
    integrator->kick(Eigen::VectorXd::Constant(1, 0.474));  // N s
    CHECK(integrator->v(0) == doctest::Approx(0.25 + 0.474 / kMass).epsilon(1e-14));
    CHECK(integrator->q(0) == 0.0);
  }
}

TEST_CASE("exact propagator accepts a step other than the precomputed one") {
  const LinearStructure s = sdof(kDampingRatio);
  auto whole = make_integrator(s, IntegratorKind::exact, 1e-3);
  auto halves = make_integrator(s, IntegratorKind::exact, 1e-3);
  whole->q(0) = halves->q(0) = 1e-3;
  const Eigen::VectorXd load = Eigen::VectorXd::Constant(1, 5.0);
  for (int k = 0; k < 20; ++k) {
    whole->step(1e-3, load);
    halves->step(5e-4, load);
    halves->step(5e-4, load);
  }
  halves->step(1e-3, load);  // back to the nominal step
  whole->step(1e-3, load);
  CHECK(halves->q(0) == doctest::Approx(whole->q(0)).epsilon(1e-12));
  CHECK(halves->v(0) == doctest::Approx(whole->v(0)).epsilon(1e-12));
}

// A 20-element aluminium cantilever with modal damping, started in its first mode: the response
// stays in that mode and decays like an SDOF oscillator with that mode's frequency. CVODE runs
// on the 4-mode reduction: on the full model it resolves the stiff modes (omega_max h >> 1) and
// costs milliseconds per step.
TEST_CASE("beam first-mode free decay, exact and CVODE") {
  Deck deck;
  deck.structure.kind = StructureKind::beam;
  deck.structure.damping_ratio = 0.01;
  BeamSpec& b = deck.structure.beam;
  b.length = 0.5;
  b.elements = 20;
  b.young = 7.0e10;
  b.density = 2700.0;
  b.area = 0.03 * 0.005;
  b.inertia = 0.03 * 0.005 * 0.005 * 0.005 / 12;
  const double tip_amplitude = 1e-3;  // m

  for (const IntegratorKind kind : {IntegratorKind::exact, IntegratorKind::cvode}) {
    deck.structure.modes = kind == IntegratorKind::exact ? 0 : 4;
    const LinearStructure s = build_structure(deck);
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eigen(s.stiffness, s.mass);
    const Eigen::VectorXd mode = eigen.eigenvectors().col(0);
    const FreeDecay reference{tip_amplitude, 0.01, std::sqrt(eigen.eigenvalues()(0))};
    const double h = 1e-4, duration = 2 * 2 * kPi / reference.omega;
    const Eigen::VectorXd no_load = Eigen::VectorXd::Zero(s.size());
    auto integrator = make_integrator(s, kind, h);
    integrator->q = mode * (tip_amplitude / (s.response * mode));
    double worst = 0;
    const auto steps = std::lround(duration / h);
    for (long k = 1; k <= steps; ++k) {
      integrator->step(h, no_load);
      const double t = static_cast<double>(k) * h;
      worst = std::max(worst, std::abs(s.response * integrator->q - reference.displacement(t)));
    }
    CAPTURE(static_cast<int>(kind));
    CHECK(worst / tip_amplitude < (kind == IntegratorKind::exact ? 1e-9 : 1e-6));
  }
}

// The full model's CVODE and exact paths agree on a forced beam over a few steps.
TEST_CASE("beam under a tip force: CVODE agrees with the exact propagator") {
  Deck deck;
  deck.structure.kind = StructureKind::beam;
  deck.structure.rayleigh = std::array<double, 2>{1.0, 1e-6};
  BeamSpec& b = deck.structure.beam;
  b.length = 0.5;
  b.elements = 4;
  b.young = 7.0e10;
  b.density = 2700.0;
  b.area = 0.03 * 0.005;
  b.inertia = 0.03 * 0.005 * 0.005 * 0.005 / 12;
  const LinearStructure s = build_structure(deck);
  const double h = 1e-4;
  auto exact = make_integrator(s, IntegratorKind::exact, h);
  auto cvode = make_integrator(s, IntegratorKind::cvode, h);
  for (int k = 0; k < 50; ++k) {
    const Eigen::VectorXd load = s.force_shape * std::sin(2 * kPi * 20 * (k + 0.5) * h);
    exact->step(h, load);
    cvode->step(h, load);
  }
  const double scale = exact->q.lpNorm<Eigen::Infinity>();
  CHECK((cvode->q - exact->q).lpNorm<Eigen::Infinity>() < 2e-7 * scale);
}

}  // namespace
}  // namespace pdsim

// Harmonic balance on maps whose answers are known: a constant effective mass and damping (the
// host's receptance with them added), Coulomb friction (Den Hartog's harmonic-balance amplitude
// of an SDOF with a dry-friction damper), and a softening load whose effective mass grows with
// the amplitude (three coexisting amplitudes below resonance, the middle one unstable).
#include <doctest/doctest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <vector>

#include "src/predict.hpp"

using namespace pdsim;

namespace {

struct Sdof {
  double mass, stiffness, damping, force;
};
const Sdof kHost{1.0, 1e4, 0.5, 1.0};  // kg, N/m (15.9 Hz), N s/m, N

// An SDOF as build_structure() makes one, its damper on the mass.
LinearStructure sdof(const Sdof& h) {
  LinearStructure s;
  s.mass = Eigen::MatrixXd::Constant(1, 1, h.mass);
  s.stiffness = Eigen::MatrixXd::Constant(1, 1, h.stiffness);
  s.damping = Eigen::MatrixXd::Constant(1, 1, h.damping);
  s.force_shape = s.base_influence = Eigen::VectorXd::Ones(1);
  s.attachment_translation = Eigen::MatrixXd::Ones(1, 1);
  s.attachment_rotation = Eigen::MatrixXd::Zero(1, 1);
  s.response = Eigen::RowVectorXd::Ones(1);
  return s;
}

// The roots of `map` on the SDOF `h` under its force at f Hz.
std::vector<HbRoot> balance(const MapInterpolant& map, double f, const Sdof& h = kHost) {
  const LinearStructure s = sdof(h);
  return harmonic_balance(map, s, host_at(s, ExcitationInput::force, h.force, f), f);
}

// A map at `frequencies` and `amplitudes` whose effective mass and damping are m(f, X), c(f, X).
MapTable synthetic_map(const std::vector<double>& frequencies,
                       const std::vector<double>& amplitudes,
                       const std::function<double(double, double)>& mass,
                       const std::function<double(double, double)>& damping) {
  MapTable t;
  for (double f : frequencies)
    for (double x : amplitudes) {
      t.frequency.push_back(f);
      t.sweep.push_back(0);
      t.converged.push_back(1);
      t.amplitude.push_back(x);
      t.effective_mass.push_back(mass(f, x));
      t.effective_damping.push_back(damping(f, x));
      t.effective_mass_ci.push_back(0.01 * std::abs(mass(f, x)));
      t.effective_damping_ci.push_back(0.01 * std::abs(damping(f, x)));
    }
  return t;
}

std::vector<double> log_space(double lo, double hi, int n) {
  std::vector<double> v;
  for (int k = 0; k < n; ++k) v.push_back(lo * std::pow(hi / lo, double(k) / (n - 1)));
  return v;
}

}  // namespace

TEST_CASE("harmonic balance: a constant effective mass and damping give the host's receptance") {
  const double m0 = 0.1, c0 = 2.0;
  const MapInterpolant map(synthetic_map(
      {10, 12, 14, 16, 18, 20}, {1e-6, 1e-1}, [&](double, double) { return m0; },
      [&](double, double) { return c0; }));
  for (double f : {10.0, 11.0, 15.0, 15.5, 20.0}) {  // on map frequencies and between them
    CAPTURE(f);
    const double w = 2 * kPi * f;
    const std::complex<double> d(kHost.stiffness - (kHost.mass + m0) * w * w,
                                 w * (kHost.damping + c0));
    const std::vector<HbRoot> roots = balance(map, f);
    REQUIRE(roots.size() == 1);
    CHECK(roots[0].amplitude == doctest::Approx(kHost.force / std::abs(d)).epsilon(1e-9));
    CHECK(roots[0].phase == doctest::Approx(-std::arg(d)).epsilon(1e-9));
    CHECK(roots[0].stable);
    CHECK(roots[0].amplitude_ci > 0);
    CHECK(roots[0].amplitude_ci < 0.1 * roots[0].amplitude);
    CHECK(roots[0].map_change == 0);  // one impedance at every amplitude: nothing to miss
  }
}

// How much a map cell may hide: for an SDOF, the step of the impedance across the cell over the
// whole dynamic stiffness there, |dZ| / |K - M w^2 + i w C + Z|.
TEST_CASE("harmonic balance: a root read across a step of the map names the step's share") {
  const double c1 = 1.0, c2 = 11.0;
  MapTable table = synthetic_map(
      {15}, {1e-6, 1e-2}, [](double, double) { return 0.0; },
      [&](double, double x) { return x < 1e-3 ? c1 : c2; });
  const double f = 15.0, w = 2 * kPi * f;
  const std::vector<HbRoot> roots = balance(MapInterpolant(table), f);
  REQUIRE(roots.size() == 1);
  CHECK(roots[0].damper.converged);
  table.converged[1] = 0;  // a point read by the root that did not converge is said so
  CHECK_FALSE(balance(MapInterpolant(table), f)[0].damper.converged);
  const std::complex<double> z(-roots[0].damper.mass * w * w, w * roots[0].damper.damping);
  const std::complex<double> d(kHost.stiffness - kHost.mass * w * w, w * kHost.damping);
  CHECK(roots[0].map_change == doctest::Approx(w * (c2 - c1) / std::abs(d + z)).epsilon(1e-9));
}

// Under base motion Y sin(w t) the map's damper moves with the mass's absolute motion Y + Q, and
// the FRF reports the relative Q: (K - M w^2 + i w C) Q + Z (Y + Q) = M w^2 Y for the damper's
// impedance Z = -m w^2 + i w c.
TEST_CASE("harmonic balance: a base-driven SDOF with a constant damper, relative and absolute") {
  const double m0 = 0.1, c0 = 2.0, y = 1e-4;
  const MapInterpolant map(synthetic_map(
      {10, 20}, {1e-7, 1e-1}, [&](double, double) { return m0; },
      [&](double, double) { return c0; }));
  const LinearStructure s = sdof(kHost);
  for (double f : {12.0, 15.9, 19.0}) {
    CAPTURE(f);
    const double w = 2 * kPi * f;
    const std::complex<double> z(-m0 * w * w, w * c0);
    const std::complex<double> q =
        (kHost.mass * w * w - z) * y /
        (std::complex<double>(kHost.stiffness - kHost.mass * w * w, w * kHost.damping) + z);
    const std::vector<HbRoot> roots =
        harmonic_balance(map, s, host_at(s, ExcitationInput::base_displacement, y, f), f);
    REQUIRE(roots.size() == 1);
    CHECK(roots[0].amplitude == doctest::Approx(std::abs(q)).epsilon(1e-9));
    CHECK(roots[0].phase == doctest::Approx(std::arg(q)).epsilon(1e-9));
    CHECK(roots[0].damper_amplitude == doctest::Approx(std::abs(y + q)).epsilon(1e-9));
  }
}

// A map stepped up and down holds each way's states: each is read on its own (sweep +1, -1),
// and each gives the receptance with its own effective mass.
TEST_CASE("harmonic balance: the ways up and down of a stepped map are read apart") {
  const double up_mass = 0.1, down_mass = 0.3, c0 = 2.0;
  MapTable map = synthetic_map(
      {14, 16}, {1e-6, 1e-1}, [&](double, double) { return up_mass; },
      [&](double, double) { return c0; });
  map.sweep.assign(map.frequency.size(), 1);
  MapTable down = synthetic_map(
      {14, 16}, {1e-1, 1e-6}, [&](double, double) { return down_mass; },
      [&](double, double) { return c0; });
  down.sweep.assign(down.frequency.size(), -1);
  append_rows(map, down);
  REQUIRE(map.frequency.size() == 8);
  CHECK_THROWS_WITH_AS(MapInterpolant(map, 0), doctest::Contains("no points"), InputError);
  const double f = 15.0, w = 2 * kPi * f;
  for (const auto& [sweep, mass] : {std::pair{1, up_mass}, std::pair{-1, down_mass}}) {
    CAPTURE(sweep);
    const std::complex<double> d(kHost.stiffness - (kHost.mass + mass) * w * w,
                                 w * (kHost.damping + c0));
    const std::vector<HbRoot> roots = balance(MapInterpolant(map, sweep), f);
    REQUIRE(roots.size() == 1);
    CHECK(roots[0].amplitude == doctest::Approx(kHost.force / std::abs(d)).epsilon(1e-9));
  }
}

TEST_CASE(
    "harmonic balance: Coulomb friction gives Den Hartog's amplitude, unbounded at resonance") {
  // Friction force Ff against the sliding: first harmonic 4 Ff / pi in phase with the velocity,
  // c_eff = 4 Ff / (pi w X). Without other damping the balance is
  // ((K - M w^2) X)^2 + (4 Ff / pi)^2 = F0^2 (Den Hartog 1931).
  const double ff = 0.2;
  Sdof host = kHost;
  host.damping = 0;
  const MapInterpolant map(synthetic_map(
      {10, 20}, {1e-6, 1e-1}, [](double, double) { return 0.0; },
      [&](double f, double x) { return 4 * ff / (kPi * 2 * kPi * f * x); }));
  for (double f : {10.0, 12.0, 18.0, 20.0}) {
    CAPTURE(f);
    const double w = 2 * kPi * f;
    const double expected = std::sqrt(host.force * host.force - std::pow(4 * ff / kPi, 2)) /
                            std::abs(host.stiffness - host.mass * w * w);
    const std::vector<HbRoot> roots = balance(map, f, host);
    REQUIRE(roots.size() == 1);
    CHECK(roots[0].amplitude == doctest::Approx(expected).epsilon(1e-3));
  }
  // At resonance friction alone cannot hold a force above 4 Ff / pi: no root within the map,
  // refused rather than extrapolated.
  CHECK_THROWS_WITH_AS(balance(map, std::sqrt(1e4) / (2 * kPi), host),
                       doctest::Contains("above the map's largest"), InputError);
  CHECK_THROWS_WITH_AS(balance(map, 25.0, host),
                       doctest::Contains("outside the map's frequencies (10 to 20 Hz)"),
                       InputError);
  // Amplitudes that do not overlap between two map frequencies (an acceleration grid spread
  // too thin): nothing to read between them.
  MapTable apart = synthetic_map(
      {10}, {1e-3, 2e-3}, [](double, double) { return 0.0; }, [](double, double) { return 1.0; });
  const MapTable high = synthetic_map(
      {20}, {1e-4, 2e-4}, [](double, double) { return 0.0; }, [](double, double) { return 1.0; });
  append_rows(apart, high);
  CHECK_THROWS_WITH_AS(balance(MapInterpolant(apart), 15.0), doctest::Contains("do not overlap"),
                       InputError);
}

TEST_CASE("harmonic balance: a softening load has three amplitudes below resonance") {
  // m_eff = 0.5 X / (X + 1 mm): the load joins the host as the motion grows, lowering its
  // natural frequency from 15.9 towards 13 Hz, so the response leans to lower frequencies.
  auto mass = [](double, double x) { return 0.5 * x / (x + 1e-3); };
  const MapInterpolant map(synthetic_map({13.0, 13.25, 13.5}, log_space(1e-6, 1.0, 400), mass,
                                         [](double, double) { return 0.0; }));
  const double f = 13.25, w = 2 * kPi * f;
  // The roots of the analytic balance, found here by a scan of its own.
  auto h = [&](double x) {
    return x * std::abs(std::complex<double>(kHost.stiffness - (kHost.mass + mass(f, x)) * w * w,
                                             w * kHost.damping)) -
           kHost.force;
  };
  std::vector<double> expected;
  const std::vector<double> scan = log_space(1e-6, 1.0, 200000);
  for (std::size_t k = 1; k < scan.size(); ++k)
    if ((h(scan[k - 1]) < 0) != (h(scan[k]) < 0)) expected.push_back(scan[k]);
  REQUIRE(expected.size() == 3);
  const std::vector<HbRoot> roots = balance(map, f);
  REQUIRE(roots.size() == 3);
  for (std::size_t b = 0; b < 3; ++b) {
    CAPTURE(b);
    CHECK(roots[b].amplitude == doctest::Approx(expected[b]).epsilon(1e-2));
  }
  CHECK(roots[0].stable);
  CHECK_FALSE(roots[1].stable);  // the middle of the jump
  CHECK(roots[2].stable);
  CHECK(roots[0].amplitude < roots[1].amplitude);
  CHECK(roots[1].amplitude < roots[2].amplitude);
}

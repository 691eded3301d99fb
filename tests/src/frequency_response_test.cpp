// The stepped-sine FRF as a user runs it, against outside numbers: the analytic receptance of a
// bare SDOF (the predicted start is exact there, so every frequency converges at the minimum
// dwell), and the rigid-mass receptance F0 / |K - (M + m_p) w^2 + i w C| of an SDOF carrying a
// resting bed under weak excitation, in each way a sweep can run.
#include <doctest/doctest.h>

#include <cmath>
#include <complex>

#include "src/run.hpp"
#include "tests/support/validation_row.hpp"

using namespace pdsim;

namespace {

constexpr double kMass = 2.37, kStiffness = 21500.0, kZeta = 0.0022;

// The Saeki primary system with the default `settle` (no table), 13-17 Hz in 0.25 Hz steps.
const std::string kBareSdof = R"(
[structure]
kind = "sdof"
mass = 2.37
stiffness = 21500.0
damping_ratio = 0.0022
[excitation]
kind = "stepped_sine"
amplitude = 1.0
frequencies = { start = 13.0, stop = 17.0, step = 0.25 }
)";

std::complex<double> receptance(double frequency, double mass) {
  const double w = 2 * kPi * frequency, c = 2 * kZeta * std::sqrt(kStiffness * kMass);
  return 1.0 / std::complex<double>(kStiffness - mass * w * w, c * w);
}

// 40 soft steel spheres resting in a 30 mm box on the same SDOF, driven with 0.2 N (or the
// `input` given) well off resonance: the container's acceleration stays below a tenth of
// friction x g, so the bed moves with it as a rigid mass.
std::string resting_bed(const std::string& start,
                        const std::string& input = "input = \"force\"\namplitude = 0.2") {
  return R"(
[structure]
kind = "sdof"
mass = 2.37
stiffness = 21500.0
damping_ratio = 0.0022
[[damper]]
container = { shape = "box", size = [0.03, 0.03, 0.03] }
particles = { count = 40, diameter = 0.005, density = 7800.0, seed = 5 }
[contact]
model = "hertz"
tangential = "history"
young = 2.0e9
restitution = 0.6
friction = 0.5
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "stepped_sine"
frequencies = [10.0, 12.0, 18.0, 20.0]
)" + input +
         "\nstart = \"" + start + "\"\n";
}

double bed_mass(const Scene& scene) {
  return scene.dampers.at(0).particle_mass;
}

void check_bare(const Results& r, const std::string& how) {
  REQUIRE(r.frf.frequency.size() == 17);
  double worst = 0;  // relative amplitude error
  for (std::size_t i = 0; i < r.frf.frequency.size(); ++i)
    worst = std::max(
        worst, std::fabs(r.frf.amplitude[i] / std::abs(receptance(r.frf.frequency[i], kMass)) - 1));
  validation_bound("bare Saeki SDOF, 13-17 Hz, " + how + ": largest |amplitude / receptance - 1|",
                   "SDOF receptance (closed form)", 2e-3, worst, "");
  for (std::size_t i = 0; i < r.frf.frequency.size(); ++i) {
    const std::complex<double> h = 1.0 * receptance(r.frf.frequency[i], kMass);
    CAPTURE(r.frf.frequency[i]);
    CHECK(r.frf.converged[i] == 1);
    CHECK(r.frf.periods[i] == 10);  // the default minimum dwell
    CHECK(r.frf.amplitude[i] == doctest::Approx(std::abs(h)).epsilon(2e-3));
    CHECK(std::fabs(r.frf.phase[i] - std::arg(h)) < 2e-3);
    // Deterministic: what scatter there is, is the discrete scheme settling from the
    // continuous prediction (1e-5).
    CHECK(r.frf.amplitude_ci[i] < 1e-4 * r.frf.amplitude[i]);
  }
}

}  // namespace

TEST_CASE("bare SDOF, zeta 0.0022, 13-17 Hz: every frequency converged at the minimum dwell") {
  const Deck deck = parse_deck(kBareSdof, "bare.toml");
  CHECK(deck.excitation.start == FrequencyStart::predicted);
  const Results r = simulate(deck, build_scene(deck));
  check_bare(r, "predicted starts");
  CHECK(r.meta_text.at("start") == "predicted");
}

TEST_CASE("bare SDOF, independent frequencies side by side: the same rows") {
  const Deck deck = parse_deck(kBareSdof + "start = \"independent\"\n", "bare.toml");
  const Results r = simulate(deck, build_scene(deck, 1), true, 2);
  check_bare(r, "independent frequencies");
  CHECK(r.meta_numbers.at("jobs") == 2);
}

TEST_CASE("a resting bed moves as a rigid mass: within 2 % of the rigid-mass receptance") {
  // (The physical stepped sine, "carried", would wait out a 5 s transient at zeta 0.0022.)
  for (const std::string start : {"predicted", "independent"}) {
    CAPTURE(start);
    const Deck deck = parse_deck(resting_bed(start), "bed.toml");
    REQUIRE(deck.bed.settle);  // gravity on particles: settled by default
    const Scene scene = build_scene(deck, 1);
    const Results r = simulate(deck, scene, true, 2);
    CHECK(r.meta_numbers.at("bed_settled") == 1);
    CHECK(r.meta_numbers.at("bed_settle_time_s") > 0.02);
    REQUIRE(r.frf.frequency.size() == 4);
    for (std::size_t i = 0; i < r.frf.frequency.size(); ++i) {
      const double f = r.frf.frequency[i], w = 2 * kPi * f;
      const std::complex<double> h = 0.2 * receptance(f, kMass + bed_mass(scene));
      CAPTURE(f);
      // Rigid: the container's peak acceleration against the friction limit 0.5 g.
      REQUIRE(w * w * std::abs(h) < 0.1 * 0.5 * 9.81);
      CHECK(r.frf.converged[i] == 1);
      CHECK(r.frf.amplitude[i] == doctest::Approx(std::abs(h)).epsilon(0.02));
      CHECK(std::fabs(r.frf.phase[i] - std::arg(h)) < 0.02);
      CHECK(r.frf.periods[i] <= 20);  // no transient to wait out
    }
  }
}

TEST_CASE("a resting bed under base acceleration: the relative motion of a rigid mass") {
  // q relative to the base, the bed moving with its container's absolute motion y + q:
  // (K - (M + m) w^2 + i w C) Q = (M + m) w^2 Y, Y = -A / w^2 for an acceleration amplitude A.
  // The predicted start of base input: the base's phasor enters the load and the dampers'
  // absolute motion.
  const Deck deck = parse_deck(
      resting_bed("predicted", "input = \"base_acceleration\"\namplitude = 0.1"), "bed.toml");
  const Scene scene = build_scene(deck, 1);
  const Results r = simulate(deck, scene);
  REQUIRE(r.frf.frequency.size() == 4);
  for (std::size_t i = 0; i < r.frf.frequency.size(); ++i) {
    const double f = r.frf.frequency[i];
    const double total = kMass + bed_mass(scene);
    const std::complex<double> expected = -total * 0.1 * receptance(f, total);
    const std::complex<double> measured = std::polar(r.frf.amplitude[i], r.frf.phase[i]);
    CAPTURE(f);
    CHECK(r.frf.converged[i] == 1);
    CHECK(std::abs(measured - expected) < 0.02 * std::abs(expected));
    CHECK(r.frf.periods[i] <= 20);
  }
}

TEST_CASE("realisations: other fill seeds, a Student-t interval across them") {
  Deck deck = parse_deck(resting_bed("predicted") + "settle = { realisations = 3 }\n", "bed.toml");
  deck.excitation.frequencies = {12.0};
  const Scene scene = build_scene(deck, 1);
  const Results r = simulate(deck, scene, true, 2);
  REQUIRE(r.frf.frequency.size() == 1);
  CHECK(r.frf.realisations[0] == 3);
  CHECK(r.meta_numbers.at("realisations") == 3);
  const std::complex<double> h = 0.2 * receptance(12.0, kMass + bed_mass(scene));
  CHECK(r.frf.converged[0] == 1);
  CHECK(r.frf.amplitude[0] == doctest::Approx(std::abs(h)).epsilon(0.02));
  CHECK(std::isfinite(r.frf.amplitude_ci[0]));
  // Three runs' periods are in /periods, each from its own settled bed.
  int runs = 0;
  for (int k : r.periods.realisation) runs = std::max(runs, k + 1);
  CHECK(runs == 3);
}

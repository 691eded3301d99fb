// Scene derivation: the cross-checks that need derived physics, and the time-step formulas.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "src/check_report.hpp"
#include "src/run.hpp"
#include "src/scene.hpp"

using namespace pdsim;

namespace {

std::string error_of(const std::string& deck_file) {
  try {
    build_scene(load_deck(std::string(PDSIM_TEST_DIR) + "/decks/" + deck_file));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("an explicit dt above the stability limit is refused at its key") {
  const std::string e = error_of("bad_dt_above_limit.toml");
  CHECK(e.find("bad_dt_above_limit.toml:17:6: 'solver.dt'") != std::string::npos);
  CHECK(e.find("exceeds the stability limit") != std::string::npos);
  CHECK(e.find("allow_unstable") != std::string::npos);
}

TEST_CASE("particles that do not fit are refused with the count the container holds") {
  const std::string e = error_of("bad_particles_do_not_fit.toml");
  CHECK(e.find("bad_particles_do_not_fit.toml:7:") != std::string::npos);
  // 0.02 m box, lattice spacing 1.02 x 5 mm, first centre at 2.55 mm: 3 per row, 27 in all.
  CHECK(e.find("holds only 27 particles") != std::string::npos);
}

TEST_CASE("Rayleigh time and linear contact time against hand-computed values") {
  // Steel, r = 2.5 mm: G = 2e11 / 2.6; T_R = pi r sqrt(rho/G) / (0.1631 nu + 0.8766).
  const double shear = 2e11 / 2.6;
  const double expected = kPi * 0.0025 * std::sqrt(7800 / shear) / (0.1631 * 0.3 + 0.8766);
  CHECK(rayleigh_time(0.0025, 7800, 2e11, 0.3) == doctest::Approx(expected).epsilon(1e-14));
  CHECK(expected == doctest::Approx(2.7022e-6).epsilon(1e-4));
  // Undamped linear contact (e = 1): t_c = pi sqrt(m*/k).
  CHECK(linear_contact_time(1e5, 1e-3, 1.0) == doctest::Approx(kPi * 1e-4).epsilon(1e-14));
  // e = 0.5: zeta = -ln e / sqrt(pi^2 + ln^2 e), t_c = pi / (w0 sqrt(1 - zeta^2)).
  const double zeta = std::log(2.0) / std::sqrt(kPi * kPi + std::log(2.0) * std::log(2.0));
  CHECK(linear_contact_time(1e5, 1e-3, 0.5) ==
        doctest::Approx(kPi * 1e-4 / std::sqrt(1 - zeta * zeta)).epsilon(1e-12));
}

TEST_CASE("auto dt is a fixed fraction of the Rayleigh time and check names the variant") {
  const Deck d = load_deck(std::string(PDSIM_TEST_DIR) + "/../examples/shaken_box.toml");
  const Scene s = build_scene(d);
  CHECK(s.dt == doctest::Approx(0.15 * rayleigh_time(0.0025, 7800, 2e11, 0.3)).epsilon(1e-12));
  REQUIRE(s.dampers.size() == 1);
  CHECK(variant_name(s.dampers[0].engine) == "hertz/history/gravity/mono/box");
  CHECK(s.dampers[0].engine.particles.size() == 196);
}

namespace {

// The error of building the tiny deck with `from` replaced by `to` ("" when it builds).
std::string tiny_error(const std::string& from, const std::string& to) {
  std::string text = load_deck(std::string(PDSIM_TEST_DIR) + "/decks/tiny_stepped_sine.toml").text;
  text.replace(text.find(from), from.size(), to);
  try {
    build_scene(parse_deck(text, "tiny.toml"));
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("what a run would overflow on is refused by check, at its key") {
  CHECK(tiny_error("mass = 0.5", "mass = 0.5").empty());
  // 1e308 kg: K - w^2 M overflows at 15 Hz; a damping ratio of 1e308 makes C infinite.
  CHECK(tiny_error("mass = 0.5", "mass = 1e308").find("'structure': its mass, stiffness") !=
        std::string::npos);
  CHECK(tiny_error("damping_ratio = 0.02", "damping_ratio = 1e308").find("overflow") !=
        std::string::npos);
  // 6.7e9 steps a period at dt = 1e-11 s would overflow the int that counts them.
  const std::string dt = tiny_error("[output]", "[solver]\ndt = 1e-11\n[output]");
  CHECK(dt.find("'solver.dt': dt = 1e-11 s takes 6.667e+09 steps a period at 15 Hz") !=
        std::string::npos);
  CHECK(tiny_error("frequencies = [15.0, 16.0]", "frequencies = [1e-6, 16]")
            .find("'excitation.frequencies': dt = ") != std::string::npos);
  CHECK(tiny_error("frequencies = [15.0, 16.0]", "frequencies = [1e308, 16]")
            .find("expected at most 3.125e+10 Hz") != std::string::npos);
}

TEST_CASE("a frequency too fast to step is refused at the key it came from, for each kind") {
  auto error = [](const std::string& file, const std::string& from, const std::string& to) {
    std::string text = load_deck(std::string(PDSIM_TEST_DIR) + "/decks/" + file).text;
    REQUIRE(text.find(from) != std::string::npos);
    text.replace(text.find(from), from.size(), to);
    try {
      build_scene(parse_deck(text, file));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string too_fast = "a frequency of 1e+12 Hz needs steps shorter than 1e-12 s";
  CHECK(error("tiny_prescribed.toml", "frequency = 20.0 }", "frequency = 1e12 }")
            .find("'excitation.motion.frequency': " + too_fast) != std::string::npos);
  CHECK(error("tiny_stepped_sine.toml",
              "kind = \"stepped_sine\"\namplitude = 1.0\nfrequencies = [15.0, 16.0]\n"
              "settle = { min_periods = 3, max_periods = 4, batches = 2 }",
              "kind = \"sine\"\namplitude = 1.0\nfrequency = 1e12\nduration = 0.2")
            .find("'excitation.frequency': " + too_fast) != std::string::npos);
  CHECK(error("tiny_stepped_sine.toml", "[15.0, 16.0]", "[15.0, 1e12]")
            .find("'excitation.frequencies': " + too_fast) != std::string::npos);
}

TEST_CASE("a beam whose matrices have no modes is refused at [structure], not by a failed solver") {
  // Found by the deck fuzz test: density = 1e-300 made the beam's eigenproblem fail, a
  // SimulationError out of check instead of an InputError at the deck's line.
  std::string text = load_deck(std::string(PDSIM_TEST_DIR) + "/../examples/beam_damper.toml").text;
  const std::string density = "density = 2700.0";
  REQUIRE(text.find(density) != std::string::npos);
  text.replace(text.find(density), density.size(), "density = 1e-300");
  CHECK_THROWS_WITH_AS(build_scene(parse_deck(text, "beam.toml")),
                       doctest::Contains("'structure': expected a structure whose mass and "
                                         "stiffness matrices have modes"),
                       InputError);
}

TEST_CASE("a random fill beyond what random placement reaches is refused at once, by volume") {
  // 5000 spheres of 4 mm in a 20 mm box: a fill fraction of 20.9, refused before any attempt
  // (it used to try 1e7 placements first; 5e7 particles would have taken hours).
  const std::string e = tiny_error("count = 20,", "count = 5000,");
  CHECK(e.find("tiny.toml:11:13: 'damper[0].particles': a random fill of fill fraction 20.94") !=
        std::string::npos);
}

// Every fill a point may grow to is drawn when the deck is checked: one whose drawn diameter
// does not fit (fills 1 and 2 fit, fill 3 draws 22.9 mm for a 20 mm box) is refused by check,
// naming the fill and its seed, where a run found it only when a point asked for that fill.
TEST_CASE("every fill a point may grow to is drawn and checked before the run") {
  const std::string ball = "count = 1, diameter_range = [0.004, 0.024], density = 7800.0, seed = 6";
  const std::string e =
      tiny_error("count = 20, diameter = 0.004, density = 7800.0, seed = 3", ball);
  CHECK(e.find("tiny.toml:11:13: 'damper[0].particles': particle diameter 0.0229 m does not fit") !=
        std::string::npos);
  CHECK(e.find("(fill 3 of the 4 a point may grow to, seed 8)") != std::string::npos);
}

TEST_CASE("a deck file larger than 16 MiB is refused without reading it all") {
  const std::string e = [] {
    try {
      load_deck("/dev/zero");
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string();
  }();
  CHECK(e.find("larger than 16 MiB") != std::string::npos);
}

TEST_CASE("allow_unstable runs with a warning in the scene and in the check report") {
  std::string text = load_deck(std::string(PDSIM_TEST_DIR) + "/decks/bad_dt_above_limit.toml").text;
  text.replace(text.find("[solver]"), 8, "[solver]\nallow_unstable = true");
  const Deck deck = parse_deck(text, "unstable.toml");
  const Scene scene = build_scene(deck);
  CHECK(scene.dt > scene.dt_limit);
  CHECK(scene.warning.find("times the stability limit") != std::string::npos);
  CHECK(check_report(deck, scene).find("WARNING: dt = ") != std::string::npos);
}

// Deck parser: values read as written, and every kind of bad input refused with the file,
// line:column, full key and expectation. Positions are counted by hand from the deck texts.
#include "io/deck.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <string>

namespace pdsim {
namespace {

const std::string kDecks = std::string(PDSIM_TEST_DIR) + "/decks/";
const std::string kExamples = std::string(PDSIM_TEST_DIR) + "/../examples/";

// Appended after the lines under test, so that those keep the line numbers of their snippet.
const std::string kSine =
    "[excitation]\nkind = \"sine\"\namplitude = 1.0\nfrequency = 15.0\nduration = 1.0\n";
const std::string kSdof = "[structure]\nkind = \"sdof\"\nmass = 2.0\nstiffness = 12800.0\n";
const std::string kContact = "[contact]\nyoung = 2e11\n";

std::string error_of(const std::string& text, const std::string& path = "deck.toml") {
  try {
    parse_deck(text, path);
  } catch (const InputError& error) {
    return error.what();
  }
  return "(no error)";
}

// The message starts with "deck.toml:<line>:<column>: '<key>': " and contains the expectation.
void check_error(const std::string& text, const std::string& position_and_key,
                 const std::string& expectation) {
  const std::string message = error_of(text);
  INFO("message: " << message);
  CHECK(message.rfind("deck.toml:" + position_and_key, 0) == 0);
  CHECK(message.find(expectation) != std::string::npos);
}

std::string load_error(const std::string& path) {
  try {
    load_deck(path);
  } catch (const InputError& error) {
    return error.what();
  }
  return "(no error)";
}

TEST_CASE("a deck with every section keeps its values, integers read as reals") {
  const Deck deck = load_deck(kDecks + "good_sdof.toml");
  CHECK(deck.title == "good sdof");
  CHECK(deck.path == kDecks + "good_sdof.toml");
  CHECK(deck.text.rfind("# Every section", 0) == 0);

  const StructureSpec& s = deck.structure;
  CHECK(s.kind == StructureKind::sdof);
  CHECK(s.mass == 2.0);
  CHECK(s.stiffness == 12800.0);
  // c = 2 zeta sqrt(K M) = 2 * 0.025 * sqrt(12800 * 2) = 0.05 * 160 = 8 N s/m
  CHECK(s.damping == doctest::Approx(8.0).epsilon(1e-14));
  CHECK(s.damping_ratio == 0.025);
  // [3, 0, 4] / 5
  CHECK(s.direction.x == doctest::Approx(0.6).epsilon(1e-15));
  CHECK(s.direction.y == 0.0);
  CHECK(s.direction.z == doctest::Approx(0.8).epsilon(1e-15));
  CHECK(s.integrator == IntegratorKind::cvode);

  REQUIRE(deck.dampers.size() == 2);
  const DamperSpec& cylinder = deck.dampers[0];
  CHECK(cylinder.container.shape == WallShape::cylinder);
  CHECK(cylinder.container.radius == 0.02);
  CHECK(cylinder.container.height == 0.03);
  CHECK(cylinder.particles.count == 100);
  CHECK(cylinder.particles.diameter_min == 0.003);
  CHECK(cylinder.particles.diameter_max == 0.005);
  CHECK(cylinder.particles.polydisperse());
  CHECK(cylinder.particles.density == 7800.0);
  CHECK(cylinder.particles.seed == 7u);
  CHECK(cylinder.particles.fill == Fill::lattice);
  CHECK(cylinder.attach_node == -1);
  CHECK(!cylinder.attach_x);
  const DamperSpec& box = deck.dampers[1];
  CHECK(box.container.shape == WallShape::box);
  CHECK(box.container.size.x == 0.05);
  CHECK(box.container.size.y == 0.04);
  CHECK(box.container.size.z == 0.03);
  CHECK(box.particles.diameters == std::vector<double>{0.004, 0.006});
  CHECK(box.particles.seed == 1u);
  CHECK(box.particles.fill == Fill::random);

  CHECK(deck.contact.model == NormalModel::linear);
  CHECK(deck.contact.tangential == TangentialModel::directional);
  CHECK(deck.contact.stiffness == 1e5);
  CHECK(deck.contact.poisson == 0.49);
  CHECK(deck.contact.restitution == 1.0);
  CHECK(deck.contact.friction == 0.2);
  CHECK(deck.contact.rolling_friction == 0.01);
  REQUIRE(deck.gravity);
  CHECK(deck.gravity->z == -9.81);

  const ExcitationSpec& e = deck.excitation;
  CHECK(e.kind == ExcitationKind::stepped_sine);
  CHECK(e.input == ExcitationInput::base_acceleration);
  CHECK(e.amplitude == 3.0);
  // 0.1..0.7 step 0.1 inclusive is 7 frequencies, though (0.7 - 0.1) / 0.1 = 5.999999999999999
  // in doubles; run downwards, the first one is exactly `stop`.
  REQUIRE(e.frequencies.size() == 7);
  for (std::size_t i = 0; i < e.frequencies.size(); ++i)
    CHECK(e.frequencies[i] == doctest::Approx(0.7 - 0.1 * double(i)).epsilon(1e-13));
  CHECK(e.frequencies.front() == 0.7);
  CHECK(e.frequencies.back() == 0.1);
  CHECK(e.settle.min_periods == 5);
  CHECK(e.settle.max_periods == 50);
  CHECK(e.settle.tolerance == 1e-4);
  CHECK(e.settle.average_periods == 6);
  CHECK(e.settle.batches == 4);
  CHECK(e.settle.realisations == 1);
  CHECK(e.start == FrequencyStart::carried);
  CHECK_FALSE(deck.bed.settle);  // gravity acts on particles, but the deck says no
  CHECK(deck.bed.speed == 2e-3);
  CHECK(deck.bed.max_time == 0.5);
  CHECK(deck.bed.file == "bed.h5");

  CHECK(deck.coupling.scheme == CouplingScheme::loose);
  CHECK(deck.coupling.every == 4);
  CHECK(deck.coupling.tolerance == 1e-8);
  CHECK(deck.coupling.max_iterations == 20);
  CHECK(deck.solver.dt == 2e-6);
  CHECK(deck.solver.dt_safety == 0.2);
  CHECK(deck.solver.backend == Backend::cpu);
  CHECK(deck.solver.allow_unstable);
  CHECK(deck.solver.threads == 2);
  CHECK(deck.output.file.empty());  // the CLI derives it from the deck name
  CHECK(deck.output.every == 1e-3);
  CHECK(deck.output.energy);
}

TEST_CASE("positions are recorded for every key and where() falls back to the enclosing one") {
  const Deck deck = load_deck(kDecks + "good_sdof.toml");
  const auto at = [&](const std::string& key) {
    const SourcePos p = deck.where(key);
    return p.file + ":" + std::to_string(p.line) + ":" + std::to_string(p.column);
  };
  const std::string file = kDecks + "good_sdof.toml";
  CHECK(at("structure.mass") == file + ":5:8");
  CHECK(at("damper[1].particles.count") == file + ":17:23");
  CHECK(at("excitation.frequencies.start") == file + ":35:25");
  CHECK(at("damper[1]") == file + ":15:1");
  CHECK(at("damper[1].particles.nothing") == file + ":17:13");
  CHECK(at("damper[1].nothing.deeper") == file + ":15:1");
  CHECK(at("damper[5].particles") == file + ":11:1");  // "damper": the first [[damper]]
  CHECK(at("nothing") == file + ":0:0");
}

TEST_CASE("a beam deck: section properties, supports, damping and attachment") {
  const Deck deck = load_deck(kDecks + "good_beam.toml");
  const StructureSpec& s = deck.structure;
  CHECK(s.kind == StructureKind::beam);
  CHECK(s.beam.length == 1.0);
  CHECK(s.beam.elements == 10);
  CHECK(s.beam.young == 2.1e11);
  CHECK(s.beam.density == 7850.0);
  CHECK(s.beam.poisson == 0.29);
  // circle d = 0.02 m: A = pi d^2 / 4 = pi * 1e-4, I = pi d^4 / 64 = pi * 2.5e-9
  CHECK(s.beam.area == doctest::Approx(3.141592653589793e-4).epsilon(1e-15));
  CHECK(s.beam.inertia == doctest::Approx(7.853981633974483e-9).epsilon(1e-15));
  CHECK(s.beam.shear_factor == 0.9);
  CHECK(s.beam.section_height == 0.02);
  CHECK(s.beam.timoshenko);
  CHECK(s.beam.start == Support::pinned);
  CHECK(s.beam.end == Support::pinned);
  REQUIRE(s.rayleigh);
  CHECK((*s.rayleigh)[0] == 0.5);
  CHECK((*s.rayleigh)[1] == 1e-5);
  CHECK(s.direction.y == 1.0);
  CHECK(s.modes == 4);
  CHECK(s.integrator == IntegratorKind::exact);
  REQUIRE(deck.dampers.size() == 1);
  CHECK(deck.dampers[0].attach_node == 5);
  CHECK(deck.contact.model == NormalModel::hertz);
  CHECK(deck.contact.tangential == TangentialModel::history);
  CHECK(!deck.gravity);
  CHECK(deck.excitation.kind == ExcitationKind::free_decay);
  CHECK(deck.excitation.initial_displacement == -0.001);
  CHECK(deck.excitation.duration == 2.0);
  CHECK(deck.solver.dt == 0.0);  // "auto"

  // rectangle 0.03 x 0.005 m: A = 1.5e-4 m^2, I = b h^3 / 12 = 3.125e-10 m^4
  const Deck example = load_deck(kExamples + "beam_damper.toml");
  CHECK(example.structure.beam.area == doctest::Approx(1.5e-4).epsilon(1e-15));
  CHECK(example.structure.beam.inertia == doctest::Approx(3.125e-10).epsilon(1e-15));
  CHECK(example.structure.beam.shear_factor == doctest::Approx(5.0 / 6.0).epsilon(1e-15));
  CHECK(example.structure.beam.section_height == 0.005);
  CHECK(example.dampers[0].attach_x == 0.5);

  const Deck general = parse_deck(
      "[structure]\nkind = \"beam\"\nlength = 1\nelements = 4\nyoung = 1e9\ndensity = 1000\n"
      "section = { area = 2e-4, inertia = 3e-9, height = 0.01 }\n" +
          kSine,
      "deck.toml");
  CHECK(general.structure.beam.area == 2e-4);
  CHECK(general.structure.beam.inertia == 3e-9);
  CHECK(general.structure.beam.section_height == 0.01);
  CHECK(general.structure.beam.start == Support::clamped);  // defaults: a cantilever
  CHECK(general.structure.beam.end == Support::free);
}

TEST_CASE("the example decks parse with the values they document") {
  const Deck saeki = load_deck(kExamples + "saeki_250.toml");
  CHECK(saeki.structure.mass == 2.37);
  CHECK(saeki.structure.stiffness == 21500.0);
  CHECK(saeki.dampers.at(0).particles.count == 250);
  REQUIRE(saeki.excitation.frequencies.size() == 17);  // 13..17 step 0.25
  CHECK(saeki.excitation.start == FrequencyStart::predicted);
  CHECK(saeki.bed.settle);  // gravity on particles
  CHECK(saeki.excitation.frequencies.back() == 17.0);
  CHECK(saeki.contact.young == 2.0e9);
  CHECK(saeki.output.file == "saeki_250.h5");
  const Deck figure = load_deck(kExamples + "saeki_fig5b_sweep.toml");
  CHECK(figure.sweep.points() == 2);
  CHECK(sweep_point(figure, 1).dampers.at(0).particles.count == 200);

  const Deck bare = load_deck(kExamples + "bare_sdof.toml");
  CHECK(bare.dampers.empty());
  CHECK(bare.excitation.frequencies.size() == 25);   // 12..18 step 0.25
  CHECK(bare.excitation.settle.max_periods == 400);  // the default
  CHECK(bare.excitation.settle.tolerance == 0.02);
  CHECK_FALSE(bare.bed.settle);  // nothing to settle

  const Deck box = load_deck(kExamples + "shaken_box.toml");
  CHECK(box.structure.kind == StructureKind::none);
  CHECK(box.excitation.kind == ExcitationKind::prescribed);
  CHECK(box.excitation.frequencies == std::vector<double>{20.0});
  CHECK(box.excitation.motion.frequency == 20.0);
  CHECK(box.excitation.motion.amplitude == 0.004);
  CHECK(box.excitation.duration == 0.5);
  CHECK(box.excitation.settle.average_periods == 5);
  CHECK(box.dampers.at(0).particles.fill == Fill::lattice);

  const Deck beam = load_deck(kExamples + "beam_damper.toml");
  CHECK(beam.excitation.frequencies.size() == 11);  // 13..18 step 0.5
  CHECK(!beam.gravity);
}

TEST_CASE("negative mass: file, line:column, key and expectation") {
  const std::string path = kDecks + "bad_negative_mass.toml";
  CHECK(load_error(path) ==
        path + ":7:15: 'structure.mass': expected a positive number (kg), got -2.37");
}

TEST_CASE("misspelt key: suggestion within 3 edits, else the valid keys") {
  // A key of another kind is not a typo of a near name: the valid keys are listed.
  check_error(kSdof +
                  "[excitation]\nkind = \"stepped_sine\"\namplitude = 1\n"
                  "frequencies = [15]\nduration = 2\n",
              "9:1: 'excitation.duration': ",
              "unknown key for kind = \"stepped_sine\"; valid here: kind, input, amplitude");
  check_error(kSdof + kSine + "[[damper]]\ncontainer = { shape = \"cylinder\", size = [1, 1] }\n",
              "11:35: 'damper[0].container.size': ", "valid here: shape, radius, height");
  const std::string path = kDecks + "bad_misspelt_key.toml";
  CHECK(load_error(path) == path +
                                ":5:3: 'structure.stifness': unknown key for kind = \"sdof\"; "
                                "did you mean 'stiffness'?");
  check_error(kSdof + kSine + "[excitaton]\n",
              "10:2: 'excitaton': ", "unknown key; did you mean 'excitation'?");
  check_error(kSdof + kSine + "[solver]\nturbo = true\n", "11:1: 'solver.turbo': ",
              "unknown key; valid here: dt, dt_safety, backend, allow_unstable, threads");
  check_error(kSdof + kSine + "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n" +
                  "particles = { cuont = 3 }\n",
              "12:15: 'damper[0].particles.cuont': ", "did you mean 'count'?");
  check_error("[structure]\nkind = \"sdof\"\nlength = 1.0\n" + kSine,
              "3:1: 'structure.length': ", "unknown key for kind = \"sdof\"");
  check_error("[structure]\nkind = \"sdfo\"\n" + kSine, "2:8: 'structure.kind': ",
              "expected one of \"sdof\", \"beam\", got \"sdfo\"; did you mean \"sdof\"?");
}

TEST_CASE("wrong types") {
  check_error("[structure]\nkind = \"sdof\"\nmass = \"heavy\"\n" + kSine,
              "3:8: 'structure.mass': ", "expected a positive number (kg), got \"heavy\"");
  check_error(kSdof + "direction = \"x\"\n" + kSine, "5:13: 'structure.direction': ",
              "expected a non-zero vector of 3 numbers [x, y, z], got \"x\"");
  check_error(kSdof + "direction = [1, 0]\n" + kSine,
              "5:13: 'structure.direction': ", "got an array of 2");
  check_error(
      kSdof + kSine + kContact +
          "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
          "particles = { count = 250.0, diameter = 0.005, density = 7800 }\n",
      "14:23: 'damper[0].particles.count': ", "expected an integer from 1 to 33554431, got 250.0");
  check_error(kSdof + kSine + "[damper]\ncontainer = 1\n",
              "10:1: 'damper': ", "expected [[damper]] tables (an array of tables), got a table");
  check_error(kSdof + kSine + "[output]\nenergy = 1\n",
              "11:10: 'output.energy': ", "expected true or false, got 1");
  check_error(kSdof + kSine + "[solver]\ndt = \"fast\"\n",
              "11:6: 'solver.dt': ", "expected \"auto\" or a positive number (s), got \"fast\"");
  check_error("gravity = [0, 0, -9.81]\n" + kSdof + kSine,
              "1:11: 'gravity': ", "expected a table, got an array");
}

TEST_CASE("non-positive masses, stiffness, densities, diameters, sizes and counts") {
  check_error("[structure]\nkind = \"sdof\"\nmass = 2.0\nstiffness = 0\n" + kSine,
              "4:13: 'structure.stiffness': ", "expected a positive number (N/m), got 0");
  const std::string damper = kSdof + kSine + kContact + "[[damper]]\n";  // damper[0] on line 12
  check_error(damper + "container = { shape = \"box\", size = [0.05, -0.05, 0.05] }\n",
              "13:44: 'damper[0].container.size': ",
              "expected 3 positive edge lengths [a, b, c] (m), got -0.05");
  const std::string box = damper + "container = { shape = \"box\", size = [1, 1, 1] }\n";
  check_error(
      box + "particles = { count = 10, diameter = 0.005, density = -7800 }\n",
      "14:55: 'damper[0].particles.density': ", "expected a positive number (kg/m^3), got -7800");
  check_error(box + "particles = { count = 10, diameter = 0, density = 7800 }\n",
              "14:38: 'damper[0].particles.diameter': ", "expected a positive number (m), got 0");
  check_error(box + "particles = { count = 0, diameter = 0.005, density = 7800 }\n",
              "14:23: 'damper[0].particles.count': ", "expected an integer from 1 to 33554431");
  check_error(box + "particles = { count = 5, diameters = [0.004, 0.0], density = 7800 }\n",
              "14:46: 'damper[0].particles.diameters': ", "got 0.0");
  check_error(
      box + "particles = { count = 5, diameter_range = [0.005, 0.004], density = 7800 }\n",
      "14:43: 'damper[0].particles.diameter_range': ", "with min <= max (m), got [0.005, 0.004]");
}

TEST_CASE("restitution outside 0 < e <= 1, poisson outside -1 < nu < 0.5, negative friction") {
  const std::string deck = kSdof + kSine + "[contact]\n";  // [contact] on line 10
  check_error(deck + "restitution = 0\n",
              "11:15: 'contact.restitution': ", "expected a number in (0, 1], got 0");
  check_error(deck + "restitution = 1.2\n", "11:15: 'contact.restitution': ", "got 1.2");
  check_error(deck + "poisson = 0.5\n",
              "11:11: 'contact.poisson': ", "expected a number in (-1, 0.5), got 0.5");
  check_error(deck + "poisson = -1\n", "11:11: 'contact.poisson': ", "got -1");
  check_error(deck + "friction = -0.1\n",
              "11:12: 'contact.friction': ", "expected a non-negative number, got -0.1");
  check_error(deck + "rolling_friction = -0.1\n",
              "11:20: 'contact.rolling_friction': ", "expected a non-negative number, got -0.1");
}

TEST_CASE("non-smooth contacts: the penalty laws' keys refused, and the solver's elsewhere") {
  const std::string deck = kSdof + kSine + "[contact]\nmodel = \"nonsmooth\"\n";  // line 11
  for (const char* key : {"young = 2e11", "poisson = 0.3", "stiffness = 1e5",
                          "tangential = \"history\"", "rolling_friction = 0.1"}) {
    CAPTURE(key);
    check_error(deck + key + "\n", "12:", "not used by model = \"nonsmooth\"");
  }
  check_error(deck + "tolerance = -1e-4\n",
              "12:13: 'contact.tolerance': ", "expected a positive number (m/s), got -0.0001");
  check_error(deck + "max_iterations = 0\n", "12:18: 'contact.max_iterations': ",
              "expected an integer (iterations a step) from 1 to 1000000, got 0");
  check_error(deck + "rest_speed = 0\n", "12:14: 'contact.rest_speed': ", "got 0");
  check_error(kSdof + kSine + "[contact]\nyoung = 2e11\ntolerance = 1e-4\n",
              "12:13: 'contact.tolerance': ", "used only by model = \"nonsmooth\"");
  const Deck d = parse_deck(deck + "tolerance = 1e-4\nmax_iterations = 50\n", "deck.toml");
  CHECK(d.contact.nonsmooth);
  CHECK(d.contact.tolerance == 1e-4);
  CHECK(d.contact.max_iterations == 50);
}

TEST_CASE("NaN and infinity are refused wherever a number is read") {
  check_error("[structure]\nkind = \"sdof\"\nmass = nan\n" + kSine,
              "3:8: 'structure.mass': ", "expected a positive number (kg), got nan");
  check_error(kSdof + "direction = [1, inf, 0]\n" + kSine,
              "5:17: 'structure.direction': ", "got inf");
  check_error(kSdof + "damping = -inf\n" + kSine, "5:11: 'structure.damping': ", "got -inf");
  check_error(kSdof + kSine + "[gravity]\nvector = [0, 0, nan]\n",
              "11:17: 'gravity.vector': ", "got nan");
}

TEST_CASE("zero direction and axis vectors are refused, a zero gravity vector means none") {
  check_error(kSdof + "direction = [0, 0, 0]\n" + kSine, "5:13: 'structure.direction': ",
              "expected a non-zero vector of 3 numbers [x, y, z], got [0, 0, 0]");
  const std::string box =
      "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
      "particles = { count = 1, diameter = 0.005, density = 7800 }\n" +
      kContact;
  check_error(box + "[excitation]\nkind = \"prescribed\"\n" +
                  "motion = { axis = [0, 0, 0], amplitude = 0.004, frequency = 20 }\n",
              "8:19: 'excitation.motion.axis': ", "got [0, 0, 0]");
  const Deck no_gravity =
      parse_deck(kSdof + kSine + "[gravity]\nvector = [0, 0, 0]\n", "deck.toml");
  CHECK(!no_gravity.gravity);
  const Deck prescribed =
      parse_deck(box + "[excitation]\nkind = \"prescribed\"\n" +
                     "motion = { axis = [0, -2, 0], amplitude = 0.004, frequency = 20 }\n",
                 "deck.toml");
  CHECK(prescribed.excitation.motion.axis.y == -1.0);
}

TEST_CASE("absurd counts: particles, elements, periods out of order") {
  const std::string box =
      kSdof + kSine + kContact + "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n";
  // The engine's own limit (kernels/dem_types.hpp: owners that fit a packed list entry).
  check_error(box + "particles = { count = 33554432, diameter = 0.005, density = 7800 }\n",
              "14:23: 'damper[0].particles.count': ",
              "expected an integer from 1 to 33554431, got 33554432");
  const std::string half = "particles = { count = 20000000, diameter = 0.005, density = 7800 }\n";
  check_error(box + half + "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n" + half,
              "17:23: 'damper[1].particles.count': ",
              "expected at most 33554431 particles in all dampers together, got 40000000");
  check_error("[structure]\nkind = \"beam\"\nlength = 1\nelements = 501\n" + kSine,
              "4:12: 'structure.elements': ", "expected an integer from 1 to 500, got 501");
  const std::string stepped = kSdof +
                              "[excitation]\nkind = \"stepped_sine\"\namplitude = 1\n"
                              "frequencies = [15]\n";  // line 8
  check_error(
      stepped + "settle = { min_periods = 100, max_periods = 60 }\n",
      "9:26: 'excitation.settle.min_periods': ", "expected at most max_periods (60), got 100");
  check_error(stepped + "settle = { max_periods = 5 }\n", "9:26: 'excitation.settle.max_periods': ",
              "expected at least min_periods (10), got 5");
  check_error(stepped + "settle = { tolerance = 2 }\n",
              "9:24: 'excitation.settle.tolerance': ", "expected a number in (0, 1], got 2");
  check_error(stepped + "settle = { average_periods = 3 }\n",
              "9:30: 'excitation.settle.average_periods': ",
              "expected at least settle.batches (4) periods, one per batch of the interval, got 3");
  check_error(stepped + "start = \"physical\"\n",
              "9:9: 'excitation.start': ", "one of \"predicted\", \"carried\", \"independent\"");
}

TEST_CASE("realisations: two by default for a random fill, need one, the energy ledger one run") {
  const std::string stepped =
      kSdof + kContact +
      "[[damper]]\ncontainer = { shape = \"box\", size = [0.05, 0.05, 0.05] }\n"
      "particles = { count = 10, diameter = 0.005, density = 7800, "
      "fill = \"lattice\" }\n"
      "[excitation]\nkind = \"stepped_sine\"\namplitude = 1\n"
      "frequencies = [15]\n";
  const Deck one = parse_deck(stepped, "deck.toml");
  CHECK(one.excitation.start == FrequencyStart::predicted);  // the default
  CHECK_FALSE(one.bed.settle);                               // no gravity: nothing to settle
  const std::string again = "settle = { realisations = 3 }\n";
  const std::string message = error_of(stepped + again);
  CHECK(message.find("'excitation.settle.realisations'") != std::string::npos);
  CHECK(message.find("fill = \"random\"") != std::string::npos);
  std::string random = stepped;
  random.replace(random.find("\"lattice\""), 9, "\"random\"");
  CHECK(parse_deck(random + again, "deck.toml").excitation.settle.realisations == 3);
  // Not given: two for a random fill (the fewest that show coexisting regimes), one for a
  // lattice, and one when the energy ledger asks for one continuous run.
  CHECK(parse_deck(random, "deck.toml").excitation.settle.realisations == 2);
  // Fills added where they disagree: up to kDefaultMaxFills, at least realisations.
  CHECK(parse_deck(random, "deck.toml").excitation.settle.max_realisations == kDefaultMaxFills);
  CHECK(one.excitation.settle.max_realisations == 1);
  CHECK(error_of(random + "settle = { realisations = 3, max_realisations = 2 }\n")
            .find("'excitation.settle.max_realisations'") != std::string::npos);
  // Up, then down from the top: each frequency twice, the sweeps marked.
  std::string swept = random;
  swept.replace(swept.find("frequencies = [15]"), 18, "frequencies = [14, 15, 16]");
  const Deck both = parse_deck(swept + "direction = \"both\"\n", "deck.toml");
  CHECK(both.excitation.frequencies == std::vector<double>{14, 15, 16, 16, 15, 14});
  CHECK(both.excitation.sweeps == std::vector<int>{1, 1, 1, -1, -1, -1});
  CHECK(error_of(random + "direction = \"both\"\nstart = \"independent\"\n")
            .find("'excitation.direction'") != std::string::npos);
  CHECK(one.excitation.settle.realisations == 1);
  CHECK(parse_deck(random + "[output]\nenergy = true\n", "deck.toml")
            .excitation.settle.realisations == 1);
  const std::string energy = error_of(random + again + "[output]\nenergy = true\n");
  CHECK(energy.find("'output.energy'") != std::string::npos);
  CHECK(energy.find("one continuous run") != std::string::npos);
  CHECK(error_of(random + "start = \"independent\"\n[output]\nenergy = true\n")
            .find("'output.energy'") != std::string::npos);
  // Particle snapshots follow one continuous run too.
  const std::string snapshots = "[output]\nparticles = { every = 0.01 }\n";
  const Deck with = parse_deck(random + snapshots, "deck.toml");
  CHECK(with.output.particles_every == 0.01);
  CHECK(with.excitation.settle.realisations == 1);
  const std::string refused = error_of(random + again + snapshots);
  CHECK(refused.find("'output.particles'") != std::string::npos);
  CHECK(refused.find("one continuous run") != std::string::npos);
  CHECK(
      error_of(random + "[output]\nparticles = { every = 0 }\n").find("'output.particles.every'") !=
      std::string::npos);
  CHECK(error_of(random + "[output]\nparticles = { each = 1 }\n").find("each") !=
        std::string::npos);
}

TEST_CASE("frequencies: start > stop, step <= 0, non-positive values, too many") {
  const std::string deck =
      kSdof + "[excitation]\nkind = \"stepped_sine\"\namplitude = 1\n";  // frequencies: line 8
  check_error(
      deck + "frequencies = { start = 18, stop = 12, step = 0.5 }\n",
      "8:36: 'excitation.frequencies.stop': ", "expected a number >= start (18 Hz), got 12");
  check_error(deck + "frequencies = { start = 12, stop = 18, step = 0 }\n",
              "8:47: 'excitation.frequencies.step': ", "expected a positive number (Hz), got 0");
  check_error(deck + "frequencies = { start = 12, stop = 18, step = -0.5 }\n",
              "8:47: 'excitation.frequencies.step': ", "got -0.5");
  check_error(deck + "frequencies = { start = 0, stop = 18, step = 0.5 }\n",
              "8:25: 'excitation.frequencies.start': ", "expected a positive number (Hz), got 0");
  check_error(deck + "frequencies = [12, 0, 14]\n", "8:20: 'excitation.frequencies': ", "got 0");
  check_error(deck + "frequencies = [12, -13.5]\n",
              "8:20: 'excitation.frequencies': ", "got -13.5");
  check_error(deck + "frequencies = []\n", "8:15: 'excitation.frequencies': ",
              "a non-empty array of positive numbers (Hz), got an array of 0");
  check_error(
      deck + "frequencies = { start = 12, stop = 18, step = 1e-4 }\n",
      "8:47: 'excitation.frequencies.step': ", "expected at most 10000 frequencies, got 60001");
  // a list is run as written, "down" reverses it
  const Deck down = parse_deck(deck + "frequencies = [14, 12, 13]\ndirection = \"down\"\n", "d");
  CHECK(down.excitation.frequencies == std::vector<double>{13, 12, 14});
}

TEST_CASE("missing required keys name the key at its table") {
  check_error("[structure]\nkind = \"sdof\"\nstiffness = 1.0\n" + kSine, "1:1: 'structure.mass': ",
              "missing: expected a positive number (kg), required for kind = \"sdof\"");
  check_error(kSdof + "[excitation]\nkind = \"stepped_sine\"\namplitude = 1.0\n",
              "5:1: 'excitation.frequencies': ", "missing: expected a table { start, stop, step }");
  check_error(kSdof + "[excitation]\nkind = \"sine\"\namplitude = 1.0\nduration = 1.0\n",
              "5:1: 'excitation.frequency': ", "required for kind = \"sine\"");
  check_error(kSdof + "[excitation]\nkind = \"sine\"\namplitude = 1.0\nfrequency = 15.0\n",
              "5:1: 'excitation.duration': ", "missing: expected a positive number (s)");
  check_error(kSdof + "[excitation]\nkind = \"free_decay\"\nduration = 1.0\n",
              "5:1: 'excitation.initial_displacement': ", "required for kind = \"free_decay\"");
  check_error(kSdof, " 'excitation': ", "missing: expected a table, required in every deck");
  check_error(kSine, " 'structure': ",
              "missing: expected a table, required unless excitation.kind = \"prescribed\"");
  const std::string box =
      "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
      "particles = { count = 1, diameter = 0.005, density = 7800 }\n";
  check_error(
      box + kContact + "[excitation]\nkind = \"prescribed\"\nduration = 1\n",
      "6:1: 'excitation.motion': ", "missing: expected a table { axis, amplitude, frequency }");
  check_error(
      "[excitation]\nkind = \"prescribed\"\nmotion = { axis = [1, 0, 0], amplitude = 1e-3 }\n",
      "3:10: 'excitation.motion.frequency': ", "or excitation.frequencies for a sweep");
  check_error(
      "[excitation]\nkind = \"prescribed\"\n"
      "motion = { axis = [1, 0, 0], amplitude = 1e-3, frequency = 20 }\n",
      " 'damper': ", "missing: expected a [[damper]] table");
  check_error(kSdof + kSine + box + "[contact]\nmodel = \"linear\"\ntangential = \"none\"\n",
              "13:1: 'contact.stiffness': ", "required for model = \"linear\"");
  check_error(kSdof + kSine + box, " 'contact.young': ",
              "missing: expected a positive number (Pa), required for model = \"hertz\"");
  check_error(kSdof + kSine + box + "[contact]\nmodel = \"linear\"\nstiffness = 1e5\n",
              "13:1: 'contact.young': ", "required for tangential = \"history\"");
  const std::string beam =
      "[structure]\nkind = \"beam\"\nlength = 0.5\nelements = 16\nyoung = 7e10\ndensity = 2700\n"
      "section = { shape = \"rectangle\", width = 0.03, height = 0.005 }\n" +
      kSine + kContact;  // [[damper]] on line 15
  check_error(beam + box, "15:1: 'damper[0].attach': ",
              "missing: expected a table { node = K } or { x = position along the beam (m) }");
  check_error(
      "[structure]\nkind = \"beam\"\nlength = 0.5\nelements = 16\nyoung = 7e10\n"
      "density = 2700\nsection = { area = 1e-4, inertia = 1e-9 }\ntimoshenko = true\n" +
          kSine,
      "7:11: 'structure.section.shear_factor': ", "required by timoshenko = true");
  // output.file may be left out: the CLI derives it from the deck name
  CHECK(parse_deck(kSdof + kSine + "[output]\nenergy = true\n", "d").output.file.empty());
  check_error(kSdof + kSine + "[output]\nfile = \"\"\n",
              "11:8: 'output.file': ", "expected a file name");
}

TEST_CASE("keys that exclude each other") {
  check_error(kSdof + "damping_ratio = 0.01\ndamping = 2.0\n" + kSine,
              "6:11: 'structure.damping': ", "give either damping or damping_ratio, not both");
  const std::string beam =
      "[structure]\nkind = \"beam\"\nlength = 0.5\nelements = 16\nyoung = 7e10\ndensity = 2700\n"
      "section = { shape = \"circle\", diameter = 0.01 }\n";
  check_error(beam + "damping_ratio = 0.01\nrayleigh = [1, 1e-5]\n" + kSine,
              "9:12: 'structure.rayleigh': ", "give either rayleigh or damping_ratio, not both");
  // A positive diameter whose area underflows (found by the deck fuzz test: no modes).
  std::string tiny = beam;
  tiny.replace(tiny.find("0.01 }"), 4, "5e-324");
  check_error(tiny + kSine, "7:42: 'structure.section.diameter': ",
              "expected a section whose area and second moment are normal numbers, got 0 m^2");
  check_error(kSdof + kSine + kContact +
                  "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
                  "particles = { count = 1, diameter = 0.005, diameters = [0.005], density = 1 }\n",
              "14:56: 'damper[0].particles.diameters': ",
              "give only one of diameter, diameters and diameter_range");
  check_error(
      "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
      "particles = { count = 1, diameter = 0.005, density = 7800 }\n" +
          kContact + "[excitation]\nkind = \"prescribed\"\n" +
          "motion = { axis = [1, 0, 0], amplitude = 0.004, frequency = 20 }\n"
          "frequencies = [10, 20]\n",
      "9:15: 'excitation.frequencies': ", "give either motion.frequency or frequencies, not both");
}

TEST_CASE("structure against excitation kind, and attach against structure kind") {
  const std::string box =
      "[[damper]]\ncontainer = { shape = \"box\", size = [1, 1, 1] }\n"
      "particles = { count = 1, diameter = 0.005, density = 7800 }\n";
  check_error(kSdof + kContact + box + "[excitation]\nkind = \"prescribed\"\n" +
                  "motion = { axis = [1, 0, 0], amplitude = 0.004, frequency = 20 }\n",
              "1:1: 'structure': ", "not allowed with excitation.kind = \"prescribed\"");
  check_error(kSdof + kSine + kContact + box + "attach = { node = 1 }\n",
              "15:10: 'damper[0].attach': ", "only a beam structure takes attach");
  const std::string beam =
      "[structure]\nkind = \"beam\"\nlength = 0.5\nelements = 16\nyoung = 7e10\ndensity = 2700\n"
      "section = { shape = \"rectangle\", width = 0.03, height = 0.005 }\n" +
      kSine + kContact + box;  // attach on line 18
  check_error(beam + "attach = { x = 0.6 }\n", "18:16: 'damper[0].attach.x': ",
              "expected a position along the beam from 0 to 0.5 (m), got 0.6");
  check_error(beam + "attach = { node = 17 }\n", "18:19: 'damper[0].attach.node': ",
              "expected an integer (node index) from 0 to 16, got 17");
  check_error(beam + "attach = { node = 1, x = 0.1 }\n",
              "18:10: 'damper[0].attach': ", "exactly one of node and x");
}

// What a resume compares (io/decks.md): keys by value, not layout or comments; pdsim's own notes
// (a sweep point's values, a map run's motion) as a change of their own.
TEST_CASE("deck_changes names changed keys and pdsim's notes, not layout or a user's comment") {
  const std::string before = kSdof + kSine + "# pdsim is the code we use\n";
  const std::string moved = kSine + "\n\n" + kSdof + "# pdsim, as told\n";
  CHECK(deck_changes(before, moved).empty());
  const std::string stiffer = kSdof + "damping = 0.5\n" + kSine;
  const std::vector<DeckChange> changes = deck_changes(before, stiffer);
  REQUIRE(changes.size() == 1);
  CHECK(changes[0].key == "structure.damping");
  CHECK(changes[0].before == "absent");
  CHECK(changes[0].after == "0.5");
  const std::vector<DeckChange> other = deck_changes(before + "# sweep point 1 of 2: x = 1\n",
                                                     before + "# sweep point 2 of 2: x = 2\n");
  REQUIRE(other.size() == 1);
  CHECK(other[0].key == "pdsim's note");
  CHECK(other[0].before == "\"sweep point 1 of 2: x = 1\"");
}

TEST_CASE("a TOML syntax error keeps toml++'s line and column") {
  const std::string path = kDecks + "bad_syntax.toml";
  const std::string message = load_error(path);
  INFO(message);
  CHECK(message.rfind(path + ":4:8: ", 0) == 0);
  CHECK(load_error(kDecks + "no_such_deck.toml") ==
        kDecks + "no_such_deck.toml: cannot open the deck file");
}

// Two dampers and a [sweep] of two keys; the sweep starts on line 10.
const std::string kSweepDeck =
    kSdof + kSine +  // lines 1-9
    "[sweep]\n"
    "\"damper.particles.count\" = [3, 4]\n"
    "\"excitation.amplitude\" = [1.0, 2.0, 3.0]\n" +
    kContact +
    "[[damper]]\ncontainer = { shape = \"box\", size = [0.05, 0.05, 0.05] }\n"
    "particles = { count = 2, diameter = 0.005, density = 7800.0 }\n"
    "[[damper]]\ncontainer = { shape = \"box\", size = [0.05, 0.05, 0.05] }\n"
    "particles = { count = 2, diameter = 0.005, density = 7800.0 }\n";

TEST_CASE("a sweep is every combination of its values, the last key fastest") {
  const Deck deck = parse_deck(kSweepDeck, "deck.toml");
  REQUIRE(deck.sweep.points() == 6);
  CHECK(deck.sweep.keys ==
        std::vector<std::string>{"damper.particles.count", "excitation.amplitude"});
  CHECK(deck.sweep.describe(1) == "damper.particles.count = 3, excitation.amplitude = 1.0");
  CHECK(deck.sweep.describe(5) == "damper.particles.count = 4, excitation.amplitude = 2.0");
  for (int k = 1; k <= 6; ++k) {
    CAPTURE(k);
    const Deck point = sweep_point(deck, k);
    CHECK(point.point == k);
    // "damper" without an index sets every damper.
    CHECK(point.dampers.at(0).particles.count == (k <= 3 ? 3 : 4));
    CHECK(point.dampers.at(1).particles.count == (k <= 3 ? 3 : 4));
    CHECK(point.excitation.amplitude == 1.0 + (k - 1) % 3);
    CHECK(point.structure.mass == 2.0);  // untouched
    CHECK(point.text.find("# sweep point " + std::to_string(k) + " of 6: ") != std::string::npos);
  }
  std::string one = kSweepDeck;
  one.replace(one.find("\"damper.particles"), 8, "\"damper[1].");
  const Deck second_only = sweep_point(parse_deck(one, "deck.toml"), 4);
  CHECK(second_only.dampers.at(0).particles.count == 2);
  CHECK(second_only.dampers.at(1).particles.count == 4);
}

TEST_CASE("a bad sweep value or key is refused at its place in the [sweep] table") {
  auto point_error = [](const std::string& sweep_lines, int point) {
    const std::string text = kSdof + kSine + "[sweep]\n" + sweep_lines + "\n";  // sweep: line 11
    try {
      sweep_point(parse_deck(text, "deck.toml"), point);
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string("(no error)");
  };
  // The value's own position: line 11, column 26 is the -2.0.
  std::string e = point_error("\"structure.mass\" = [1.0, -2.0]", 2);
  CHECK(e.rfind("deck.toml:11:26: 'structure.mass': expected a positive number", 0) == 0);
  CHECK(e.find("(sweep point 2 of 2: structure.mass = -2.0)") != std::string::npos);
  CHECK(point_error("\"structure.mass\" = [1.0, -2.0]", 1) == "(no error)");
  // A misspelt key is an unknown key at the sweep entry, with the suggestion.
  e = point_error("\"structure.mas\" = [1.0]", 1);
  CHECK(e.rfind("deck.toml:11:1: 'structure.mas': unknown key", 0) == 0);
  CHECK(e.find("did you mean 'mass'?") != std::string::npos);
  e = point_error("\"damper[0].particles.count\" = [5]", 1);
  CHECK(e.rfind("deck.toml:11:1: 'sweep.\"damper[0].particles.count\"': 'damper' does not exist",
                0) == 0);
  check_error(kSdof + kSine + "[sweep]\n\"structure.mass\" = 3.0\n",
              "11:20: 'sweep.\"structure.mass\"'", "expected an array of the values to sweep");
  check_error(kSdof + kSine + "[sweep]\n\"structure\" = [1]\n", "11:1: 'sweep.\"structure\"'",
              "expected a key inside a deck table");
  check_error(
      kSdof + kSine + "[sweep]\n\"damper.particles.count\" = [1]\n\"damper.particles\" = [{}]\n",
      "12:1:", "overlaps the sweep key");
  check_error(kSdof + kSine + "[sweep]\n\"damper[1].particles.count\" = [1]\n" +
                  "\"damper.particles.count\" = [2]\n",
              "12:1:", "overlaps the sweep key");
  const Deck deck = parse_deck(kSdof + kSine + "[sweep]\n\"structure.mass\" = [1.0, 2.0]\n", "d");
  try {
    sweep_point(deck, 3);
    FAIL("point 3 of 2 accepted");
  } catch (const InputError& error) {
    CHECK(std::string(error.what()).find("points 1 to 2") != std::string::npos);
  }
}

TEST_CASE("directions are normalised without overflow or underflow") {
  auto direction = [](const std::string& v) {
    return parse_deck(kSdof + "direction = " + v + "\n" + kSine, "d").structure.direction;
  };
  const Vec3 big = direction("[1e308, 0, 1]");  // its length squared overflows
  CHECK(big.x == 1.0);
  CHECK(std::isfinite(big.z));
  CHECK(direction("[1e-200, 0, 0]").x == 1.0);  // its length squared underflows
  check_error(kSdof + "direction = [0, 0, 0]\n" + kSine,
              "5:13: 'structure.direction': ", "got [0, 0, 0]");
}

TEST_CASE("a key given twice is said plainly, and a huge value is cut in the message") {
  const std::string twice = error_of(kSdof + kSine + "[sweep]\n\"structure.mass\" = [1, 2]\n" +
                                     "\"structure.mass\" = [3]\n");
  CHECK(twice.find("a key or table given twice: expected each key once") != std::string::npos);
  CHECK(twice.find("ststructure") == std::string::npos);  // toml++'s garbled quote
  std::string deck = kSdof + kSine;
  deck.replace(deck.find("mass = 2.0"), 10, "mass = \"" + std::string(1'000'000, 'x') + "\"");
  const std::string huge = error_of(deck);
  CHECK(huge.find("'structure.mass'") != std::string::npos);
  CHECK(huge.find("(1000000 characters)") != std::string::npos);
  CHECK(huge.size() < 300);
}

}  // namespace
}  // namespace pdsim

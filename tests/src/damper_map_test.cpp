// pdsim map against the mechanics of one ball on a floor shaken sideways (a box of 3 cm, one
// steel ball of 4 mm, friction 0.3, gravity across the motion). Below 3.5 mu g the ball rolls
// without slipping: the floor's friction f accelerates it as f = m a_ball and spins it up as
// f r = (2/5) m r^2 alpha, and rolling (a_ball - a = -alpha r) gives f = (2/7) m a, in phase
// with the acceleration: an effective mass of 2/7 m and no damping. Well above it the ball slides
// the whole period: the friction is mu m g against the sliding, a square wave whose first
// harmonic is 4/pi mu m g.
#include <doctest/doctest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "src/damper_map.hpp"
#include "src/predict.hpp"

using namespace pdsim;
namespace fs = std::filesystem;

namespace {

const char* kBallDeck = R"(title = "one ball on a shaken floor"
[structure]
kind = "sdof"
mass = 0.5
stiffness = 5000.0
damping_ratio = 0.02
[[damper]]
container = { shape = "box", size = [0.03, 0.03, 0.02] }
particles = { count = 1, diameter = 0.004, density = 7800.0, seed = 3 }
[contact]
model = "linear"
tangential = "history"
stiffness = 2000.0
young = 2.0e8
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "stepped_sine"
amplitude = 1.0
frequencies = [15.0]
settle = { min_periods = 6, max_periods = 60, batches = 3, realisations = 1 }
[solver]
threads = 1
[map]
accelerations = [0.1, 3.0]
frequencies = [15.0, 20.0]
)";

// Every point of a map of the ball checked against rolling (below 3.5 mu g) or sliding; while
// it rolls, its loss factor c_eff / (w m_eff) below `rolling_loss`.
void check_ball(const MapTable& m, double rolling_loss = 1e-3) {
  const double mass = 7800.0 * 4.0 / 3.0 * kPi * std::pow(0.002, 3), mu = 0.3, g = 9.81;
  for (std::size_t i = 0; i < m.frequency.size(); ++i) {
    CAPTURE(m.frequency[i]);
    CAPTURE(m.acceleration[i]);
    CAPTURE(m.sweep[i]);
    CHECK(m.converged[i] == 1);
    const double w = 2 * kPi * m.frequency[i];
    CHECK(m.amplitude[i] * w * w / kStandardGravity == doctest::Approx(m.acceleration[i]));
    if (m.acceleration[i] < 3.5 * mu) {
      // Rolling: the contact springs (a contact time of 1.3 ms against a period of 50-67 ms)
      // add a little; no sliding, so no loss beyond the integrator's (loss factor < 1e-3).
      CHECK(m.effective_mass[i] == doctest::Approx(2.0 / 7.0 * mass).epsilon(5e-3));
      CHECK(std::abs(m.effective_damping[i]) < rolling_loss * w * m.effective_mass[i]);
    } else {
      CHECK(m.force_amplitude[i] == doctest::Approx(4 / kPi * mu * mass * g).epsilon(5e-3));
      CHECK(m.dissipated_power[i] > 0);
      CHECK(m.effective_damping[i] > 0);
    }
  }
}

// A quiet map into `file`, one job at a time.
MapOptions map_into(const fs::path& file) {
  MapOptions o;
  o.output = file.string();
  o.quiet = true;
  o.jobs = 1;
  return o;
}

}  // namespace

TEST_CASE("a map of one ball: 2/7 of its mass while it rolls, 4/pi mu m g once it slides") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_map_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const Deck deck = parse_deck(kBallDeck, "ball.toml");
  MapOptions options = map_into(dir / "ball_map.h5");
  const RunReport report = run_map(deck, options);
  const MapTable m = read_results(report.output).map;
  REQUIRE(m.frequency.size() == 4);          // 2 accelerations x 2 frequencies
  CHECK(m.sweep == std::vector<int>(4, 0));  // each from the settled bed
  check_ball(m);
  // A finished map is not overwritten without --force; its runs are kept beside it, and with
  // --resume a map is made from the finished runs without running them again.
  CHECK_THROWS_WITH_AS(run_map(deck, options), doctest::Contains("map file exists"), InputError);
  fs::remove(report.output);
  options.resume = true;
  const RunReport again = run_map(deck, options);
  const MapTable n = read_results(again.output).map;
  CHECK(n.effective_mass == m.effective_mass);
  CHECK(n.force_amplitude == m.force_amplitude);

  // The map predicts a host of this damper (its structure's mass doubled is another host, the
  // same damper); a deck of another damper, or one map read twice, is refused.
  std::string host = kBallDeck;
  host.replace(host.find("mass = 0.5"), 10, "mass = 1.0");
  PredictOptions predict;
  predict.maps = {again.output};
  predict.output = (dir / "hb.h5").string();
  CHECK(read_results(run_predict(parse_deck(host, "host.toml"), predict).output)
            .frf_hb.frequency.size() >= 1);
  // Each field that makes another damper is named, with its value in the map and in the deck.
  predict.force = true;
  struct Edit {
    std::string from, to;
    std::vector<std::string> said;
  };
  const Edit edits[] = {
      {"size = [0.03",
       "size = [0.04",
       {"damper[0].container: box size 0.03 x 0.03 x 0.02 m in the map, box size 0.04 x 0.03 x "
        "0.02 m "
        "in the deck"}},
      {"diameter = 0.004",
       "diameter = 0.005",
       {"damper[0].particles.diameter: 0.004 m in the map, 0.005 m in the deck"}},
      {"friction = 0.3", "friction = 0.2", {"contact.friction: 0.3 in the map, 0.2 in the deck"}},
      {"-9.81]", "-9.8]", {"gravity: 0 0 -9.81 m/s^2 in the map, 0 0 -9.8 m/s^2 in the deck"}},
      {"threads = 1",
       "threads = 1\ndt = 1.0e-5",
       {"solver.dt: ", " s in the map, 1e-05 s in the deck"}}};
  for (const Edit& edit : edits) {
    std::string other = kBallDeck;
    other.replace(other.find(edit.from), edit.from.size(), edit.to);
    CAPTURE(edit.to);
    std::string message;
    try {
      run_predict(parse_deck(other, "other.toml"), predict);
    } catch (const InputError& e) {
      message = e.what();
    }
    CAPTURE(message);
    CHECK(message.find("a map of another damper than the deck's") != std::string::npos);
    for (const std::string& part : edit.said) CHECK(message.find(part) != std::string::npos);
  }
  predict.maps = {again.output, again.output};
  CHECK_THROWS_WITH_AS(run_predict(deck, predict), doctest::Contains("twice"), InputError);
  fs::remove_all(dir);
}

// Rigid contacts: a step follows each run's motion, so each run settles and keeps its own bed
// (a shared one was refused by the second run); the ball rolls and slides as with springs.
TEST_CASE(
    "a map of one ball on rigid contacts: each run its own bed; it rolls and slides as it should") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_map_rigid_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::string text = kBallDeck;
  for (const char* penalty :
       {"tangential = \"history\"\n", "stiffness = 2000.0\n", "young = 2.0e8\n"})
    text.erase(text.find(penalty), std::string(penalty).size());
  text.replace(text.find("model = \"linear\""), 16, "model = \"nonsmooth\"");
  const Deck deck = parse_deck(text, "rigid.toml");
  MapOptions options = map_into(dir / "rigid_map.h5");
  const MapTable m = read_results(run_map(deck, options).output).map;
  REQUIRE(m.frequency.size() == 4);
  // `check` gives the runs' steps and tolerances: the smallest, a tenth of the floor's speed
  // at 0.1 g and 20 Hz, 0.1 x 0.1 g / (2 pi 20 Hz) = 7.804e-4 m/s.
  CHECK(check_map(deck, 1, Backend::cpu).find("the tolerance 0.0007804 to ") != std::string::npos);
  for (const char* bed : {"bed_m001.h5", "bed_m002.h5", "bed_m003.h5", "bed_m004.h5"})
    CHECK(fs::exists(dir / "rigid_map_runs" / bed));
  CHECK_FALSE(fs::exists(dir / "rigid_map_runs" / "bed.h5"));
  // Rolling, the rigid contacts lose no more than the springs (a loss factor below 1e-3): their
  // walls move by the step's chord, and velocities are met to a tenth of the floor's speed
  // (before both, 0.06-0.08: omega dt / 2 from the velocity at the step's start, the rest from
  // a step's friction reused while within a tolerance as large as the motion).
  check_ball(m);
  // A bed's setting changed: --force settles every run's bed anew (it refused them before).
  std::string longer = text;
  longer.replace(longer.find("[solver]"), 8, "[bed]\nmax_time = 1.5\n[solver]");
  options.force = true;
  CHECK(read_results(run_map(parse_deck(longer, "rigid.toml"), options).output)
            .map.frequency.size() == 4);
  // A threshold the deck sets is the damper's model: a map made without it predicts no deck
  // with it (derived ones follow each run's motion and may differ).
  std::string tighter = text;
  tighter.replace(tighter.find("friction = 0.3"), 14, "friction = 0.3\ntolerance = 1.0e-4");
  PredictOptions predict;
  predict.maps = {options.output};
  predict.output = (dir / "hb.h5").string();
  CHECK(read_results(run_predict(deck, predict).output).frf_hb.frequency.size() >= 1);
  predict.force = true;
  CHECK_THROWS_WITH_AS(
      run_predict(parse_deck(tighter, "tight.toml"), predict),
      doctest::Contains("contact.tolerance: derived in the map, 1e-04 m/s in the deck"),
      InputError);
  // A map made before the walls moved at the chord's velocity (its identity without the line)
  // is another model's: refused by name.
  Results older = read_results(options.output);
  std::string& id = older.meta_text.at("identity");
  const std::size_t line = id.find("contact.walls = ");
  REQUIRE(line != std::string::npos);
  id.erase(line, id.find('\n', line) + 1 - line);
  const std::string older_map = (dir / "older_map.h5").string();
  write_results(older_map, older, true, true);
  predict.maps = {older_map};
  CHECK_THROWS_WITH_AS(run_predict(deck, predict),
                       doctest::Contains("contact.walls: absent in the map"), InputError);
  fs::remove_all(dir);
}

// A map (4 runs: 2 accelerations x 2 frequencies) run one grid run at a time, as Slurm's tasks
// run it (`pdsim map --run K`), then collected (`--collect`), is the map run whole: the ball's
// physics and the same numbers.
TEST_CASE("a map run a grid run at a time and collected is the map run whole") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_map_runs_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const Deck deck = parse_deck(kBallDeck, "ball.toml");
  MapOptions whole = map_into(dir / "whole_map.h5");
  const MapTable m = read_results(run_map(deck, whole).output).map;
  MapOptions task = whole;
  task.output = (dir / "split_map.h5").string();
  task.collect = true;
  CHECK_THROWS_WITH_AS(run_map(deck, task),
                       doctest::Contains("runs 1, 2, 3, 4 of 4 have not finished"),
                       std::runtime_error);
  task.collect = false;
  task.run = 2;
  CHECK(run_map(deck, task).output.empty());  // a run, no map
  CHECK(run_map(deck, task).summary.find("finished earlier, kept") != std::string::npos);
  task.run = 5;
  CHECK_THROWS_WITH_AS(run_map(deck, task), doctest::Contains("the map has runs 1 to 4"),
                       InputError);
  for (int k : {1, 3, 4}) {
    task.run = k;
    run_map(deck, task);
  }
  task.run = 0;
  task.collect = true;
  const MapTable n = read_results(run_map(deck, task).output).map;
  check_ball(n);
  CHECK(n.frequency == m.frequency);
  CHECK(n.effective_mass == m.effective_mass);
  CHECK(n.effective_damping == m.effective_damping);
  CHECK(n.force_amplitude == m.force_amplitude);
  fs::remove_all(dir);
}

// Stepped up and back down at each frequency, the ball carried from one amplitude to the next:
// it slides at 3 g and rolls again at 0.1 g on the way down (a single ball has no hysteresis),
// and the points come in the order they ran.
TEST_CASE("a map of one ball stepped up and down: it rolls again on the way down") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_map_steps_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::string text = kBallDeck;
  text.insert(text.find("accelerations"), "steps = \"both\"\n");
  MapOptions options = map_into(dir / "ball_map.h5");
  const MapTable m = read_results(run_map(parse_deck(text, "ball.toml"), options).output).map;
  REQUIRE(m.frequency.size() == 8);  // 2 frequencies x (2 up + 2 down)
  CHECK(m.frequency == std::vector<double>{15, 15, 15, 15, 20, 20, 20, 20});
  CHECK(m.sweep == std::vector<int>{1, 1, -1, -1, 1, 1, -1, -1});
  CHECK(m.acceleration[0] == doctest::Approx(0.1));
  CHECK(m.acceleration[1] == doctest::Approx(3.0));
  CHECK(m.acceleration[2] == doctest::Approx(3.0));
  CHECK(m.acceleration[3] == doctest::Approx(0.1));
  check_ball(m);
  fs::remove_all(dir);
}

TEST_CASE("[map] refuses what it cannot map, naming the key or the reason") {
  auto refused = [](const std::string& map, const std::string& message) {
    std::string text = kBallDeck;
    text = text.substr(0, text.find("[map]")) + map;
    CAPTURE(map);
    CHECK_THROWS_WITH_AS(map_runs(parse_deck(text, "ball.toml"), "runs"),
                         doctest::Contains(message.c_str()), InputError);
  };
  refused("", "no [map] table");
  refused("[map]\nfrequencies = [10.0]\n", "give either amplitudes (m) or accelerations (g)");
  refused("[map]\namplitudes = [0.001]\naccelerations = [1.0]\nfrequencies = [10.0]\n",
          "give either amplitudes");
  refused("[map]\namplitudes = [-0.001]\nfrequencies = [10.0]\n", "map.amplitudes");
  refused("[map]\namplitudes = [0.001]\n", "map.frequencies");
  refused("[map]\namplitudes = [0.001, 0.001]\nfrequencies = [10.0]\n", "expected each value once");
  refused("[map]\namplitudes = [0.001]\nfrequencies = [10.0]\nspeed = 1\n", "map.speed");
  refused("[map]\namplitudes = [0.001]\nfrequencies = [10.0]\nsteps = \"sideways\"\n",
          "\"independent\", \"up\", \"both\"");
  refused(
      "[map]\namplitudes = [0.001]\nfrequencies = [10.0]\n[sweep]\n\"contact.friction\" = [0.1]\n",
      "not with a [sweep] table");
}

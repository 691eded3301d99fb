// The /energy ledger closes: over whole runs of small scenes, the input's work equals the losses
// by mechanism plus the change of kinetic and potential energy, within 0.5 % of the work put in
// (of the initial energy in a free decay), for every input, container, structure and coupling
// scheme; and a stepped sine's per-frequency tallies match the containers' input.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "src/run.hpp"
#include "tests/support/validation_row.hpp"

using namespace pdsim;

namespace {

// 24 soft spheres (4 mm) on an SDOF, with friction, rolling resistance and gravity.
const std::string kStructure = R"(
[structure]
kind = "sdof"
mass = 0.5
stiffness = 5000.0
damping_ratio = 0.02
direction = [1.0, 0.0, 0.0]
)";
const std::string kBox = R"(
[[damper]]
container = { shape = "box", size = [0.02, 0.02, 0.02] }
particles = { count = 24, diameter = 0.004, density = 7800.0, seed = 3 }
)";
// One thread: a few dozen particles run faster than OpenMP can share them.
// Rigid contacts (model "nonsmooth") take restitution and friction only.
std::string contact(const std::string& model = "linear", const std::string& solver = "") {
  const std::string penalty = R"(tangential = "history"
stiffness = 2000.0
young = 2.0e8
rolling_friction = 0.02
)";
  return R"(
[contact]
model = ")" +
         model + "\"\n" + (model == "nonsmooth" ? "" : penalty) +
         R"(restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[bed]
settle = false
[output]
file = "ledger.h5"
energy = true
[solver]
threads = 1
)" + solver;
}
std::string sine(const std::string& input, double amplitude, double duration = 0.4) {
  return "[excitation]\nkind = \"sine\"\ninput = \"" + input +
         "\"\namplitude = " + std::to_string(amplitude) +
         "\nfrequency = 15.0\nduration = " + std::to_string(duration) + "\n";
}
std::string scheme(const std::string& name) {
  return "[coupling]\nscheme = \"" + name + "\"\n";
}

// Largest |imbalance| over the run, relative to `reference` (J).
double worst_imbalance(const Results& r, double reference) {
  REQUIRE(r.energy.has_value());
  const EnergySeries& e = *r.energy;
  REQUIRE(e.imbalance.size() > 10);
  double worst = 0;
  for (double x : e.imbalance) worst = std::max(worst, std::fabs(x));
  const std::size_t n = e.time.size() - 1;
  MESSAGE("work in " << e.work_in[n] - e.work_in[0] << " J, dissipated: structure "
                     << e.dissipated_structure[n] << ", normal " << e.dissipated[kNormal][n]
                     << ", tangential " << e.dissipated[kTangential][n] << ", rolling "
                     << e.dissipated[kRolling][n] << " J; largest |imbalance| " << worst / reference
                     << " of " << reference << " J");
  return worst / reference;
}

Results run(const std::string& text) {
  const Deck deck = parse_deck(text, "ledger.toml");
  return simulate(deck, build_scene(deck));
}

double work_in(const Results& r) {
  return r.energy->work_in.back() - r.energy->work_in.front();
}

// A hard case's checks and validation rows (`name`: "hard case, ..."): the ledger closed to
// 0.5 % of the work put in, and the displacement within `bound` (m), the SDOF's from rest with
// the particles as a rigid mass.
void check_hard_case(const Results& r, const std::string& name, double bound) {
  const double imbalance = worst_imbalance(r, work_in(r));
  CHECK(imbalance <= 5e-3);
  double peak = 0;
  for (double x : r.timeseries.displacement) peak = std::max(peak, std::fabs(x));
  MESSAGE("peak displacement " << peak << " m, bound " << bound << " m");
  CHECK(peak <= bound);
  validation_bound(name + ": energy ledger imbalance / work in", "energy conservation", 5e-3,
                   imbalance, "");
  validation_bound(name + ": peak displacement", "SDOF from rest, particles as a rigid mass", bound,
                   peak, "m");
}

}  // namespace

TEST_CASE(
    "energy ledger: free decay with friction and rolling closes to 0.5 % of the initial "
    "energy") {
  const Results r = run(kStructure + kBox + contact() +
                        "[excitation]\nkind = \"free_decay\"\ninitial_displacement = 0.004\n"
                        "duration = 0.4\n");
  const EnergySeries& e = *r.energy;
  CHECK(e.dissipated[kTangential].back() > 0);
  CHECK(e.dissipated[kRolling].back() > 0);
  CHECK(work_in(r) == 0);
  CHECK(worst_imbalance(r, 0.5 * 5000.0 * 0.004 * 0.004) <= 5e-3);
}

TEST_CASE("energy ledger: force-driven sine, every coupling scheme") {
  for (const char* name : {"loose", "interleaved", "tight"}) {
    CAPTURE(name);
    const Results r = run(kStructure + kBox + contact() + sine("force", 1.0) + scheme(name));
    CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
  }
}

TEST_CASE("energy ledger: base acceleration, in the inertial frame") {
  const Results r = run(kStructure + kBox + contact() + sine("base_acceleration", 2.0));
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

// A bed shaken hard on its own: the contact tallies count each dashpot's work at the mid-step
// velocity its own force predicts (contact_tangential.hpp), which misses the other contacts'
// share of the velocity change: an O(dt) over-count, here 0.53 % of the input at the default
// dt (0.02 contact times), 1.1 % at 0.05 and 0.33 % at 0.01, the step run here.
TEST_CASE("energy ledger: prescribed container motion") {
  const Results r = run(kBox + contact("linear", "dt_safety = 0.01\n") +
                        "[excitation]\nkind = \"prescribed\"\nmotion = { axis = [1.0, 0.0, 0.0], "
                        "amplitude = 0.003, frequency = 20.0 }\nduration = 0.3\n");
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

TEST_CASE("energy ledger: a cylinder") {
  const Results r = run(kStructure +
                        "[[damper]]\ncontainer = { shape = \"cylinder\", radius = 0.01, "
                        "height = 0.02 }\nparticles = { count = 24, diameter = 0.004, density = "
                        "7800.0, seed = 3 }\n" +
                        contact() + sine("force", 1.0));
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

TEST_CASE("energy ledger: a beam with two dampers under base displacement") {
  const std::string beam = R"(
[structure]
kind = "beam"
length = 0.4
elements = 8
young = 7.0e10
density = 2700.0
section = { shape = "rectangle", width = 0.03, height = 0.005 }
supports = { start = "clamped", end = "free" }
damping_ratio = 0.01
direction = [0.0, 1.0, 0.0]
modes = 3
[[damper]]
container = { shape = "box", size = [0.02, 0.02, 0.02] }
particles = { count = 12, diameter = 0.004, density = 7800.0, seed = 3 }
attach = { node = 8 }
[[damper]]
container = { shape = "box", size = [0.02, 0.02, 0.02] }
particles = { count = 12, diameter = 0.004, density = 7800.0, seed = 4 }
attach = { node = 5 }
)";
  const Results r = run(beam + contact() + sine("base_displacement", 0.0005, 0.3));
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

TEST_CASE(
    "energy ledger: Hertz with Mindlin history (the Saeki law) closes with the stiffness "
    "term") {
  const Results r = run(kStructure + kBox + contact("hertz") + sine("force", 1.0));
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

TEST_CASE(
    "stepped sine: per-frequency normal + tangential + rolling dissipation equals the "
    "containers' input within 1 %") {
  const Results r = run(kStructure + kBox + contact() + R"([excitation]
kind = "stepped_sine"
amplitude = 1.0
frequencies = [15.5, 16.0, 16.5]
settle = { min_periods = 30, max_periods = 30, batches = 5 }
)");
  REQUIRE(r.frf.frequency.size() == 3);
  for (std::size_t i = 0; i < 3; ++i) {
    const double tallied = r.frf.dissipated[kNormal][i] + r.frf.dissipated[kTangential][i] +
                           r.frf.dissipated[kRolling][i];
    CAPTURE(r.frf.frequency[i]);
    MESSAGE("input " << r.frf.dissipated_energy[i] << " J per period, tallied " << tallied);
    CHECK(r.frf.dissipated_energy[i] > 0);
    CHECK(std::fabs(tallied - r.frf.dissipated_energy[i]) <= 0.01 * r.frf.dissipated_energy[i]);
  }
}

// Hard cases (issue 35): the ledger stays closed and the response bounded at the extremes of
// restitution, with this scene's linear contacts 100x stiffer at the auto dt (not yet the
// issue's 100x steel), and with diameters 1:4. The bound: started from rest, a damped SDOF
// driven at F sin(w t) below resonance stays within twice its steady amplitude
// F / |k - m w^2 + i c w| (2.001 times for this damping and frequency ratio). It is taken with
// the particles carried as a rigid mass, the largest m (the closest to resonance) they can add;
// a damper, whose impacts also take energy out, is expected under it, not proven to be.
TEST_CASE(
    "energy ledger: near-elastic, nearly plastic, 100x stiffer and 1:4 sizes close, bounded") {
  const double pi = std::acos(-1.0), w = 2 * pi * 15.0, k = 5000.0;
  const double c = 2 * 0.02 * std::sqrt(k * 0.5);  // damping_ratio of the bare structure
  auto sphere = [&](double d) { return 7800.0 * pi / 6 * d * d * d; };
  struct Case {
    const char* name;
    std::string from, to;  // in the contact and box text
    double particles;      // kg, at most
  };
  const std::string mono = "count = 24, diameter = 0.004";
  const Case cases[] = {
      {"restitution 0.99", "restitution = 0.5", "restitution = 0.99", 24 * sphere(0.004)},
      {"restitution 0.05", "restitution = 0.5", "restitution = 0.05", 24 * sphere(0.004)},
      {"stiffness x100", "stiffness = 2000.0", "stiffness = 200000.0", 24 * sphere(0.004)},
      {"diameters 2-8 mm", mono, "count = 12, diameter_range = [0.002, 0.008]",
       12 * sphere(0.008)}};
  for (const Case& hard : cases) {
    CAPTURE(hard.name);
    std::string text = kBox + contact();
    text.replace(text.find(hard.from), hard.from.size(), hard.to);
    const Results r = run(kStructure + text + sine("force", 1.0));
    check_hard_case(r, std::string("hard case, ") + hard.name,
                    2.001 * 1.0 / std::hypot(k - (0.5 + hard.particles) * w * w, c * w));
  }
}

// Hard cases (issue 35), continued: the Saeki law with contacts 100x stiffer than steel
// (E = 2e13 Pa) at the auto dt (3.2e-8 s: 0.2 s is 6 million steps), and a run of 1,000
// periods (67 s simulated). Each closes its ledger to 0.5 % of the work put in over the whole
// run (measured: 0.10 % and 0.024 %) and stays within the rigid-mass bound above (peaks 1.5 and
// 2.2 mm against 3.7 mm).
TEST_CASE("energy ledger: Hertz at 100x steel's stiffness, and 1,000 periods, close, bounded") {
  const double pi = std::acos(-1.0), w = 2 * pi * 15.0, k = 5000.0;
  const double c = 2 * 0.02 * std::sqrt(k * 0.5);
  const double particles = 24 * 7800.0 * pi / 6 * std::pow(0.004, 3);
  const double bound = 2.001 * 1.0 / std::hypot(k - (0.5 + particles) * w * w, c * w);
  struct Case {
    const char* name;
    std::string text;
  };
  std::string steel = contact("hertz");
  steel.replace(steel.find("young = 2.0e8"), 13, "young = 2.0e13");
  const Case cases[] = {
      {"hertz, E = 2e13 Pa", kStructure + kBox + steel + sine("force", 1.0, 0.2)},
      {"1,000 periods", kStructure + kBox + contact() + sine("force", 1.0, 1000 / 15.0)}};
  for (const Case& hard : cases) {
    CAPTURE(hard.name);
    const Deck deck = parse_deck(hard.text, "hard.toml");
    const Scene scene = build_scene(deck);
    const Results r = simulate(deck, scene);
    MESSAGE("dt " << scene.dt << " s, " << r.meta_numbers.at("simulated_time_s") << " s simulated");
    check_hard_case(r, std::string("hard case, ") + hard.name, bound);
  }
}

// Hard case (issue 35): a damper near a node of the driven mode. A cantilever (10 elements)
// driven through its base at its second mode, 161 Hz, with 12 settled spheres at 0.8 L, by the
// node of that mode (Euler-Bernoulli: x = 0.783 L), or at the tip. Euler-Bernoulli's mode shape
// phi2(0.8 L) / phi2(L) = 0.070 (beta2 L = 4.694), to which modes 1 and 3, off resonance, add a
// little: the response there is a fraction of the tip's, below 1 g, so its particles barely
// move and take almost nothing out, while the tip's slide and hop. Both ledgers close.
TEST_CASE("a damper near a node of the driven mode: the mode shape's motion, little loss, closed") {
  auto cantilever = [](int node) {
    return R"(
[structure]
kind = "beam"
length = 0.4
elements = 10
young = 7.0e10
density = 2700.0
section = { shape = "rectangle", width = 0.03, height = 0.005 }
supports = { start = "clamped", end = "free" }
damping_ratio = 0.01
direction = [0.0, 1.0, 0.0]
modes = 3
[[damper]]
container = { shape = "box", size = [0.02, 0.02, 0.02] }
particles = { count = 12, diameter = 0.004, density = 7800.0, seed = 3 }
attach = { node = )" +
           std::to_string(node) + " }\n" +
           std::string(contact()).replace(contact().find("settle = false"), 14, "settle = true") +
           "[excitation]\nkind = \"sine\"\ninput = \"base_acceleration\"\namplitude = 2.0\n"
           "frequency = 161.0\nduration = 0.5\n";
  };
  // Particle losses (J) over the last 0.25 s, the bed's fall and first transient past.
  auto late_loss = [](const Results& r) {
    const EnergySeries& e = *r.energy;
    const auto i = static_cast<std::size_t>(
        std::lower_bound(e.time.begin(), e.time.end(), e.time.back() - 0.25) - e.time.begin());
    double loss = 0;
    for (const auto& d : {e.dissipated[kNormal], e.dissipated[kTangential], e.dissipated[kRolling]})
      loss += d.back() - d[i];
    return loss;
  };
  const Results node = run(cantilever(8)), tip = run(cantilever(10));
  CHECK(worst_imbalance(node, work_in(node)) <= 5e-3);
  CHECK(worst_imbalance(tip, work_in(tip)) <= 5e-3);
  const double ratio = node.frf.amplitude.front() / tip.frf.amplitude.front();
  const double w = 2 * std::acos(-1.0) * 161.0;
  MESSAGE("amplitude ratio " << ratio << " (mode shape 0.070); acceleration at 0.8 L "
                             << node.frf.amplitude.front() * w * w << " m/s^2; particle losses "
                             << late_loss(node) << " and " << late_loss(tip) << " J");
  CHECK(ratio > 0.05);
  CHECK(ratio < 0.1);
  CHECK(node.frf.amplitude.front() * w * w < 9.81);
  CHECK(late_loss(node) < 0.05 * late_loss(tip));
}

// The same bed with rigid contacts (kernels/nonsmooth.hpp): the impulses' work is tallied as
// the impulse times the mean of the contact's relative velocity before and after the step,
// which is what the bodies' kinetic energy loses to it.
TEST_CASE("energy ledger with rigid contacts: force-driven sine, every scheme, and shaken") {
  for (const char* name : {"loose", "interleaved", "tight"}) {
    CAPTURE(name);
    const Results r =
        run(kStructure + kBox + contact("nonsmooth") + sine("force", 1.0) + scheme(name));
    CHECK(r.energy->dissipated[kNormal].back() > 0);
    CHECK(r.energy->dissipated[kTangential].back() > 0);
    CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
  }
  const Results r = run(kBox + contact("nonsmooth") +
                        "[excitation]\nkind = \"prescribed\"\nmotion = { axis = [1.0, 0.0, 0.0], "
                        "amplitude = 0.003, frequency = 20.0 }\nduration = 0.3\n");
  CHECK(worst_imbalance(r, work_in(r)) <= 5e-3);
}

// The hard cases above with rigid contacts: near-elastic and nearly plastic impacts, diameters
// 1:4, 1,000 periods, and particles a third of a light structure's mass (0.02 kg, whose 69 Hz
// mode a 15 Hz drive leaves below twice the steady amplitude too; tight coupling, which
// resolves an impact with the structure's answer; the bed settled first, since its fall would
// release 8 times the work the drive puts in; a quarter of the auto step, where its ledger
// closes to 0.19 %: at the auto step to 0.98 %, a first-order drift of the coupled step, and
// interleaved 0.52 %, loose 4.6 %, with the warning the scene gives). Each closes its ledger
// to 0.5 % of the work put in and stays within the rigid-mass bound.
TEST_CASE("rigid contacts' hard cases: closed and bounded, heavy particles on a light structure") {
  const double pi = std::acos(-1.0), w = 2 * pi * 15.0, k = 5000.0;
  auto sphere = [&](double d) { return 7800.0 * pi / 6 * d * d * d; };
  using Edits = std::vector<std::pair<std::string, std::string>>;  // in the deck's text
  struct Case {
    const char* name;
    Edits edits;
    double particles;  // kg, at most
    double mass;       // kg, the structure's
    std::string more;  // tables added to the deck
    double duration;   // s
  };
  const double balls = 24 * sphere(0.004);
  const Case cases[] = {
      {"restitution 0.99", {{"restitution = 0.5", "restitution = 0.99"}}, balls, 0.5, "", 0.4},
      {"restitution 0.05", {{"restitution = 0.5", "restitution = 0.05"}}, balls, 0.5, "", 0.4},
      {"diameters 2-8 mm",
       {{"count = 24, diameter = 0.004", "count = 12, diameter_range = [0.002, 0.008]"}},
       12 * sphere(0.008),
       0.5,
       "",
       0.4},
      {"1,000 periods", {}, balls, 0.5, "", 1000 / 15.0},
      {"particles 0.31 of a 0.02 kg structure, tight coupling",
       {{"mass = 0.5", "mass = 0.02"},
        {"settle = false", "settle = true"},
        {"threads = 1", "threads = 1\ndt_safety = 0.05"}},
       balls,
       0.02,
       scheme("tight"),
       0.4}};
  for (const Case& hard : cases) {
    CAPTURE(hard.name);
    std::string text =
        kStructure + kBox + contact("nonsmooth") + hard.more + sine("force", 1.0, hard.duration);
    for (const auto& [from, to] : hard.edits) text.replace(text.find(from), from.size(), to);
    const double c = 2 * 0.02 * std::sqrt(k * hard.mass);  // damping_ratio of the bare structure
    check_hard_case(run(text), std::string("hard case, rigid contacts, ") + hard.name,
                    2.001 * 1.0 / std::hypot(k - (hard.mass + hard.particles) * w * w, c * w));
  }
}

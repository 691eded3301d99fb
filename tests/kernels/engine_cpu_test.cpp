// The OpenMP engine (kernels/cpu/engine_cpu.hpp) on many-particle scenes: energy conservation
// of an elastic gas, static equilibrium of piles (force balance, overlaps against Hertz), and
// bitwise reproducibility across thread counts and checkpoints.
#include "kernels/engine.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <type_traits>
#include <variant>

#include "tests/kernels/dem_fixtures.hpp"
#include "tests/support/validation_row.hpp"

namespace pdsim {
namespace {

using namespace fixtures;

constexpr double kGravity = 9.81;  // m/s^2

// Uniform double in [a, b) from a fixed-seed generator (reproducible scenes).
double uniform(std::mt19937_64& gen, double a, double b) {
  return a + (b - a) * static_cast<double>(gen() >> 11) * 0x1.0p-53;
}

// Centres on a simple cubic lattice of spacing `spacing` from the lower corner of a box of half
// edges `half`, x fastest (like the deck's fill = "lattice", io/decks.md).
std::vector<Vec3> lattice(Vec3 half, double spacing, std::size_t count) {
  std::vector<Vec3> out;
  const Vec3 start = Vec3{0.51, 0.51, 0.51} * spacing - half;
  const int nx = static_cast<int>((2 * half.x - 0.02 * spacing) / spacing);
  const int ny = static_cast<int>((2 * half.y - 0.02 * spacing) / spacing);
  for (int k = 0; out.size() < count; ++k)
    for (int j = 0; j < ny && out.size() < count; ++j)
      for (int i = 0; i < nx && out.size() < count; ++i)
        out.push_back(start + spacing * Vec3{double(i), double(j), double(k)});
  return out;
}

// Largest overlap over all pairs and walls of a box (brute force, independent of the engine's
// neighbour lists).
double max_overlap(const std::vector<ParticleState>& p, const std::vector<double>& radius,
                   Vec3 half) {
  double worst = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 x = p[i].position;
    const double r = radius[i];
    for (double gap :
         {x.x + half.x, half.x - x.x, x.y + half.y, half.y - x.y, x.z + half.z, half.z - x.z})
      worst = std::max(worst, r - gap);
    for (std::size_t j = i + 1; j < p.size(); ++j)
      worst = std::max(worst, r + radius[j] - norm(x - p[j].position));
  }
  return worst;
}

TEST_CASE("elastic gas in a closed box conserves kinetic energy between contacts") {
  // 64 steel balls, e = 1, no friction, no gravity: kinetic energy sampled when no contact is
  // active must return to its initial value (energy conservation); a wrong sign, a missing
  // pair half or an unstable step would make it drift by orders of magnitude more.
  const double radius = 2.5e-3, stiffness = 1e5;
  const Vec3 half{0.02, 0.02, 0.02};
  const double mass = ball_mass(radius, kSteelDensity);
  const double dt = linear_contact_time(stiffness, 0.5 * mass, 1.0) / 50;
  EngineConfig c = steel_box(half, NormalModel::linear, TangentialModel::none,
                             linear_contact(stiffness, 1.0, 0), dt);
  std::mt19937_64 gen(7);
  for (Vec3 x : lattice(half, 9.8e-3, 64))
    add_particle(c, radius, x, {uniform(gen, -1, 1), uniform(gen, -1, 1), uniform(gen, -1, 1)});
  auto engine = make_engine(c);
  const std::vector<double> radii = c.radius;
  double initial = 0;
  for (const auto& p : c.particles) initial += 0.5 * mass * dot(p.velocity, p.velocity);

  // Pair contacts are counted every 10 steps (a contact lasts 50), to make sure the energy
  // went through many collisions.
  std::vector<char> touching(64 * 64, 0);
  int collisions = 0;
  auto count_collisions = [&](const std::vector<ParticleState>& p) {
    for (std::size_t i = 0; i < p.size(); ++i)
      for (std::size_t j = i + 1; j < p.size(); ++j) {
        const bool now = norm(p[i].position - p[j].position) < 2 * radius;
        char& before = touching[i * p.size() + j];
        if (now && !before) ++collisions;
        before = now;
      }
  };
  double worst_drift = 0;
  int samples = 0;
  for (int sample = 0; sample < 100; ++sample) {
    for (int n = 1; n <= 1000; ++n) {
      step(*engine, dt);
      if (n % 10 == 0) count_collisions(engine->particles());
    }
    // Step on to the next moment without any contact, where all energy is kinetic.
    for (int n = 0; n < 5000; ++n) {
      const double kinetic = step(*engine, dt).kinetic;
      if (max_overlap(engine->particles(), radii, half) <= 0) {
        worst_drift = std::max(worst_drift, std::fabs(kinetic / initial - 1));
        ++samples;
        break;
      }
    }
  }
  CHECK(samples == 100);
  CHECK(collisions > 500);
  CHECK(worst_drift < 1e-3);
}

struct Pile {
  std::unique_ptr<DemEngine> engine;
  EngineConfig config;
  double weight = 0;  // N
};

// Particles dropped from a lattice with random velocities settle into a pile.
Pile settled_pile(EngineConfig c, std::size_t count, double spacing, double r_min, double r_max,
                  int settle_steps) {
  std::mt19937_64 gen(11);
  c.gravity = Vec3{0, 0, -kGravity};
  for (Vec3 x : lattice(c.geometry.half_size, spacing, count))
    add_particle(c, uniform(gen, r_min, r_max), x,
                 {uniform(gen, -0.1, 0.1), uniform(gen, -0.1, 0.1), uniform(gen, -0.1, 0.1)});
  Pile pile;
  for (double r : c.radius) pile.weight += ball_mass(r, c.density) * kGravity;
  pile.engine = make_engine(c);
  pile.config = c;
  for (int n = 0; n < settle_steps; ++n) step(*pile.engine, c.dt);
  return pile;
}

TEST_CASE("oblique frictional impact: momentum conserved, spins in the ratio (r1/r2)^4") {
  // Each pair's force is computed once and given to both spheres. For spheres of radii r1, r2
  // the tangential force acts at distances r1 and r2 from the centres, so the torques are in
  // the ratio r2/r1 at every step and the spins (I ~ r^5) end in the ratio (r1/r2)^4; linear
  // momentum is conserved. Both orders are run, so that each sphere owns the pair once.
  const double r1 = 2.5e-3, r2 = 2.0e-3, speed = 1.0;
  for (double side : {1.0, -1.0}) {
    CAPTURE(side);
    const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, 0.7, 0.3);
    EngineConfig c =
        steel_box({0.05, 0.05, 0.05}, NormalModel::hertz, TangentialModel::history, contact, 1e-7);
    add_particle(c, r1, {-side * 0.0025, 0, 0}, {side * speed, 0, 0});
    add_particle(c, r2, {side * 0.0025, 0.002, 0.001}, {0, 0, 0});
    auto engine = make_engine(c);
    const double m1 = ball_mass(r1, kSteelDensity), m2 = ball_mass(r2, kSteelDensity);
    for (int n = 0; n < 20000; ++n) {
      const StepTotals& t = step(*engine, c.dt);
      REQUIRE(norm(t.wall_force) == 0.0);  // nothing touches the walls
    }
    const std::vector<ParticleState> p = engine->particles();
    const Vec3 momentum = m1 * p[0].velocity + m2 * p[1].velocity;
    CHECK(norm(momentum - Vec3{side * m1 * speed, 0, 0}) < 1e-14 * m1 * speed);
    CHECK(norm(p[1].position - p[0].position) > r1 + r2);  // the impact is over
    const Vec3 w1 = p[0].spin, w2 = p[1].spin;
    REQUIRE(norm(w1) > 10.0);  // rad/s: friction acted
    CHECK(norm(w2 - std::pow(r1 / r2, 4) * w1) < 1e-12 * norm(w2));
  }
}

TEST_CASE("static pile: at rest for 10 s simulated and the walls carry its weight") {
  // 200 balls dropped from a lattice, linear law (soft, so that dt is large), e = 0.3, Mindlin
  // friction 0.5. Balls resting on the floor may roll freely (no rolling resistance), so
  // "static" means slower than the bound, not zero. Held 10 s (220,000 steps, a hard case of
  // issue 35): a pile that crept, or gained energy from the integrator, would exceed the bound
  // or lose its balance of forces.
  const double radius = 2.5e-3, stiffness = 2e3;  // N/m: 0.8 % overlap under 8 layers
  const double mass = ball_mass(radius, kSteelDensity);
  const double dt = linear_contact_time(stiffness, 0.5 * mass, 0.3) / 25;
  EngineConfig c = steel_box({0.013, 0.013, 0.03}, NormalModel::linear, TangentialModel::history,
                             linear_contact(stiffness, 0.3, 0.5), dt);
  Pile pile = settled_pile(c, 200, 1.02 * 2 * radius, radius, radius, 40000);

  const double speed_bound = 1e-3;  // m/s
  double max_speed = 0, max_kinetic = 0;
  Vec3 mean_force;
  const int steps = static_cast<int>(std::ceil(10.0 / dt));
  for (int n = 0; n < steps; ++n) {
    const StepTotals& t = step(*pile.engine, dt);
    mean_force += (1.0 / steps) * t.wall_force;
    max_kinetic = std::max(max_kinetic, t.kinetic);
    if (n % 5 != 0) continue;  // 5 samples per contact time catch any vibration
    for (const auto& p : pile.engine->particles())
      max_speed = std::max(max_speed, norm(p.velocity));
  }
  // The force at the last state (compute() without accept() only evaluates the step).
  const Vec3 last = pile.engine->compute({}, dt).wall_force;
  CHECK(steps * dt >= 10.0);
  CHECK(max_speed < speed_bound);
  // Kinetic energy (translation and rotation) below the whole pile moving at the speed bound.
  CHECK(max_kinetic < 0.5 * (pile.weight / kGravity) * speed_bound * speed_bound);
  // Static equilibrium: the force on the container is the pile's weight, pointing down.
  validation_row("static pile of 200 balls held 10 s: mean vertical wall force", "its weight",
                 pile.weight, -mean_force.z, 1e-3, "N");
  validation_bound("static pile of 200 balls held 10 s: fastest ball",
                   "at rest (the bound a pile at rest stays under)", speed_bound, max_speed, "m/s");
  for (const Vec3 force : {last, mean_force}) {
    CHECK(force.z / pile.weight == doctest::Approx(-1).epsilon(1e-3));
    CHECK(std::fabs(force.x) < 1e-3 * pile.weight);
    CHECK(std::fabs(force.y) < 1e-3 * pile.weight);
  }
}

TEST_CASE("polydisperse pile: overlaps of the order of Hertz's static overlap") {
  // Radii 1.5 to 2.5 mm, soft Hertz (E = 1e8 Pa, so that dt is large), e = 0.3, friction 0.5.
  const double r_min = 1.5e-3, r_max = 2.5e-3, young = 1e8, poisson = 0.3;
  const double dt = 0.15 * rayleigh_time(r_min, kSteelDensity, young, poisson);
  const Vec3 half{0.016, 0.016, 0.03};
  EngineConfig c = steel_box(half, NormalModel::hertz, TangentialModel::history,
                             hertz_contact(young, poisson, 0.3, 0.5), dt);
  // 60,000 steps: at 40,000 a straggler may still move at 3e-2 m/s, depending on rounding
  // (-march=native or not); from 50,000 on every ball is below 3.3e-3 m/s in both builds.
  Pile pile = settled_pile(c, 300, 1.02 * 2 * r_max, r_min, r_max, 60000);
  // Impacts at the remaining speeds overlap far less than the static load does (Hertz impact
  // overlap (15 m* v^2 / (16 E* sqrt(R*)))^(2/5) of two small balls at 1e-2 m/s: 1.6e-6 m).
  double max_speed = 0;
  for (const auto& p : pile.engine->particles()) max_speed = std::max(max_speed, norm(p.velocity));
  CHECK(max_speed < 1e-2);
  const double overlap = max_overlap(pile.engine->particles(), pile.config.radius, half);
  // Scale of the contact forces: the floor pressure of the pile on one mean-diameter square.
  // Hertz, F = 4/3 E* sqrt(R*) d^(3/2) (Johnson 1985, ch. 4), turns it into an overlap for the
  // softest pair (two small balls); force chains put the largest overlap a few times above it.
  const double r_mean = 0.5 * (r_min + r_max);
  const double force = pile.weight / (4 * half.x * half.y) * 4 * r_mean * r_mean;
  const double modulus = pile.config.contact.hertz_modulus_pp;
  const double overlap_scale =
      std::pow(3 * force / (4 * modulus * std::sqrt(0.5 * r_min)), 2.0 / 3.0);
  const Vec3 last = pile.engine->compute({}, dt).wall_force;
  CHECK(overlap > overlap_scale / 3);
  CHECK(overlap < 3 * overlap_scale);
  CHECK(overlap < 0.01 * r_min);
  CHECK(last.z / pile.weight == doctest::Approx(-1).epsilon(1e-3));
}

// 600 balls (three reduction blocks of 256), polydisperse, Hertz with Mindlin history, gravity,
// in a box shaken along x: every code path that could depend on the thread count.
EngineConfig shaken_scene(int threads) {
  const double r_min = 1.5e-3, r_max = 2.5e-3, young = 1e8, poisson = 0.3;
  EngineConfig c = steel_box({0.025, 0.025, 0.04}, NormalModel::hertz, TangentialModel::history,
                             hertz_contact(young, poisson, 0.3, 0.5),
                             0.15 * rayleigh_time(r_min, kSteelDensity, young, poisson));
  c.gravity = Vec3{0, 0, -kGravity};
  c.threads = threads;
  std::mt19937_64 gen(3);
  for (Vec3 x : lattice(c.geometry.half_size, 1.02 * 2 * r_max, 600))
    add_particle(c, uniform(gen, r_min, r_max), x,
                 {uniform(gen, -0.5, 0.5), uniform(gen, -0.5, 0.5), uniform(gen, -0.5, 0.5)});
  return c;
}

// Container centre at step n: 2 mm amplitude at 30 Hz along x.
ContainerKinematics shaken(int n, double dt) {
  const double omega = 2 * kPi * 30, amplitude = 2e-3, t = n * dt;
  return translating({amplitude * std::sin(omega * t), 0, 0},
                     {amplitude * omega * std::cos(omega * t), 0, 0});
}

// Steps n = first .. last-1; appends the totals of each step to `log`.
void run_shaken(DemEngine& engine, double dt, int first, int last, std::vector<double>& log) {
  for (int n = first; n < last; ++n) {
    const StepTotals& t = engine.compute(shaken(n, dt), dt);
    log.insert(log.end(), {t.wall_force.x, t.wall_force.y, t.wall_force.z, t.tally.normal,
                           t.tally.tangential, t.tally.rolling, t.kinetic, double(t.flags)});
    engine.accept();
  }
}

template <class T>
bool bitwise_equal(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST_CASE("bitwise identical results for 1, 2, 3 and 5 threads") {
  const int steps = 2000;
  std::vector<std::vector<ParticleState>> finals;
  std::vector<std::vector<double>> logs;
  for (int threads : {1, 2, 3, 5}) {  // 600 spheres: 3 blocks, so 5 threads leave shares empty
    const EngineConfig c = shaken_scene(threads);
    auto engine = make_engine(c);
    REQUIRE(engine->threads() == threads);
    logs.emplace_back();
    run_shaken(*engine, c.dt, 0, steps, logs.back());
    finals.push_back(engine->particles());
  }
  // The scene is not trivial: friction dissipated energy.
  double friction_loss = 0;
  for (std::size_t k = 4; k < logs[0].size(); k += 8) friction_loss += logs[0][k];
  CHECK(friction_loss > 0);
  for (std::size_t k = 1; k < finals.size(); ++k) {
    CAPTURE(k + 1);
    CHECK(bitwise_equal(finals[k], finals[0]));
    CHECK(bitwise_equal(logs[k], logs[0]));
  }
}

TEST_CASE("in-place steps equal double-buffered ones, each computed twice as tight coupling does") {
  const int steps = 1500;
  EngineConfig c = shaken_scene(2);
  auto in_place = make_engine(c);
  c.recompute = true;
  auto buffered = make_engine(c);
  std::vector<double> in_place_log, buffered_log;
  run_shaken(*in_place, c.dt, 0, steps, in_place_log);
  for (int n = 0; n < steps; ++n) {
    // A first guess of the container (at the same place, or the lists would be sorted in
    // another order), then the converged one.
    ContainerKinematics guess = shaken(n, c.dt);
    guess.velocity = -2.0 * guess.velocity;
    buffered->compute(guess, c.dt);
    const StepTotals& t = buffered->compute(shaken(n, c.dt), c.dt);
    buffered_log.insert(buffered_log.end(),
                        {t.wall_force.x, t.wall_force.y, t.wall_force.z, t.tally.normal,
                         t.tally.tangential, t.tally.rolling, t.kinetic, double(t.flags)});
    buffered->accept();
  }
  CHECK(bitwise_equal(buffered_log, in_place_log));
  CHECK(bitwise_equal(buffered->particles(), in_place->particles()));
}

TEST_CASE("skipping the slot tests of particles clear of their partners changes nothing") {
  // A restored engine tests every particle's slots in its first step (it has no record of
  // clearances), so one restored from its own checkpoint before every step never skips.
  const int steps = 800;
  const EngineConfig c = shaken_scene(1);
  auto skipping = make_engine(c), testing = make_engine(c);
  std::vector<double> skipping_log, testing_log;
  run_shaken(*skipping, c.dt, 0, steps, skipping_log);
  for (int n = 0; n < steps; ++n) {
    testing->restore(testing->save());
    run_shaken(*testing, c.dt, n, n + 1, testing_log);
  }
  CHECK(bitwise_equal(skipping_log, testing_log));
  CHECK(bitwise_equal(skipping->particles(), testing->particles()));
}

TEST_CASE("save and restore continue bitwise as if never stopped") {
  const int steps = 2000, pause = 1000;
  const EngineConfig c = shaken_scene(1);
  auto straight = make_engine(c);
  std::vector<double> straight_log, resumed_log;
  run_shaken(*straight, c.dt, 0, steps, straight_log);

  auto first = make_engine(c);
  run_shaken(*first, c.dt, 0, pause, resumed_log);
  const StateArrays checkpoint = first->save();
  first.reset();
  auto second = make_engine(c);
  second->restore(checkpoint);
  run_shaken(*second, c.dt, pause, steps, resumed_log);

  CHECK(bitwise_equal(second->particles(), straight->particles()));
  CHECK(bitwise_equal(resumed_log, straight_log));
  // Everything the next steps depend on (history, neighbour lists) matches too.
  const StateArrays a = second->save(), b = straight->save();
  REQUIRE(a.size() == b.size());
  for (const auto& [name, values] : a) {
    CAPTURE(name);
    REQUIRE(b.count(name) == 1);
    REQUIRE(values.index() == b.at(name).index());  // the same type
    CHECK(std::visit(
        [&](const auto& x) {
          return bitwise_equal(x, std::get<std::decay_t<decltype(x)>>(b.at(name)));
        },
        values));
  }
}

}  // namespace
}  // namespace pdsim

// The GPU engine's orchestration (kernels/gpu_engine.hpp) against the CPU engine. Both launch
// the same per-particle functions (kernels/particle_step.hpp, kernels/neighbours.hpp) on the same
// particle order, so they must agree to rounding: the reference is the CPU engine, whose physics
// the other kernel tests check against analytical values. Two GPU runs must agree bitwise
// (fixed-order reductions). Every test runs the orchestration through the host reference
// launcher, which CI can run, and through CUDA where a device is usable.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "io/stl_mesh.hpp"
#include "kernels/engine.hpp"
#include "kernels/gpu_engine_host.hpp"
#include "src/scene.hpp"
#include "tests/kernels/dem_fixtures.hpp"
#include "tests/support/stl_files.hpp"

namespace {

using namespace pdsim;

struct SceneSpec {
  NormalModel normal;
  TangentialModel tangential;
  bool rolling, gravity, polydisperse;
  WallShape shape;
};

// Reproducible uniform numbers in [0, 1) (64-bit LCG, Knuth's MMIX constants).
struct Uniform {
  std::uint64_t state = 12345;
  double operator()() {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  }
};

constexpr int kSide = 6, kLayers = 10;         // 360 particles: more than one 256-particle block
constexpr double kRadius = 0.0025;             // m, steel spheres d = 5 mm (the benchmark scene)
constexpr double kPitch = 2 * kRadius + 2e-4;  // m, lattice spacing: 0.2 mm gaps
constexpr double kWallGap = 1e-4;              // m, between the outer spheres and the walls
constexpr double kDt = 1e-6;                   // s

// A lattice of spheres a fraction of a millimetre apart, with random velocities up to 1 m/s and
// spins up to 200 rad/s, in a container just large enough: within 1000 steps (1 ms) every
// particle collides with neighbours and walls and the lists are rebuilt several times.
EngineConfig make_scene(const SceneSpec& s, Backend backend) {
  EngineConfig c;
  c.backend = backend;
  c.threads = 2;
  c.shape = s.shape;
  c.normal = s.normal;
  c.tangential = s.tangential;
  c.rolling = s.rolling;
  if (s.gravity) c.gravity = Vec3{0, 0, -9.81};
  c.density = 7800;
  c.dt = kDt;
  const double restitution = 0.5;
  c.contact = s.normal == NormalModel::linear ? fixtures::linear_contact(1e5, restitution, 0.3)
                                              : hertz_contact(2e11, 0.3, restitution, 0.3);
  c.contact.rolling_friction = s.rolling ? 0.01 : 0.0;
  const double extent = 0.5 * (kSide - 1) * kPitch;  // centre of the outer spheres, m
  const double half_height = 0.5 * (kLayers - 1) * kPitch + kRadius + kWallGap;
  if (s.shape == WallShape::box) {
    c.geometry.half_size = {extent + kRadius + kWallGap, extent + kRadius + kWallGap, half_height};
  } else if (s.shape == WallShape::mesh) {
    // The cylinder as 64 facets around (inscribed 0.12 % inside the circle, well within the
    // wall gap): faces, the rims' edges and the facets' folds all meet the spheres.
    static const std::shared_ptr<const MeshSurface> mesh = [&] {
      const double radius = std::sqrt(2.0) * extent + kRadius + kWallGap;
      const std::string path = stl_files::binary(
          stl_files::cylinder(radius / std::cos(kPi / 64), 2 * half_height, 64), "gpu.stl");
      auto surface = load_mesh(path, 1.0, kDefaultCurvature);
      std::filesystem::remove(path);
      return surface;
    }();
    ContainerSpec spec;
    spec.mesh = mesh;
    c.geometry = MeshShape::geometry(spec);
  } else {
    c.geometry.radius = std::sqrt(2.0) * extent + kRadius + kWallGap;
    c.geometry.half_size = {c.geometry.radius, c.geometry.radius, half_height};
  }
  Uniform u;
  for (int k = 0; k < kLayers; ++k)
    for (int j = 0; j < kSide; ++j)
      for (int i = 0; i < kSide; ++i) {
        const Vec3 centre{i * kPitch - extent, j * kPitch - extent,
                          (k - 0.5 * (kLayers - 1)) * kPitch};
        const Vec3 velocity{2 * u() - 1, 2 * u() - 1, 2 * u() - 1};
        const Vec3 spin{400 * u() - 200, 400 * u() - 200, 400 * u() - 200};
        c.particles.push_back({centre, velocity, spin});
        c.radius.push_back(s.polydisperse ? kRadius * (0.8 + 0.2 * u()) : kRadius);
      }
  return c;
}

// The container shaken along x: 2 mm at 50 Hz (peak 0.63 m/s).
ContainerKinematics container_at(int step) {
  const double omega = 2 * kPi * 50, amplitude = 0.002, t = step * kDt;
  return translating({amplitude * std::sin(omega * t), 0, 0},
                     {amplitude * omega * std::cos(omega * t), 0, 0});
}

struct Trace {
  std::vector<StepTotals> totals;
  std::vector<ParticleState> final;
};

Trace advance(DemEngine& engine, int first_step, int steps) {
  Trace trace;
  for (int n = first_step; n < first_step + steps; ++n) {
    trace.totals.push_back(engine.compute(container_at(n), kDt));
    engine.accept();
  }
  trace.final = engine.particles();
  return trace;
}

double max_norm(const std::vector<ParticleState>& p, Vec3 ParticleState::*member) {
  double m = 0;
  for (const ParticleState& q : p) m = std::max(m, norm(q.*member));
  return m;
}

// Largest deviation of `other` from `reference` in units of the reference run's largest value:
// the particle state after the run, and the totals of every step. NaN counts as the worst.
struct Deviation {
  double position = 0, velocity = 0, spin = 0;  // relative to the container size, v_max, w_max
  double kinetic = 0, dissipated = 0, wall_force = 0, speed = 0;
  bool flags_equal = true;
};

void keep_worst(double& worst, double candidate) {
  if (std::isnan(candidate) || candidate > worst) worst = candidate;
}

Deviation compare(const Trace& reference, const Trace& other, double container_size) {
  Deviation d;
  const double v_max = max_norm(reference.final, &ParticleState::velocity);
  const double w_max = max_norm(reference.final, &ParticleState::spin);
  for (std::size_t i = 0; i < reference.final.size(); ++i) {
    const ParticleState& a = reference.final[i];
    const ParticleState& b = other.final[i];
    keep_worst(d.position, norm(a.position - b.position) / container_size);
    keep_worst(d.velocity, norm(a.velocity - b.velocity) / v_max);
    keep_worst(d.spin, norm(a.spin - b.spin) / w_max);
  }
  double dissipated_max = 0, force_max = 0, speed_max = 0;
  for (const StepTotals& t : reference.totals) {
    dissipated_max = std::max({dissipated_max, std::fabs(t.tally.normal),
                               std::fabs(t.tally.tangential), std::fabs(t.tally.rolling)});
    force_max = std::max(force_max, norm(t.wall_force));
    speed_max = std::max(speed_max, t.speed_sq);
  }
  for (std::size_t n = 0; n < reference.totals.size(); ++n) {
    const StepTotals& a = reference.totals[n];
    const StepTotals& b = other.totals[n];
    keep_worst(d.kinetic, std::fabs(a.kinetic - b.kinetic) / a.kinetic);
    keep_worst(d.dissipated, std::fabs(a.tally.normal - b.tally.normal) / dissipated_max);
    keep_worst(d.dissipated, std::fabs(a.tally.tangential - b.tally.tangential) / dissipated_max);
    keep_worst(d.dissipated, std::fabs(a.tally.rolling - b.tally.rolling) / dissipated_max);
    keep_worst(d.wall_force, norm(a.wall_force - b.wall_force) / force_max);
    keep_worst(d.speed, std::fabs(a.speed_sq - b.speed_sq) / speed_max);
    d.flags_equal = d.flags_equal && a.flags == b.flags;
  }
  return d;
}

double container_size(const EngineConfig& c) {
  return 2 * std::max({c.geometry.half_size.x, c.geometry.half_size.y, c.geometry.half_size.z});
}

// The engines sum a particle's contact forces in different orders (the CPU in SIMD batches, the
// GPU particle by particle), so their states part by an ulp within the first hundred steps and
// the colliding spheres amplify that smoothly (the Hertz scenes faster): 1e-16 at 100 steps,
// below 1e-12 at 300 in the state and 2e-11 in the sums, which cancel. Up to 300 steps the
// engines must agree to that; over 1000 steps they must stay far inside what a missed contact
// or a wrong neighbour list gives (a contact impulse changes a velocity by ~1e-3 of its range).
void check_agree(const Deviation& d, int steps) {
  const bool early = steps <= 300;
  CHECK(d.position <= (early ? 1e-12 : 1e-9));
  CHECK(d.velocity <= (early ? 1e-11 : 1e-7));
  CHECK(d.spin <= (early ? 1e-11 : 1e-7));
  CHECK(d.kinetic <= (early ? 1e-12 : 1e-9));
  CHECK(d.dissipated <= (early ? 1e-9 : 1e-6));
  CHECK(d.wall_force <= (early ? 1e-11 : 1e-8));
  CHECK(d.speed <= (early ? 1e-11 : 1e-8));
  CHECK(d.flags_equal);
}

// The host reference engine of one of kScenes' variants (only these are compiled here).
template <class... V>
std::unique_ptr<DemEngine> reference_of(const EngineConfig& c) {
  using Engine = gpu_engine::HostReferenceEngine;
  const std::string name = variant_name(c);
  std::unique_ptr<DemEngine> engine;
  ((variant_string<V>() == name ? (void)(engine = std::make_unique<Engine>(c, Engine::step_of<V>()))
                                : (void)0),
   ...);
  if (!engine) throw std::logic_error("no reference engine compiled for " + name);
  return engine;
}
std::unique_ptr<DemEngine> make_reference(const EngineConfig& c) {
  return reference_of<
      Variant<HertzNormal, MindlinHistory, false, true, false, WallShape::box, false>,
      Variant<HertzNormal, MindlinHistory, true, false, true, WallShape::cylinder, false>,
      Variant<LinearNormal, DirectionalCoulomb, false, true, true, WallShape::box, false>,
      Variant<LinearNormal, NoTangential, false, false, false, WallShape::cylinder, false>,
      Variant<HertzNormal, MindlinHistory, false, true, false, WallShape::mesh, false>>(c);
}
std::unique_ptr<DemEngine> make_cuda(const EngineConfig& c) {
  EngineConfig cuda = c;
  cuda.backend = Backend::cuda;
  return make_engine(cuda);
}

// PDSIM_REQUIRE_CUDA=1 (tests/gpu/run.sh on a lent GPU): a CUDA device that is not usable is
// a failure, not a skip, so that a wrong driver, library or architecture cannot pass.
bool cuda_required() {
  const char* value = std::getenv("PDSIM_REQUIRE_CUDA");
  return value != nullptr && std::string(value) == "1";
}

// The engines that run the GPU orchestration: the host reference launcher always, CUDA where a
// device is usable (otherwise said once per test).
struct GpuEngine {
  std::string name;
  std::unique_ptr<DemEngine> (*make)(const EngineConfig&);
};
std::vector<GpuEngine> gpu_engines() {
  std::vector<GpuEngine> engines{{"host reference", &make_reference}};
  std::string description;
  if (cuda_device_available(&description))
    engines.push_back({"cuda", &make_cuda});
  else if (cuda_required())
    FAIL_CHECK("cuda required (PDSIM_REQUIRE_CUDA=1) but not usable: " << description);
  else
    MESSAGE("cuda skipped: no usable CUDA device (" << description << ")");
  return engines;
}

// A step's totals, every value; bitwise comparison (a NaN equals itself, -0 differs from 0).
std::vector<std::uint64_t> bits_of(const StepTotals& t) {
  const double values[] = {t.wall_force.x,  t.wall_force.y,     t.wall_force.z,
                           t.wall_torque.x, t.wall_torque.y,    t.wall_torque.z,
                           t.tally.normal,  t.tally.tangential, t.tally.rolling,
                           t.tally.elastic, t.tally.spring_in,  t.tally.spring_out,
                           t.kinetic,       t.speed_sq,         static_cast<double>(t.flags)};
  std::vector<std::uint64_t> bits(std::size(values));
  std::memcpy(bits.data(), values, sizeof(values));
  return bits;
}

// Two checkpoint arrays hold the same type and the same bytes.
bool same_bytes(const StateArray& a, const StateArray& b) {
  if (a.index() != b.index()) return false;
  return std::visit(
      [&](const auto& values) {
        const auto& other = std::get<std::decay_t<decltype(values)>>(b);
        return values.size() == other.size() &&
               (values.empty() ||
                std::memcmp(values.data(), other.data(), values.size() * sizeof(values[0])) == 0);
      },
      a);
}

// Checkpoints equal array by array (each named in the failure), byte for byte.
void check_same_checkpoint(const StateArrays& a, const StateArrays& b) {
  REQUIRE(a.size() == b.size());
  for (const auto& [name, values] : a) {
    CAPTURE(name);
    REQUIRE(b.count(name) == 1);
    CHECK(same_bytes(values, b.at(name)));
  }
}

const SceneSpec kScenes[] = {
    {NormalModel::hertz, TangentialModel::history, false, true, false, WallShape::box},
    {NormalModel::hertz, TangentialModel::history, true, false, true, WallShape::cylinder},
    {NormalModel::linear, TangentialModel::directional, false, true, true, WallShape::box},
    {NormalModel::linear, TangentialModel::none, false, false, false, WallShape::cylinder},
    {NormalModel::hertz, TangentialModel::history, false, true, false, WallShape::mesh},
};

}  // namespace

TEST_CASE("cuda_device_available answers without a GPU or driver and make_engine reports it") {
  std::string description;
  bool available = true;
  REQUIRE_NOTHROW(available = cuda_device_available(&description));
  CHECK_FALSE(description.empty());  // the device name, or why there is none
  if (cuda_required()) CHECK_MESSAGE(available, "PDSIM_REQUIRE_CUDA=1: " << description);
  if (!available) {
    EngineConfig c = make_scene(kScenes[0], Backend::cuda);
    CHECK_THROWS_AS(make_engine(c), InputError);
  }
}

TEST_CASE("the gpu engines follow the cpu engine for 1000 steps in every physics family") {
  for (const GpuEngine& gpu : gpu_engines()) {
    CAPTURE(gpu.name);
    for (const SceneSpec& spec : kScenes) {
      const EngineConfig config = make_scene(spec, Backend::cpu);
      CAPTURE(variant_name(config));
      REQUIRE(gpu.make(config)->variant() == variant_name(config));
      for (int steps : {300, 1000}) {
        CAPTURE(steps);
        auto cpu = make_engine(config);
        auto other = gpu.make(config);
        const Trace reference = advance(*cpu, 0, steps);
        const Trace trace = advance(*other, 0, steps);
        // The scene must be eventful and valid for the comparison to mean anything.
        double dissipated = 0;
        for (const StepTotals& t : reference.totals) {
          REQUIRE(t.flags == 0);
          dissipated += t.tally.normal;
        }
        CHECK(dissipated > 0);
        check_agree(compare(reference, trace, container_size(config)), steps);
      }
    }
  }
}

TEST_CASE("two runs of a gpu engine are bitwise identical") {
  for (const GpuEngine& gpu : gpu_engines()) {
    CAPTURE(gpu.name);
    const EngineConfig config = make_scene(kScenes[1], Backend::cpu);
    auto first = gpu.make(config);
    auto second = gpu.make(config);
    const Trace a = advance(*first, 0, 1000);
    const Trace b = advance(*second, 0, 1000);
    const StateArrays saved_a = first->save();
    const StateArrays saved_b = second->save();
    for (const char* key : {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz", "neighbour_mask"}) {
      CAPTURE(key);
      CHECK(saved_a.at(key) == saved_b.at(key));
    }
    for (std::size_t n = 0; n < a.totals.size(); ++n) {
      CAPTURE(n);
      REQUIRE(a.totals[n].kinetic == b.totals[n].kinetic);
      REQUIRE(a.totals[n].tally.normal == b.totals[n].tally.normal);
      REQUIRE(a.totals[n].tally.tangential == b.totals[n].tally.tangential);
      REQUIRE(a.totals[n].tally.rolling == b.totals[n].tally.rolling);
      REQUIRE(a.totals[n].wall_force.x == b.totals[n].wall_force.x);
    }
  }
}

// The CUDA kernels compute what the host reference launcher computes, in the same order and,
// with --fmad=false, with the same roundings as this baseline x86-64 build: every step's totals
// and the whole checkpoint must be equal bit for bit. On the host the reference runs against
// itself, a fresh engine each, so that a value read before it is written (the host arrays start
// as changing garbage) shows as a difference.
TEST_CASE(
    "the gpu engines equal the host reference bitwise for 1000 steps in every physics family") {
  for (const GpuEngine& gpu : gpu_engines()) {
    CAPTURE(gpu.name);
    for (const SceneSpec& spec : kScenes) {
      const EngineConfig config = make_scene(spec, Backend::cpu);
      CAPTURE(variant_name(config));
      auto reference = make_reference(config);
      auto other = gpu.make(config);
      const Trace expected = advance(*reference, 0, 1000);
      const Trace trace = advance(*other, 0, 1000);
      for (std::size_t n = 0; n < expected.totals.size(); ++n) {
        CAPTURE(n);
        REQUIRE(bits_of(trace.totals[n]) == bits_of(expected.totals[n]));
      }
      check_same_checkpoint(other->save(), reference->save());
    }
  }
}

// A checkpoint is what a run's OUT.partial and bed files hold: two equal runs must write the
// same bytes, whatever memory the engine was given (on a GPU the last engine's, here the host
// reference's changing garbage), and -1 in the list slots past each particle's count.
TEST_CASE("two engines made one after the other save byte-identical checkpoints") {
  std::vector<GpuEngine> engines = gpu_engines();
  engines.insert(engines.begin(), {"cpu", &make_engine});
  for (const GpuEngine& e : engines) {
    CAPTURE(e.name);
    for (const SceneSpec& spec : {kScenes[0], kScenes[3], kScenes[4]}) {
      const EngineConfig config = make_scene(spec, Backend::cpu);
      CAPTURE(variant_name(config));
      // Checkpoints after 100, 200 and 300 steps (rebuilds in between swap the lists' arrays).
      auto run = [&] {
        auto engine = e.make(config);
        std::vector<StateArrays> saved;
        for (int n = 0; n < 300; n += 100) {
          advance(*engine, n, 100);
          saved.push_back(engine->save());
        }
        return saved;  // the engine and its memory go before the next one is made
      };
      const std::vector<StateArrays> first = run(), second = run();
      for (std::size_t k = 0; k < first.size(); ++k) {
        CAPTURE(k);
        check_same_checkpoint(second[k], first[k]);
      }
      const StateArrays& last = first.back();
      const auto m = static_cast<std::size_t>(state_value<std::int32_t>(last, "max_neighbours"));
      const auto& count = state_values<std::int32_t>(last, "neighbour_count");
      const auto& reverse_count = state_values<std::int32_t>(last, "reverse_count");
      auto unused_hold_minus_one = [&](const std::string& name,
                                       const std::vector<std::int32_t>& used, bool padded_list) {
        CAPTURE(name);
        const auto& list = state_values<std::int32_t>(last, name);
        int wrong = 0;
        for (std::size_t i = 0; i < used.size(); ++i)
          for (std::size_t k = static_cast<std::size_t>(padded_list ? padded(used[i]) : used[i]);
               k < m; ++k)
            wrong += list[i * m + k] != -1;
        CHECK(wrong == 0);
      };
      unused_hold_minus_one("neighbours", count, true);
      unused_hold_minus_one("partner_id", count, false);
      unused_hold_minus_one("reverse", reverse_count, false);
    }
  }
}

TEST_CASE("a gpu engine's step computed twice before accept gives the same totals") {
  for (const GpuEngine& gpu : gpu_engines()) {
    CAPTURE(gpu.name);
    auto engine = gpu.make(make_scene(kScenes[0], Backend::cpu));
    advance(*engine, 0, 300);
    const StepTotals first = engine->compute(container_at(300), kDt);
    const StepTotals again = engine->compute(container_at(300), kDt);
    CHECK(first.kinetic == again.kinetic);
    CHECK(first.tally.tangential == again.tally.tangential);
    CHECK(first.wall_force.x == again.wall_force.x);
  }
}

TEST_CASE(
    "both backends refuse a damaged checkpoint by name and write exactly the table's arrays") {
  std::vector<GpuEngine> engines = gpu_engines();
  engines.insert(engines.begin(), {"cpu", &make_engine});
  for (const GpuEngine& e : engines) {
    CAPTURE(e.name);
    for (const SceneSpec& spec : {kScenes[0], kScenes[3]}) {  // with and without history
      const EngineConfig config = make_scene(spec, Backend::cpu);
      auto engine = e.make(config);
      advance(*engine, 0, 300);
      const StateArrays good = engine->save();
      // save() writes the table's arrays and no others, so the check below covers the file.
      CHECK(good.size() == checkpoint_arrays().size());
      REQUIRE_NOTHROW(e.make(config)->restore(good));
      auto refused = [&](StateArrays damaged, const std::string& message) {
        auto fresh = e.make(config);
        CHECK_THROWS_WITH_AS(fresh->restore(damaged), doctest::Contains(message.c_str()),
                             SimulationError);
      };
      StateArrays a = good;
      std::get<std::vector<double>>(a["vx"]).pop_back();
      refused(a, "'vx' holds");
      a = good;
      a.erase("neighbours");
      refused(a, "lacks the array 'neighbours'");
      a = good;
      a["id"] = std::vector<double>(static_cast<std::size_t>(engine->count()), 0.0);
      refused(a, "'id' holds double values, not int32");
      a = good;
      a["spare"] = std::vector<double>{1.0};
      refused(a, "an array 'spare'");
      a = good;
      std::get<std::vector<std::int32_t>>(a["id"])[1] = 0;
      refused(a, "'id' is not a permutation");
      a = good;
      std::get<std::vector<std::int32_t>>(a["neighbour_count"])[0] = 1000;
      refused(a, "'neighbour_count' holds 1000 partners");
      a = good;
      auto& counts = std::get<std::vector<std::int32_t>>(a["neighbour_count"]);
      const auto listed = std::find_if(counts.begin(), counts.end(), [](int c) { return c > 0; });
      REQUIRE(listed != counts.end());
      const int max_neighbours = state_value<std::int32_t>(good, "max_neighbours");
      std::get<std::vector<std::int32_t>>(
          a["neighbours"])[static_cast<std::size_t>(listed - counts.begin()) * max_neighbours] =
          engine->count();
      refused(a, "'neighbours' names a particle out of range");
      // A checkpoint of the other kind of scene (history against none) is not this engine's.
      const SceneSpec other = spec.tangential == TangentialModel::history ? kScenes[3] : kScenes[0];
      auto foreign = e.make(make_scene(other, Backend::cpu));
      advance(*foreign, 0, 10);
      StateArrays mixed = foreign->save();
      REQUIRE(foreign->count() == engine->count());
      refused(mixed, "'history' holds");
    }
  }
}

TEST_CASE("checkpoints move between the cpu and gpu engines mid-run") {
  for (const GpuEngine& gpu : gpu_engines()) {
    CAPTURE(gpu.name);
    for (const SceneSpec& spec : {kScenes[0], kScenes[1], kScenes[4]}) {  // the mesh: keyed walls
      const EngineConfig config = make_scene(spec, Backend::cpu);
      auto cpu = make_engine(config);
      auto other = gpu.make(config);
      advance(*cpu, 0, 500);
      other->restore(cpu->save());  // live contacts and tangential history cross over
      const Trace reference = advance(*cpu, 500, 500);
      const Trace trace = advance(*other, 500, 500);
      const Deviation d = compare(reference, trace, container_size(config));
      CAPTURE(other->variant());
      check_agree(d, 500);
      // And back: a gpu checkpoint restored on a fresh cpu engine continues the gpu run.
      auto cpu_again = make_engine(config);
      cpu_again->restore(other->save());
      const Trace gpu_more = advance(*other, 1000, 200);
      const Trace cpu_more = advance(*cpu_again, 1000, 200);
      const Deviation back = compare(gpu_more, cpu_more, container_size(config));
      check_agree(back, 200);
    }
  }
}

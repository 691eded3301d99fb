#include "src/scene.hpp"

#include "io/deck.hpp"
#include "io/excitation.hpp"
#include "src/coupled_system.hpp"
#include "src/format.hpp"
#include "structure/structure.hpp"

#include <algorithm>
#include <cstdint>
#include <random>
#include <sstream>

namespace pdsim {

namespace {

// Uniform double in [0, 1) from a 64-bit generator, identical on every platform.
double uniform(std::mt19937_64& gen) {
  return static_cast<double>(gen() >> 11) * 0x1.0p-53;
}

std::vector<double> particle_radii(const ParticleSpec& p) {
  std::vector<double> r(static_cast<std::size_t>(p.count));
  std::mt19937_64 gen(p.seed ^ 0x9e3779b97f4a7c15ULL);
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (!p.diameters.empty())
      r[i] = 0.5 * p.diameters[i % p.diameters.size()];
    else if (p.diameter_max > 0)
      r[i] = 0.5 * (p.diameter_min + (p.diameter_max - p.diameter_min) * uniform(gen));
    else
      r[i] = 0.5 * p.diameter;
  }
  return r;
}

ContainerGeometry geometry_of(const ContainerSpec& c) {
  return with_shape(c.shape, [&](auto shape) { return decltype(shape)::geometry(c); });
}

// A sphere of radius r at p (container frame) lies inside (the fill).
bool inside(WallShape shape, const ContainerGeometry& g, Vec3 p, double r) {
  return with_shape(shape, [&](auto s) { return decltype(s)::inside(p, r, g); });
}

double container_volume(WallShape shape, const ContainerGeometry& g) {
  return with_shape(shape, [&](auto s) { return decltype(s)::volume(g); });
}

}  // namespace

// Largest fill fraction a random fill is tried at.
constexpr double kRandomFillLimit = 0.35;
// The shortest time step (s), and the most DEM steps a period can take (an int counts them).
constexpr double kMinDt = 1e-12;
constexpr double kMaxStepsPerPeriod = 1e9;

Orientation orientation_of(const ContainerSpec& c) {
  Orientation o;
  if (c.shape != WallShape::cylinder) return o;
  const Vec3 a = c.axis;
  if (a.x == 0 && a.y == 0) {  // along z: as it is, or turned over about x
    if (a.z < 0) o.y = {0, -1, 0}, o.z = {0, 0, -1};
    return o;
  }
  // The shortest turn taking z to a: about k = z x a / |z x a| by the angle whose cosine is
  // a.z (Rodrigues: R v = v cos + (k x v) sin + k (k . v)(1 - cos)).
  const double sine = std::hypot(a.x, a.y), cosine = a.z;
  const Vec3 k{-a.y / sine, a.x / sine, 0};
  auto turn = [&](Vec3 v) {
    return cosine * v + sine * cross(k, v) + (dot(k, v) * (1 - cosine)) * k;
  };
  o.x = turn({1, 0, 0});
  o.y = turn({0, 1, 0});
  o.z = a;
  return o;
}

std::vector<Vec3> fill_particles(WallShape shape, const ContainerGeometry& g,
                                 const ParticleSpec& particles, const std::vector<double>& radius,
                                 const SourcePos& where, const std::string& key) {
  const std::size_t n = radius.size();
  const double r_max = *std::max_element(radius.begin(), radius.end());
  std::vector<Vec3> centres;
  centres.reserve(n);
  if (particles.fill == Fill::lattice) {
    // Simple cubic lattice (io/decks.md): spacing 1.02 d, first centre 0.51 d from each lower wall.
    const double d = 2 * r_max, spacing = 1.02 * d;
    const Vec3 start = -1.0 * g.half_size + Vec3{0.51 * d, 0.51 * d, 0.51 * d};
    for (int k = 0; centres.size() < n; ++k) {
      const double z = start.z + k * spacing;
      if (z > g.half_size.z - r_max) break;
      for (int j = 0; centres.size() < n; ++j) {
        const double y = start.y + j * spacing;
        if (y > g.half_size.y - r_max) break;
        for (int i = 0; centres.size() < n; ++i) {
          const double x = start.x + i * spacing;
          if (x > g.half_size.x - r_max) break;
          if (inside(shape, g, {x, y, z}, r_max)) centres.push_back({x, y, z});
        }
      }
    }
    if (centres.size() < n)
      throw InputError(where, key + ".count",
                       "a lattice of spacing 1.02 d holds only " + std::to_string(centres.size()) +
                           " particles in this container, " + std::to_string(n) + " requested");
    return centres;
  }
  // Random sequential addition with a cell list for the overlap test. It jams near a fill
  // fraction of 0.38 (0.3 in practice, with walls), and trying to reach more would spin for
  // hours on large counts: refused by volume first.
  double volume = 0;
  for (double ri : radius) volume += 4.0 / 3.0 * kPi * ri * ri * ri;
  const double fraction = volume / container_volume(shape, g);
  if (fraction > kRandomFillLimit)
    throw InputError(where, key,
                     "a random fill of fill fraction " + number(fraction) + ": expected at most " +
                         number(kRandomFillLimit) +
                         " (random placement jams near 0.38); use fill = \"lattice\", fewer "
                         "particles or a larger container");
  std::mt19937_64 gen(particles.seed);
  // Cells at least 2 r_max wide hold every overlapping partner in the adjacent ones, whatever
  // their width (the same centres come out); about one a particle at most, so that a container
  // far wider than its particles (a 1 m box of 0.5 mm spheres) needs no more cells than spheres.
  const double cell = std::max(2 * r_max, std::cbrt(8 * g.half_size.x * g.half_size.y *
                                                    g.half_size.z / static_cast<double>(n)));
  const int nx = std::max(1, static_cast<int>(std::ceil(2 * g.half_size.x / cell)));
  const int ny = std::max(1, static_cast<int>(std::ceil(2 * g.half_size.y / cell)));
  const int nz = std::max(1, static_cast<int>(std::ceil(2 * g.half_size.z / cell)));
  std::vector<std::vector<int>> cells(static_cast<std::size_t>(nx) * ny * nz);
  auto index = [&](int i, int j, int k) { return (static_cast<std::size_t>(k) * ny + j) * nx + i; };
  auto cell_coord = [&](double v, double half, int count) {
    return std::clamp(static_cast<int>((v + half) / cell), 0, count - 1);
  };
  const long max_attempts = 20000 + 2000L * static_cast<long>(n);
  long attempts = 0;
  for (std::size_t p = 0; p < n; ++p) {
    const double r = radius[p];
    for (;;) {
      if (++attempts > max_attempts)
        throw InputError(where, key,
                         "random fill placed only " + std::to_string(p) + " of " +
                             std::to_string(n) + " particles (fill fraction " + number(fraction) +
                             "); use fill = \"lattice\", fewer particles or a larger container");
      const Vec3 q{(2 * uniform(gen) - 1) * (g.half_size.x - r),
                   (2 * uniform(gen) - 1) * (g.half_size.y - r),
                   (2 * uniform(gen) - 1) * (g.half_size.z - r)};
      if (!inside(shape, g, q, r)) continue;
      const int ci = cell_coord(q.x, g.half_size.x, nx), cj = cell_coord(q.y, g.half_size.y, ny),
                ck = cell_coord(q.z, g.half_size.z, nz);
      bool free = true;
      for (int k = std::max(0, ck - 1); free && k <= std::min(nz - 1, ck + 1); ++k)
        for (int j = std::max(0, cj - 1); free && j <= std::min(ny - 1, cj + 1); ++j)
          for (int i = std::max(0, ci - 1); free && i <= std::min(nx - 1, ci + 1); ++i)
            for (int other : cells[index(i, j, k)]) {
              const Vec3 d = q - centres[static_cast<std::size_t>(other)];
              const double reach = r + radius[static_cast<std::size_t>(other)];
              if (dot(d, d) < reach * reach) {
                free = false;
                break;
              }
            }
      if (!free) continue;
      cells[index(ci, cj, ck)].push_back(static_cast<int>(p));
      centres.push_back(q);
      break;
    }
  }
  return centres;
}

namespace {

Locate locate(const Deck& deck) {
  return [&deck](const std::string& key) { return deck.where(key); };
}

// Where the deck's dampers are bolted to its beam.
std::vector<Mount> mounts_of(const Deck& deck) {
  std::vector<Mount> mounts;
  for (const DamperSpec& d : deck.dampers) mounts.push_back({d.attach_node, d.attach_x});
  return mounts;
}

// What a run will count and compute must be representable, so that `check` refuses what the
// run would overflow on: a period's steps in an int (FrequencyRun::configure), and structural
// matrices that stay finite at every frequency of the excitation.
void check_feasible(const Deck& deck, const ExcitationSpec& x, const Scene& s) {
  const std::vector<double>& frequencies = x.frequencies;
  const std::string& f_key = x.frequencies_key;
  const std::string dt_key = deck.solver.dt > 0 ? "solver.dt" : f_key;
  const std::string step_key = deck.solver.dt > 0 ? "solver.dt" : "solver.dt_safety";
  if (!(s.dt >= kMinDt))
    throw InputError(
        deck.where(step_key), step_key,
        "a time step of " + number(s.dt) + " s: expected at least " + number(kMinDt) + " s");
  const double every = deck.coupling.every;
  for (double f : frequencies) {
    if (1.0 / (32 * f) < kMinDt)  // a run takes at least 32 steps a period
      throw InputError(deck.where(f_key), f_key,
                       "a frequency of " + number(f) + " Hz needs steps shorter than " +
                           number(kMinDt) + " s: expected at most " + number(1 / (32 * kMinDt)) +
                           " Hz");
    const double steps = std::ceil(1.0 / (f * s.dt));
    if (steps * every > kMaxStepsPerPeriod)
      throw InputError(deck.where(dt_key), dt_key,
                       "dt = " + number(s.dt) + " s takes " + number(steps) +
                           " steps a period at " + number(f) + " Hz: expected at most " +
                           number(kMaxStepsPerPeriod) + " (raise dt or the frequency)");
  }
  if (!s.structure) return;
  const LinearStructure& st = *s.structure;
  bool finite = st.mass.allFinite() && st.stiffness.allFinite() && st.damping.allFinite();
  for (double f : frequencies) {
    const double w = 2 * kPi * f;
    finite = finite && (st.stiffness - w * w * st.mass).allFinite() && (w * st.damping).allFinite();
  }
  if (!finite)
    throw InputError(deck.where("structure"), "structure",
                     "its mass, stiffness and damping overflow (non-finite dynamic stiffness at "
                     "the deck's frequencies): expected values a structure can have");
}

// The smallest radius a fill of `p` holds: of the diameters used, or the range's lower end.
double smallest_radius(const ParticleSpec& p) {
  if (p.diameters.empty()) return 0.5 * (p.diameter_max > 0 ? p.diameter_min : p.diameter);
  const std::size_t used = std::min(p.diameters.size(), static_cast<std::size_t>(p.count));
  return 0.5 * *std::min_element(p.diameters.begin(), p.diameters.begin() + used);
}

// The radii and centres (container frame) of a damper's fill of `seed`; errors name `where`
// and `key` (the damper's particles table).
struct Drawn {
  std::vector<double> radius;
  std::vector<Vec3> centres;
};
Drawn draw_fill(const DamperScene& ds, std::uint64_t seed, const SourcePos& where,
                const std::string& key) {
  ParticleSpec p = ds.particles;
  p.seed = seed;
  Drawn f;
  f.radius = particle_radii(p);
  const double r_max = *std::max_element(f.radius.begin(), f.radius.end());
  const double smallest_extent = smallest_inner_size(ds.engine.shape, ds.engine.geometry);
  if (2 * r_max >= smallest_extent)
    throw InputError(where, key,
                     "particle diameter " + number(2 * r_max) +
                         " m does not fit in the container (smallest inner size " +
                         number(smallest_extent) + " m)");
  f.centres = fill_particles(ds.engine.shape, ds.engine.geometry, p, f.radius, where, key);
  return f;
}

// A damper's particles for the fill of `seed`: radii, centres in the world, mass and fill
// fraction (its engine's other settings are the scene's).
void fill_damper(DamperScene& ds, std::uint64_t seed, const SourcePos& where,
                 const std::string& key) {
  Drawn drawn = draw_fill(ds, seed, where, key);
  EngineConfig& e = ds.engine;
  e.radius = std::move(drawn.radius);
  const std::vector<Vec3>& centres = drawn.centres;
  double volume = 0;
  const Orientation& o = e.orientation;
  e.particles.clear();
  for (std::size_t i = 0; i < centres.size(); ++i) {
    const Vec3 c = centres[i];  // into the world: the container's axes at rest
    e.particles.push_back({o.identity() ? c : c.x * o.x + c.y * o.y + c.z * o.z, {}, {}});
    volume += 4.0 / 3.0 * kPi * std::pow(e.radius[i], 3);
  }
  ds.particle_mass = volume * e.density;
  ds.fill_fraction = volume / container_volume(e.shape, e.geometry);
}

// An explicit solver.dt against the scene's s.dt_limit, which `name` names and `why` explains:
// refused above it unless solver.allow_unstable, then run with a warning of `risk`.
void explicit_dt(const Deck& deck, DamperModel& s, const std::string& name, const std::string& why,
                 const std::string& risk) {
  if (!(deck.solver.dt > 0)) return;
  const std::string limit = name + " " + number(s.dt_limit) + " s";
  if (deck.solver.dt > s.dt_limit && !deck.solver.allow_unstable)
    throw InputError(deck.where("solver.dt"), "solver.dt",
                     "dt = " + number(deck.solver.dt) + " s exceeds " + limit + why +
                         "; lower it, use dt = \"auto\", or set solver.allow_unstable = true");
  s.dt = deck.solver.dt;
  s.dt_basis = "given in the deck";
  if (s.dt > s.dt_limit)
    s.warning = "dt = " + number(s.dt) + " s is " + number(s.dt / s.dt_limit) + " times " + limit +
                " (solver.allow_unstable): " + risk;
}

// Non-smooth contacts: the step is a fraction of the time the fastest particle takes to cross
// the smallest radius (a contact may then close within a step by a fraction of it, and the
// envelope holds every contact that can), and no stiffness sets it.
// default dt_safety: a fifth of r_min a step at the speed bound (which few particles reach).
// On the shaken Saeki pile 0.1 took 22.9 iterations a step, 0.2 19.3 and 0.4 17.9: the
// step's cost hardly grows with it (`pdsim bench --rigid`).
constexpr double kNonsmoothSafety = 0.2;
constexpr double kNonsmoothLimit = 0.5;  // beyond half a radius a step contacts are missed
// The default tolerance is at most this share of the containers' largest speed: contact
// velocities are met to a tenth of the motion that drives them. The rest speed alone (2 g dt)
// exceeded a map's slow motions: a ball rolling on a floor shaken at 0.1 g (1 cm/s) reused its
// last step's friction, a step late, and showed a loss factor of 0.035 where it has none; at a
// tenth, 2e-4 (validation/results/nonsmooth.md).
constexpr double kNonsmoothToleranceShare = 0.1;

// The largest speed the containers reach (m/s): the motion's where it is prescribed; else the
// bare structure's steady response at the run's frequencies (the particles as rigid mass: they
// only take energy out, so it bounds the damped response), or its free decay's start.
double container_speed_bound(const ExcitationSpec& x, const Scene& s) {
  double v = 0;
  for (std::size_t k = 0; k < x.frequencies.size(); ++k) {
    const double omega = 2 * kPi * x.frequencies[k];
    const double amplitude = point_amplitude(x, k);
    if (!s.structure) {
      v = std::max(v, omega * amplitude);
      continue;
    }
    const DrivePhasors drive = drive_phasors(*s.structure, x.input, amplitude, omega);
    std::vector<std::complex<double>> impedance;
    for (const DamperScene& d : s.dampers) impedance.push_back(-d.particle_mass * omega * omega);
    const Eigen::VectorXcd q =
        harmonic_response(*s.structure, omega, drive.load, impedance, drive.base);
    for (std::size_t d = 0; d < s.dampers.size(); ++d) {
      const auto t = s.structure->attachment_translation.row(static_cast<int>(d));
      v = std::max(v, omega * std::abs(t.cast<std::complex<double>>().dot(q) + drive.base));
    }
  }
  if (!measures_harmonics(x) && !s.natural_hz.empty())  // a free decay's start
    v = std::max(v, 2 * kPi * s.natural_hz.back() * std::abs(x.initial_displacement));
  return v;
}

// The non-smooth scene's step and constants (kernels/nonsmooth.hpp), once the host (`structure`,
// built in `s`) and the excitation `x` are known.
void nonsmooth_step(const Deck& deck, const ExcitationSpec& x, const StructureSpec& structure,
                    Scene& s) {
  const double r_min = s.r_min;
  const ContactSpec& contact = deck.contact;
  // A particle reaches twice the containers' speed off a wall, plus a fall across the largest
  // container.
  double fall = 0;
  const double g = deck.gravity ? norm(*deck.gravity) : 0.0;
  for (const DamperScene& d : s.dampers) {
    const Vec3 h = world_half_size(d.engine.geometry.half_size, d.engine.orientation);
    fall = std::max(fall, std::sqrt(2 * g * 2 * std::max({h.x, h.y, h.z})));
  }
  const double container = container_speed_bound(x, s);
  double speed = 2 * container + fall;
  std::string basis = "of r_min / " + number(speed) + " m/s (twice the containers' " +
                      number(container) + " m/s and a fall of " + number(fall) + " m/s)";
  if (!(speed > 0)) speed = 1.0, basis = "of r_min / 1 m/s (nothing in the scene moves)";
  const double safety = deck.solver.dt_safety > 0 ? deck.solver.dt_safety : kNonsmoothSafety;
  s.dt_limit = kNonsmoothLimit * r_min / speed;
  s.dt = safety * r_min / speed;
  s.dt_basis = number(safety) + " " + basis;
  explicit_dt(deck, s, "the limit",
              ", the step in which the fastest particle this scene can reach (" + number(speed) +
                  " m/s) crosses half the smallest radius",
              "fast contacts may be missed");
  NonsmoothParams p = nonsmooth_params(contact.restitution, contact.friction, speed, s.dt, g);
  if (contact.rest_speed > 0) p.rest_speed = p.recovery_speed = p.tolerance = contact.rest_speed;
  if (container > 0) p.tolerance = std::min(p.tolerance, kNonsmoothToleranceShare * container);
  if (contact.recovery_speed > 0) p.recovery_speed = contact.recovery_speed;
  if (contact.tolerance > 0) p.tolerance = contact.tolerance;
  if (contact.max_iterations > 0) p.max_iterations = contact.max_iterations;
  s.rest_speed_given = contact.rest_speed;
  s.recovery_speed_given = contact.recovery_speed;
  s.tolerance_given = contact.tolerance;
  for (DamperScene& d : s.dampers) d.engine.nonsmooth = p;
  s.contact_note = " (rigid: non-smooth contacts)";
  // An explicit scheme holds the container's velocity through a step, so a rigid impact sees
  // the structure as infinitely heavy: the rebound off it is off by about (1 + e) m / M for a
  // particle of mass m on a structure of mass M (tests/src/coupling_test.cpp measures it). The
  // tight scheme recomputes the step with the structure's answer.
  if (deck.coupling.scheme != CouplingScheme::tight && structure.kind != StructureKind::none) {
    const BeamSpec& b = structure.beam;
    const double host_mass =
        structure.kind == StructureKind::sdof ? structure.mass : b.density * b.area * b.length;
    double heaviest = 0;
    for (const DamperScene& d : s.dampers)
      for (double r : d.engine.radius)
        heaviest = std::max(heaviest, sphere_mass(r, d.engine.density).mass);
    const double error = (1 + contact.restitution) * heaviest / host_mass;
    if (error > 1e-3) {
      const std::string w =
          "rigid contacts with " +
          std::string(deck.coupling.scheme == CouplingScheme::loose ? "loose" : "interleaved") +
          " coupling: an impact of the heaviest particle sees the structure's "
          "velocity held, which shifts its rebound by about " +
          number(100 * error) + " %; coupling.scheme = \"tight\" resolves it";
      s.warning = s.warning.empty() ? w : s.warning + "; " + w;
    }
  }
}

}  // namespace

DamperModel compile_dampers(const Deck& deck, int threads, std::optional<Backend> backend,
                            int fills) {
  DamperModel s;
  const ContactSpec& contact = deck.contact;
  s.threads = threads > 0 ? threads : deck.solver.threads;

  const Backend wanted = backend.value_or(deck.solver.backend);
  std::string gpu;  // probed only when the deck or the command line may want it
  const bool have_gpu = wanted != Backend::cpu && cuda_device_available(&gpu);
  if (wanted == Backend::cuda && !have_gpu)
    throw InputError(deck.where("solver.backend"), "solver.backend",
                     "\"cuda\" requested but no usable CUDA device (" + gpu + ")");
  // "auto" stays on the CPU until the CUDA engine has passed tests/kernels/engine_gpu_test.cpp
  // on a GPU (CI runs its orchestration on the host only); "cuda" selects it explicitly.
  if (contact.nonsmooth && wanted == Backend::cuda)
    throw InputError(deck.where("solver.backend"), "solver.backend",
                     "contact.model = \"nonsmooth\" runs on the CPU backend only; expected "
                     "\"cpu\" or \"auto\"");
  s.backend = wanted == Backend::automatic ? Backend::cpu : wanted;
  s.backend_reason = wanted != Backend::automatic ? "requested"
                     : have_gpu ? "auto: CPU until the CUDA backend is validated on a GPU; "
                                  "--backend cuda uses " +
                                      gpu
                                : "auto: " + gpu;

  // Same material for particles and walls.
  ContactParams params =
      contact.nonsmooth ? ContactParams{} : with_normal_law(contact.model, [&](auto law) {
        return decltype(law)::params(contact);
      });
  params.rolling_friction = contact.rolling_friction;

  double r_min = 1e300, density_min = 0;
  for (std::size_t k = 0; k < deck.dampers.size(); ++k) {
    const DamperSpec& d = deck.dampers[k];
    DamperScene ds;
    ds.particles = d.particles;
    const std::string key = "damper[" + std::to_string(k) + "].particles";
    const SourcePos at = deck.where(key);
    EngineConfig& e = ds.engine;
    e.threads = s.threads;
    e.backend = s.backend;
    e.shape = d.container.shape;
    e.geometry = geometry_of(d.container);
    e.density = d.particles.density;
    e.normal = contact.model;
    e.tangential = contact.tangential;
    e.rolling = contact.rolling_friction > 0;
    e.orientation = orientation_of(d.container);
    if (deck.gravity && norm(*deck.gravity) > 0) e.gravity = deck.gravity;
    e.contact = params;
    e.recompute = deck.coupling.scheme == CouplingScheme::tight;  // iterates each step
    fill_damper(ds, d.particles.seed, at, key);
    // Every other fill a run may draw (scene_of_fill), drawn here once: a seed whose random fill
    // jams, or whose drawn diameters do not fit, is refused by check, not hours into a run.
    for (int r = 1; r < fills; ++r) {
      try {
        draw_fill(ds, d.particles.seed + static_cast<std::uint64_t>(r), at, key);
      } catch (const InputError& error) {
        throw InputError(std::string(error.what()) + " (fill " + std::to_string(r + 1) +
                         " of the " + std::to_string(fills) + " a point may grow to, seed " +
                         std::to_string(d.particles.seed + static_cast<std::uint64_t>(r)) + ")");
      }
    }
    // dt follows the smallest particle a fill of this design can hold, so that every fill
    // (scene_of_fill) runs at the same step.
    const double r_least = smallest_radius(d.particles);
    if (r_least < r_min) r_min = r_least, density_min = e.density;
    s.dampers.push_back(std::move(ds));
  }
  s.r_min = r_min;

  // Time step: a fraction of the contact time (linear) or of the Rayleigh time (Hertz); for
  // non-smooth contacts once the host is known (place_dampers()).
  if (!deck.dampers.empty() && !contact.nonsmooth) {
    const double mass_min = density_min * 4.0 / 3.0 * kPi * r_min * r_min * r_min;
    const TimeStepRule rule = with_normal_law(contact.model, [&](auto law) {
      return decltype(law)::time_step(contact, params, r_min, density_min, mass_min);
    });
    const double safety = deck.solver.dt_safety > 0 ? deck.solver.dt_safety : rule.default_safety;
    s.contact_time = rule.contact_time;
    s.rayleigh_time = rule.rayleigh_time;
    s.contact_note = rule.contact_note;
    s.dt = safety * rule.basis_time;
    s.dt_limit = rule.dt_limit;
    s.dt_basis = number(safety) + " x " + rule.basis + " " + number(rule.basis_time) + " s";
    explicit_dt(deck, s, "the stability limit", " of this contact model",
                "contacts are under-resolved and results may be shifted or blow up");
  }
  return s;
}

Scene place_dampers(const DamperModel& model, const Deck& deck, const ExcitationSpec& x,
                    const StructureSpec& structure) {
  Scene s;
  static_cast<DamperModel&>(s) = model;
  const bool hosted = structure.kind != StructureKind::none;
  for (DamperScene& d : s.dampers)  // follows the node's slope, or is laid along another axis
    d.engine.rotating = structure.kind == StructureKind::beam || !d.engine.orientation.identity();
  if (hosted) {
    s.structure = build_structure(structure, mounts_of(deck), locate(deck));
    try {
      s.natural_hz = natural_frequencies(*s.structure);
    } catch (const SimulationError&) {
      throw_no_modes(locate(deck));
    }
  }
  if (deck.contact.nonsmooth && !s.dampers.empty()) nonsmooth_step(deck, x, structure, s);
  if (s.dampers.empty()) {
    // Bare structure: the exact propagator has no step limit; sample 256 steps a period.
    const std::vector<double>& f = x.frequencies;
    const double f_top = f.empty() ? 100.0 : *std::max_element(f.begin(), f.end());
    s.dt = deck.solver.dt > 0 ? deck.solver.dt : 1.0 / (256 * f_top);
    s.dt_basis = deck.solver.dt > 0 ? "given in the deck" : "1/256 of the shortest period";
  }
  if (deck.coupling.scheme == CouplingScheme::interleaved && !s.dampers.empty() && hosted) {
    // The impulse kick is consistent only for modes the exchange interval resolves; stiff FE
    // modes (omega h >> 1) answer it with aliased or growing motion (tests/src: a full
    // 20-element cantilever loses the damper's moment or blows up).
    const double omega_max = 2 * kPi * s.natural_hz.back();
    const double h = s.dt * deck.coupling.every;
    if (omega_max * h > 2.0)
      throw InputError(deck.where("coupling.scheme"), "coupling.scheme",
                       "interleaved coupling (the default) needs every structural mode resolved "
                       "by the exchange interval (omega h < 2), but the highest mode has omega "
                       "h = " +
                           number(omega_max * h) +
                           "; keep the low modes with structure.modes = N, or use scheme = "
                           "\"loose\" or \"tight\"");
  }
  if (deck.coupling.scheme == CouplingScheme::tight && deck.coupling.every != 1)
    throw InputError(deck.where("coupling.every"), "coupling.every",
                     "tight coupling iterates every DEM step: expected 1");
  check_feasible(deck, x, s);
  for (auto& d : s.dampers) d.engine.dt = s.dt;
  s.integrator = structure.integrator;
  s.direction = structure.direction;
  if (structure.kind == StructureKind::beam) {
    const Vec3 axis = cross(structure.beam.axis, structure.direction);
    s.rotation_axis = (1.0 / norm(axis)) * axis;
  }
  s.coupling = deck.coupling;
  s.motion_axis = x.motion.axis;
  s.gravity = deck.gravity;
  return s;
}

Scene build_scene(const Deck& deck, int threads, std::optional<Backend> backend, bool every_fill) {
  const int fills = every_fill ? most_fills(deck.excitation) : 1;
  return place_dampers(compile_dampers(deck, threads, backend, fills), deck, deck.excitation,
                       deck.structure);
}

Scene scene_of_fill(const Scene& first, int fill) {
  Scene s = first;
  for (DamperScene& d : s.dampers) {
    try {  // build_scene() drew every fill a run may ask for: this cannot refuse
      fill_damper(d, d.particles.seed + static_cast<std::uint64_t>(fill), SourcePos{}, "");
    } catch (const InputError& error) {
      throw SimulationError("fill " + std::to_string(fill + 1) +
                            " could not be drawn: " + error.what());
    }
  }
  return s;
}

LinearStructure build_structure(const Deck& deck) {
  return build_structure(deck.structure, mounts_of(deck), locate(deck));
}

std::vector<double> structure_frequencies(const Deck& deck) {
  try {
    return natural_frequencies(build_structure(deck));
  } catch (const SimulationError&) {
    throw_no_modes(locate(deck));
  }
}

}  // namespace pdsim

// The scene: the deck compiled into what the solver runs, with the physical cross-checks that
// need derived quantities (particles fit, dt below the stability limit at the deck's
// frequencies). In two steps: the dampers (particle masses, contact constants, kernel variant,
// initial positions, a penalty law's time step), then the host they are placed on (the built
// structure, or a prescribed motion as a map's runs share; a rigid contact's step follows it).
// deck -> scene + run plan (src/run_plan.hpp) -> solver: the coupled system takes only the
// scene, the frequency runs the scene and the plan.
#pragma once

#include <string>
#include <vector>

#include "io/specs.hpp"
#include "kernels/engine.hpp"
#include "structure/structure.hpp"

namespace pdsim {

struct Deck;  // io/deck.hpp: only the compile functions and the deck helpers below read it

struct DamperScene {
  EngineConfig engine;       // dt is filled per run segment by the solver
  double particle_mass = 0;  // kg, total
  double fill_fraction = 0;  // particle volume / container volume
  // What every fill is drawn from (scene_of_fill), in the container of `engine` (shape and
  // geometry); its seed is fill 0's. build_scene() drew and checked every fill a run may draw.
  ParticleSpec particles;
};

// The deck's dampers compiled apart from any host: each damper's engine and fill 0, the backend,
// and the step their contact law allows (rigid contacts' step follows the host's motion: set
// when the model is placed on one, place_dampers()).
struct DamperModel {
  std::vector<DamperScene> dampers;
  Backend backend = Backend::cpu;
  std::string backend_reason;
  double dt = 0;             // s, largest step the solver may take
  double dt_limit = 0;       // s, stability/accuracy limit for an explicit dt
  std::string warning;       // what the user accepted against advice (allow_unstable), or ""
  double contact_time = 0;   // s, linear: exact binary contact time; hertz: estimate at 1 m/s
  std::string contact_note;  // how contact_time was taken (the law's words), or ""
  double rayleigh_time = 0;  // s, hertz only
  std::string dt_basis;      // how dt was chosen
  int threads = 0;
  double r_min = 0;  // m, the smallest radius any fill holds (a rigid step follows it)
};

// The dampers placed on their host: what the coupled system runs.
struct Scene : DamperModel {
  // Rigid contacts' thresholds as the deck gives them, m/s (0: derived from the scene's motion
  // and step, as each map run's are): a choice of the damper's model (src/identity.cpp).
  double rest_speed_given = 0, recovery_speed_given = 0, tolerance_given = 0;

  // The host, checked: a structure, or (none) the containers' motion prescribed along an axis.
  std::optional<LinearStructure> structure;  // built once, here (with a damper at each mount)
  std::vector<double> natural_hz;            // the structure's natural frequencies, ascending
  IntegratorKind integrator = IntegratorKind::exact;
  Vec3 direction{1, 0, 0};            // unit: the structure's motion direction
  std::optional<Vec3> rotation_axis;  // unit: a beam's mounts turn about it with its slope
  Vec3 motion_axis{1, 0, 0};          // no structure: the containers move along it (unit)
  CouplingSpec coupling;
  std::optional<Vec3> gravity;
};

// Validates the physical consistency of `deck` and derives the scene: the deck's dampers
// (compile_dampers()) on its structure and excitation (place_dampers()). `threads` and `backend`
// override the deck's [solver] values when given (command line). `every_fill`: every fill a
// point may grow to is drawn, so that a seed whose fill cannot be drawn is refused now (else
// fill 0 only, for what needs no run).
Scene build_scene(const Deck& deck, int threads = 0, std::optional<Backend> backend = {},
                  bool every_fill = true);

// The deck's dampers, as build_scene() compiles them, the first `fills` fills of each drawn
// (fill 0 kept), so that a seed whose fill cannot be drawn is refused now.
DamperModel compile_dampers(const Deck& deck, int threads, std::optional<Backend> backend,
                            int fills);

// `model` (compiled from `deck`) on the host `structure` (kind none: the containers moved as
// `excitation`'s motion says) driven at `excitation`'s points; the deck's [solver], [contact]
// and [coupling] as they apply to that host, refused naming their keys. The scene of a map's
// run is the deck's dampers on a prescribed host.
Scene place_dampers(const DamperModel& model, const Deck& deck, const ExcitationSpec& excitation,
                    const StructureSpec& structure);

// The scene of another fill of the same design: `first` with every damper's particles drawn
// from fill seed seed + fill (radii, positions, masses); the rest (structure, dt) as it is.
Scene scene_of_fill(const Scene& first, int fill);

// The deck's structure with its dampers' mounts; errors name the deck's keys.
LinearStructure build_structure(const Deck& deck);
// Natural frequencies (Hz) of the deck's structure, ascending; an InputError when it has none.
std::vector<double> structure_frequencies(const Deck& deck);

// The container's axes in the world at rest: a cylinder's z along its `axis` (the shortest turn
// from z), the identity otherwise.
Orientation orientation_of(const ContainerSpec& container);

// Initial particle centres in the container's frame (centred at the origin; build_scene turns
// them into the world by orientation_of()) for a fill of `particles` of radii `radius` in a
// container of `shape` and `geometry`; errors name `where` and `key` (the damper's particles
// table).
std::vector<Vec3> fill_particles(WallShape shape, const ContainerGeometry& geometry,
                                 const ParticleSpec& particles, const std::vector<double>& radius,
                                 const SourcePos& where, const std::string& key);

}  // namespace pdsim

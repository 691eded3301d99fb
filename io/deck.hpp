// The input deck as the user wrote it, parsed and validated (brief section 5). SI units.
// Derived quantities (masses, time step, kernel variant) live in the Scene, not here.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "kernels/dem_types.hpp"
#include "src/common.hpp"

namespace pdsim {

enum class StructureKind { none, sdof, beam };
enum class Support { clamped, pinned, free };
enum class ContainerShape { box, cylinder };
enum class Fill { random, lattice };
enum class ExcitationKind { stepped_sine, sine, free_decay, prescribed };
enum class ExcitationInput { force, base_displacement, base_acceleration };
// How each stepped-sine frequency starts: `predicted` carries the particles on and puts the
// structure on the steady state predicted from the damper's measured impedance; `carried` is the
// physical stepped sine (the whole state carried on, nothing reset); `independent` starts every
// frequency from the settled bed with the predicted structure state, so that they run side by
// side.
enum class FrequencyStart { predicted, carried, independent };
enum class CouplingScheme { loose, interleaved, tight };
enum class IntegratorKind { exact, cvode };

struct BeamSpec {
  double length = 0;  // m
  int elements = 0;
  double young = 0;           // Pa
  double density = 0;         // kg/m^3
  double poisson = 0.3;       // for the Timoshenko shear modulus
  double area = 0;            // m^2, from `section`
  double inertia = 0;         // m^4, second moment about the bending axis
  double shear_factor = 0;    // Timoshenko shear coefficient (5/6 rectangle, 0.9 circle)
  double section_height = 0;  // m, section depth along `direction` (0 = not given)
  bool timoshenko = false;
  Vec3 axis{1, 0, 0};  // unit, along the beam; a damper turns about axis x direction
  Support start = Support::clamped;
  Support end = Support::free;
};

struct StructureSpec {
  StructureKind kind = StructureKind::none;
  // sdof
  double mass = 0;           // kg
  double stiffness = 0;      // N/m
  double damping = 0;        // N s/m (sdof: resolved from damping_ratio when that is given)
  double damping_ratio = 0;  // sdof: of the bare system; beam: modal damping ratio on every mode
  std::optional<std::array<double, 2>> rayleigh;  // beam: C = alpha M + beta K
  Vec3 direction{1, 0, 0};  // unit; sdof: motion direction; beam: bending direction ([0,0,1])
  BeamSpec beam;
  IntegratorKind integrator = IntegratorKind::exact;
  int modes = 0;  // beam: keep the first N modes (0 = full model)
};

struct ContainerSpec {
  ContainerShape shape = ContainerShape::box;
  Vec3 size;          // box: full edge lengths, m
  double radius = 0;  // cylinder, m (axis along z)
  double height = 0;  // cylinder, m
};

struct ParticleSpec {
  int count = 0;
  double diameter = 0;                        // m, monodisperse
  std::vector<double> diameters;              // polydisperse: diameters cycled over particles
  double diameter_min = 0, diameter_max = 0;  // polydisperse: uniform range
  double density = 0;                         // kg/m^3
  std::uint64_t seed = 1;
  Fill fill = Fill::random;
  bool polydisperse() const { return !diameters.empty() || diameter_max > 0; }
};

struct DamperSpec {
  ContainerSpec container;
  ParticleSpec particles;
  int attach_node = -1;            // beam: node index (0 = start)
  std::optional<double> attach_x;  // beam: position along the beam, m
};

struct ContactSpec {
  NormalModel model = NormalModel::hertz;
  TangentialModel tangential = TangentialModel::history;
  double young = 0;  // Pa
  double poisson = 0.3;
  double restitution = 0.6;     // (0, 1]
  double friction = 0.0;        // Coulomb coefficient
  double stiffness = 0;         // N/m, linear model normal stiffness (required for `linear`)
  double rolling_friction = 0;  // dimensionless rolling resistance coefficient (0 = off)
};

// When a frequency's response counts as steady (src/steady_state.hpp): its per-period first
// harmonics, after the warm-up is discarded, show no relevant drift and their mean is known to
// `tolerance` (95 % half-width relative to the amplitude; the phase's half-width in rad).
struct SettleSpec {
  int min_periods = 10;     // never converged before this many periods
  int max_periods = 400;    // a frequency stops here, converged or not
  double tolerance = 2e-2;  // relative 95 % half-width of the first-harmonic amplitude
  int batches = 4;          // batch means an interval needs
  int average_periods = 0;  // 0: the stationary periods found; N: the last N periods
  int realisations = 1;     // independent runs (fill seeds seed, seed+1, ...) per frequency
};
struct MotionSpec {
  Vec3 axis{1, 0, 0};    // unit
  double amplitude = 0;  // m
  double frequency = 0;  // Hz; for a sweep, the first of ExcitationSpec::frequencies
};

struct ExcitationSpec {
  ExcitationKind kind = ExcitationKind::sine;
  ExcitationInput input = ExcitationInput::force;
  double amplitude = 0;             // N, m or m/s^2 according to `input`
  std::vector<double> frequencies;  // Hz, in the order they are run (prescribed: never empty)
  SettleSpec settle;
  FrequencyStart start = FrequencyStart::predicted;  // stepped_sine (prescribed: carried)
  double frequency = 0;                              // Hz, `sine`
  double duration = 0;                               // s, `sine`, `free_decay`, `prescribed`
  double initial_displacement = 0;                   // m, `free_decay`
  MotionSpec motion;                                 // `prescribed`
};

struct CouplingSpec {
  CouplingScheme scheme = CouplingScheme::interleaved;  // energy-consistent at the cost of loose
  int every = 1;                                        // DEM steps per coupling exchange
  double tolerance = 1e-6;  // tight: relative change of the interface force
  int max_iterations = 10;  // tight
};

struct SolverSpec {
  double dt = 0;           // s; 0 = auto
  double dt_safety = 0.0;  // 0 = default for the contact model
  Backend backend = Backend::automatic;
  bool allow_unstable = false;
  int threads = 0;  // 0 = OpenMP default
};

// The particle bed settled under gravity, container at rest, before the excitation starts.
struct BedSpec {
  bool settle = false;    // default: true when gravity acts on particles
  double speed = 1e-3;    // m/s: settled when no particle moves faster, for kBedHold_s
  double max_time = 2.0;  // s of settling at most (then the run goes on, and says so)
  std::string file;       // settled bed read from here when it exists, else written here
};
constexpr double kBedHold_s = 0.02;  // a falling particle exceeds any threshold sooner

struct OutputSpec {
  std::string file;            // HDF5 path, relative to the working directory
  double every = 0;            // s between time-series samples; 0 = automatic
  bool energy = false;         // write /energy
  double particles_every = 0;  // s between particle snapshots (/particles and OUT.xdmf); 0 = none
};

// A parameter sweep, the [sweep] table: each key names a deck value by its dotted name
// ("damper.particles.count"; "damper[1].container.size" for one damper, "damper.x" for every
// one) and lists the values it takes. The points are every combination, numbered from 1 with
// the last key varying fastest; each is the deck with those values (sweep_point below).
struct SweepSpec {
  std::vector<std::string> keys;                     // in deck order
  std::vector<std::vector<std::string>> values;      // each value as TOML writes it
  int points() const;                                // 0 when there is no sweep
  std::vector<std::size_t> choice(int point) const;  // index of each key's value
  std::string describe(int point) const;             // "damper.particles.count = 200, ..."
};

struct Deck {
  std::string path;  // as given on the command line
  std::string text;  // the whole deck, stored as provenance
  std::string title;
  StructureSpec structure;
  std::vector<DamperSpec> dampers;
  ContactSpec contact;
  std::optional<Vec3> gravity;  // absent = no gravity
  ExcitationSpec excitation;
  BedSpec bed;
  CouplingSpec coupling;
  SolverSpec solver;
  OutputSpec output;
  SweepSpec sweep;
  int point = 0;  // the sweep point this deck is (1-based), 0 for the deck itself
  // Where each key given in the deck stands, by dotted name ("damper[0].particles.count").
  std::map<std::string, SourcePos> positions;

  // Position of a key (or of its closest enclosing table) for error messages.
  SourcePos where(const std::string& key) const;
};

// Parses and validates a deck; throws InputError naming file:line:column, key and expectation.
Deck load_deck(const std::string& path);
Deck parse_deck(const std::string& text, const std::string& path);

// Sweep point `point` (1 to deck.sweep.points()) of a deck: the deck with that point's values,
// validated. An error names the [sweep] entry that set the value, and the point.
Deck sweep_point(const Deck& deck, int point);

}  // namespace pdsim

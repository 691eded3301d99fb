// What each table of a deck holds, as plain values (SI units): the parser (io/deck.hpp) fills
// them, the scene (src/scene.hpp) keeps what the run needs. Nothing here knows the deck's text
// or its positions, so that what runs after the scene never sees the deck.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "kernels/contact_laws.hpp"
#include "kernels/dem_types.hpp"
#include "kernels/shapes.hpp"
#include "kernels/vec3.hpp"
#include "structure/structure_spec.hpp"

namespace pdsim {

enum class Fill { random, lattice };
enum class ExcitationKind { stepped_sine, sine, free_decay, prescribed };
enum class ExcitationInput { force, base_displacement, base_acceleration };
// How each stepped-sine frequency starts: `predicted` carries the particles on and puts the
// structure on the steady state predicted from the damper's measured impedance; `carried` is the
// physical stepped sine (the whole state carried on, nothing reset); `independent` starts every
// frequency from the settled bed with the predicted structure state, so that they run side by
// side.
enum class FrequencyStart { predicted, carried, independent };
// Their names in decks (`start`) and in /meta.
constexpr const char* kStartNames[] = {"predicted", "carried", "independent"};
inline const char* start_name(FrequencyStart s) {
  return kStartNames[static_cast<int>(s)];
}
enum class CouplingScheme { loose, interleaved, tight };

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

// When a frequency's response counts as steady (src/steady_state.hpp): its per-period first
// harmonics, after the warm-up is discarded, show no relevant drift and their mean is known to
// `tolerance` (95 % half-width relative to the amplitude; the phase's half-width in rad).
// Fills a point of a random fill may grow to by default (settle.max_realisations).
inline constexpr int kDefaultMaxFills = 4;

struct SettleSpec {
  int min_periods = 10;      // never converged before this many periods
  int max_periods = 400;     // a frequency stops here, converged or not
  double tolerance = 2e-2;   // relative 95 % half-width of the first-harmonic amplitude
  int batches = 4;           // batch means an interval needs
  int average_periods = 0;   // 0: the stationary periods found; N: the last N periods
  int realisations = 1;      // fills (fill seeds seed, seed+1, ...) a point starts with
  int max_realisations = 1;  // fills a point may grow to while its ensemble mean is not known
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
  std::vector<double> frequencies;  // Hz, in the order they are run (a sine's one; a free
                                    // decay's none)
  std::string frequencies_key = "excitation.frequencies";  // the deck key they came from
  std::vector<int> sweeps;         // per frequency: +1 sweeping up, -1 down (direction "both":
                                   // the list up, then down from the top again)
  std::vector<double> amplitudes;  // per frequency when the points' amplitudes differ (pdsim
                                   // map's amplitude steps), else `amplitude` / motion.amplitude
  SettleSpec settle;
  FrequencyStart start = FrequencyStart::predicted;  // stepped_sine (prescribed: carried)
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

// Where the points of a sweep run on a Slurm cluster (`pdsim sweep --slurm`), the [cluster] table.
struct ClusterSpec {
  std::string sbatch;  // sbatch options (partition, account, time limit, ...), split (and its
                       // variables expanded) only where a job is submitted
};

// A damper map, the [map] table (`pdsim map`): the deck's dampers under prescribed sinusoidal
// motion along the structure's direction over a grid of motion amplitudes (or peak
// accelerations) and frequencies.
// How a map's amplitudes follow each other at one frequency: each point from the settled bed, or
// stepped up (and back down) with the bed carried from one amplitude to the next.
enum class MapSteps { independent, up, both };
struct MapSpec {
  std::vector<double> amplitudes;     // m; or
  std::vector<double> accelerations;  // in units of kStandardGravity
  std::vector<double> frequencies;    // Hz
  double duration = 0;                // s per point; 0 = until the steady state (excitation.settle)
  MapSteps steps = MapSteps::independent;
  bool given() const { return !frequencies.empty(); }
};
constexpr double kStandardGravity = 9.80665;  // m/s^2, the unit of [map] accelerations

}  // namespace pdsim

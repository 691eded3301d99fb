// Host API of the DEM engine: one particle system in one rigid container. The backend (OpenMP
// or CUDA) and the kernel variant are chosen once, when the engine is made.
#pragma once

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <optional>
#include <vector>

#include "kernels/contact_laws.hpp"
#include "kernels/neighbours.hpp"
#include "kernels/nonsmooth.hpp"
#include "kernels/shapes.hpp"
#include "kernels/step_args.hpp"
#include "kernels/state_arrays.hpp"

namespace pdsim {

struct ParticleState {
  Vec3 position, velocity, spin;  // m, m/s, rad/s
};

struct EngineConfig {
  Backend backend = Backend::cpu;
  int threads = 0;  // OpenMP threads, 0 = default
  WallShape shape = WallShape::box;
  ContainerGeometry geometry;
  std::vector<double> radius;  // m, per particle
  double density = 0;          // kg/m^3
  NormalModel normal = NormalModel::hertz;
  TangentialModel tangential = TangentialModel::history;
  bool rolling = false;
  bool rotating = false;    // the container turns (a damper on a beam node) or is laid along
                            // another axis (orientation)
  Orientation orientation;  // the container's axes at rest
  std::optional<Vec3> gravity;
  ContactParams contact;
  // Rigid contacts (kernels/nonsmooth.hpp) instead of the penalty laws above: the CPU backend.
  std::optional<NonsmoothParams> nonsmooth;
  double dt = 0;    // s
  double skin = 0;  // m, Verlet skin (0 = 0.15 x smallest diameter), plus a rigid envelope
  std::vector<ParticleState> particles;  // initial state, world frame
  // A step may be computed again before accept() (tight coupling): the state then stays
  // double buffered. Otherwise the CPU engine advances it in place, which saves the memory
  // traffic of a second copy.
  bool recompute = false;
};

using StepTotals = ParticleContribution;

// A particle touches at most one wall per container axis of a box or cylinder only if it is
// narrower than the container (engine_sizes() checks; decks are checked with a clearer message
// before that), and at most kWallSlots features of a mesh (more stop the run).
constexpr int kMaxWallContacts = kWallSlots;
inline double smallest_inner_size(WallShape shape, const ContainerGeometry& g) {
  return with_shape(shape, [&](auto s) { return decltype(s)::smallest_inner_size(g); });
}

class DemEngine {
 public:
  virtual ~DemEngine() = default;
  // Computes the step t_n -> t_n + dt with the container at `container` (its state at t_n)
  // and returns the totals (the force on the container is the one at t_n). With
  // EngineConfig::recompute, into the back buffer, and calling it again before accept()
  // recomputes the same step (tight coupling); without it the state may advance in place, so
  // each compute() must be followed by accept().
  virtual const StepTotals& compute(const ContainerKinematics& container, double dt) = 0;
  virtual void accept() = 0;  // the computed step becomes the current state
  virtual int count() const = 0;
  virtual std::string variant() const = 0;  // e.g. "hertz/history/gravity/box"
  virtual std::string backend() const = 0;  // "cpu (2 threads)" or "cuda (H100)"
  virtual int threads() const = 0;
  // Particles of the current state, in their original order.
  virtual std::vector<ParticleState> particles() const = 0;
  virtual void set_particles(const std::vector<ParticleState>& state) = 0;  // clears history
  // Exact save/restore of everything the next steps depend on (checkpoints).
  virtual StateArrays save() const = 0;
  virtual void restore(const StateArrays& state) = 0;
  virtual std::size_t bytes_per_particle() const = 0;
};

// What the non-smooth steps of this process have cost their solver so far (all engines).
struct SolverTotals {
  long long steps = 0, iterations = 0;
  long long contacts = 0;     // summed over the steps
  long long capped = 0;       // steps that ended at the iteration cap
  int most = 0;               // iterations of the longest step
  double worst_residual = 0;  // m/s, the largest a step ended with
};
SolverTotals nonsmooth_totals();

// Throws InputError if the backend is unavailable (e.g. "cuda" without a GPU).
std::unique_ptr<DemEngine> make_engine(const EngineConfig& config);

// Name of the kernel variant a config selects, e.g. "hertz/history/gravity/mono/box".
std::string variant_name(const EngineConfig& config);

// Backend factories (kernels/cpu, kernels/cuda).
std::unique_ptr<DemEngine> make_cpu_engine(const EngineConfig& config);
std::unique_ptr<DemEngine> make_cuda_engine(const EngineConfig& config);
bool cuda_device_available(std::string* description = nullptr);

}  // namespace pdsim

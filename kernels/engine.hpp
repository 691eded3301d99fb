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
  double dt = 0;                         // s
  double skin = 0;                       // m, Verlet skin (0 = 0.15 x smallest diameter)
  std::vector<ParticleState> particles;  // initial state, world frame
  // A step may be computed again before accept() (tight coupling): the state then stays
  // double buffered. Otherwise the CPU engine advances it in place, which saves the memory
  // traffic of a second copy.
  bool recompute = false;
};

using StepTotals = ParticleContribution;

// The cell grid and rebuild policy of an engine's checkpoint, the same for both backends.
struct GridState {
  Grid grid{};
  bool needs_rebuild = true;
  int max_neighbours = 0;  // slots per particle in the checkpoint's lists
  double travel = 0;       // m, the particles' largest drift since the last rebuild
};
inline void put_grid(StateArrays& out, const GridState& g) {
  out["grid.origin"] = std::vector<double>{g.grid.origin.x, g.grid.origin.y, g.grid.origin.z};
  out["grid.cell_size"] = std::vector<double>{g.grid.cell_size};
  out["grid.cells"] = std::vector<std::int32_t>{g.grid.nx, g.grid.ny, g.grid.nz};
  out["needs_rebuild"] = std::vector<std::int32_t>{g.needs_rebuild ? 1 : 0};
  out["max_neighbours"] = std::vector<std::int32_t>{g.max_neighbours};
  out["travel"] = std::vector<double>{g.travel};
}
inline GridState get_grid(const StateArrays& in) {
  GridState g;
  const auto& origin = state_values<double>(in, "grid.origin");
  const auto& cells = state_values<std::int32_t>(in, "grid.cells");
  if (origin.size() != 3 || cells.size() != 3)
    throw SimulationError("the checkpoint's grid arrays should hold three values each");
  g.grid = {{origin[0], origin[1], origin[2]},
            state_value<double>(in, "grid.cell_size"),
            cells[0],
            cells[1],
            cells[2]};
  g.needs_rebuild = state_value<std::int32_t>(in, "needs_rebuild") != 0;
  g.max_neighbours = state_value<std::int32_t>(in, "max_neighbours");
  if (g.max_neighbours <= 0 || g.max_neighbours % kSlotGroup != 0)
    throw SimulationError("the checkpoint's max_neighbours is not a whole number of slot groups");
  g.travel = state_value<double>(in, "travel");
  return g;
}

// Contact history as a checkpoint stores it: `slots` slots of 3 values per particle, only those
// whose bit is set in the particle's mask. The others hold stale values that are never read and
// would make two equal states save differently. Scenes without history have none (empty).
template <class Mask>
std::vector<double> live_history(std::vector<double> history, const std::vector<Mask>& mask,
                                 int slots) {
  if (history.empty()) return history;
  for (std::size_t i = 0; i < mask.size(); ++i)
    for (int k = 0; k < slots; ++k)
      if (!(static_cast<std::uint64_t>(mask[i]) >> k & 1u))
        for (int c = 0; c < 3; ++c) history[3 * (i * static_cast<std::size_t>(slots) + k) + c] = 0;
  return history;
}

// Checkpoints store the lists in the fixed-stride layout (`slots` per particle, the GPU's own),
// whatever the backend's, so that they move between backends. A reverse entry is stored there
// as the flat slot owner * slots + k (-1 where unused; check_particle_count keeps it in int32).
inline std::vector<std::int32_t> flat_reverse(const std::vector<std::int32_t>& entries, int slots) {
  std::vector<std::int32_t> out(entries.size(), -1);
  for (std::size_t r = 0; r < entries.size(); ++r)
    if (entries[r] >= 0) out[r] = entry_owner(entries[r]) * slots + entry_place(entries[r]);
  return out;
}
inline std::vector<std::int32_t> packed_reverse(const std::vector<std::int32_t>& flat, int slots) {
  std::vector<std::int32_t> out(flat.size(), -1);
  for (std::size_t r = 0; r < flat.size(); ++r)
    if (flat[r] >= 0) out[r] = reverse_entry(flat[r] / slots, flat[r] % slots);
  return out;
}

// Both backends index slots with int32 and pack reverse entries (see reverse_entry()).
inline void check_particle_count(int count, int max_neighbours) {
  if (count > kMaxParticles ||
      static_cast<long long>(count) * max_neighbours > std::numeric_limits<std::int32_t>::max())
    throw SimulationError(std::to_string(count) + " particles with " +
                          std::to_string(max_neighbours) +
                          " neighbour slots each are more than a DEM engine indexes (at most " +
                          std::to_string(kMaxParticles) + " particles and 2^31 slots)");
}

// A particle touches at most one wall per container axis (kMaxWallContacts) only if it is
// narrower than the container; decks are checked with a clearer message before this.
constexpr int kMaxWallContacts = 3;
inline double smallest_inner_size(WallShape shape, const ContainerGeometry& g) {
  return with_shape(shape, [&](auto s) { return decltype(s)::smallest_inner_size(g); });
}
inline void check_fits(WallShape shape, const ContainerGeometry& g, double r_max) {
  if (2 * r_max >= smallest_inner_size(shape, g))
    throw SimulationError("particle diameter " + std::to_string(2 * r_max) +
                          " m does not fit in the container");
}

// What both backends derive from a config before allocating: the radii's range, the Verlet
// skin and the neighbour slots per particle, all checked.
struct EngineSizes {
  int count = 0;
  double r_min = 0, r_max = 0, skin = 0;  // m
  int max_neighbours = 0;
};
inline EngineSizes engine_sizes(const EngineConfig& c) {
  if (c.particles.empty() || c.radius.size() != c.particles.size())
    throw SimulationError("a DEM engine needs at least one particle and one radius per particle");
  EngineSizes s;
  s.count = static_cast<int>(c.particles.size());
  const auto [r_min, r_max] = std::minmax_element(c.radius.begin(), c.radius.end());
  s.r_min = *r_min;
  s.r_max = *r_max;
  s.skin = default_skin(s.r_min, c.skin);
  s.max_neighbours = neighbour_slots(s.r_min, s.r_max, s.skin);
  check_particle_count(s.count, s.max_neighbours);
  check_fits(c.shape, c.geometry, s.r_max);
  return s;
}

inline std::string neighbour_overflow_message(int max_neighbours) {
  return "neighbour list overflow (" + std::to_string(max_neighbours) +
         " slots): particles are packed beyond the densest packing; the simulation has most "
         "likely blown up";
}

// The checkpoint's names of the particle state's nine columns, in ParticleArrays' order.
inline constexpr const char* kStateNames[9] = {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz"};

// Every array of a DEM engine's checkpoint, as either backend writes it and both read it (lists
// in the fixed-stride layout): its element type and its length, in values per particle, per list
// slot (particles x max_neighbours) or in all. restore() checks a checkpoint against this table
// before reading it (check_checkpoint), so that a damaged or foreign one is refused by name
// instead of being read past an array's end; the round-trip tests check that save() writes
// exactly these.
enum class CheckpointType { f64, i32, u64, u8 };  // StateArray's alternatives, in order
enum class CheckpointExtent { particle, slot, total };
struct CheckpointField {
  const char* name;
  CheckpointType type;
  CheckpointExtent extent;
  int values;    // per particle or slot, or in all
  bool history;  // empty in scenes without tangential history
};
inline constexpr CheckpointField kCheckpointFields[] = {
    {kStateNames[0], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[1], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[2], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[3], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[4], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[5], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[6], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[7], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {kStateNames[8], CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {"id", CheckpointType::i32, CheckpointExtent::particle, 1, false},
    {"radius", CheckpointType::f64, CheckpointExtent::particle, 1, false},
    {"history", CheckpointType::f64, CheckpointExtent::slot, 3, true},
    {"wall_history", CheckpointType::f64, CheckpointExtent::particle, 3 * kWallSlots, true},
    {"wall_mask", CheckpointType::u8, CheckpointExtent::particle, 1, false},
    {"neighbour_mask", CheckpointType::u64, CheckpointExtent::particle, 1, false},
    {"neighbours", CheckpointType::i32, CheckpointExtent::slot, 1, false},
    {"partner_id", CheckpointType::i32, CheckpointExtent::slot, 1, false},
    {"neighbour_count", CheckpointType::i32, CheckpointExtent::particle, 1, false},
    {"reverse", CheckpointType::i32, CheckpointExtent::slot, 1, false},
    {"reverse_count", CheckpointType::i32, CheckpointExtent::particle, 1, false},
    {"grid.origin", CheckpointType::f64, CheckpointExtent::total, 3, false},
    {"grid.cell_size", CheckpointType::f64, CheckpointExtent::total, 1, false},
    {"grid.cells", CheckpointType::i32, CheckpointExtent::total, 3, false},
    {"needs_rebuild", CheckpointType::i32, CheckpointExtent::total, 1, false},
    {"max_neighbours", CheckpointType::i32, CheckpointExtent::total, 1, false},
    {"travel", CheckpointType::f64, CheckpointExtent::total, 1, false},
};

// Refuses (SimulationError, naming the array) a checkpoint that is not one of `count` particles
// for an engine with (`history`) or without tangential history: an array missing, unknown, of
// another type or length, or a particle or list index out of range. Returns its grid.
inline GridState check_checkpoint(const StateArrays& in, int count, bool history) {
  const GridState g = get_grid(in);
  check_particle_count(count, g.max_neighbours);
  const auto n = static_cast<std::size_t>(count);
  const std::size_t slots = n * static_cast<std::size_t>(g.max_neighbours);
  static constexpr const char* kTypeNames[] = {"double", "int32", "uint64", "uint8"};
  for (const CheckpointField& f : kCheckpointFields) {
    const auto it = in.find(f.name);
    if (it == in.end())
      throw SimulationError(std::string("the checkpoint lacks the array '") + f.name + "'");
    const auto type = static_cast<std::size_t>(f.type);
    if (it->second.index() != type)
      throw SimulationError(std::string("the checkpoint's array '") + f.name + "' holds " +
                            kTypeNames[it->second.index()] + " values, not " + kTypeNames[type]);
    const std::size_t per = f.extent == CheckpointExtent::particle ? n
                            : f.extent == CheckpointExtent::slot   ? slots
                                                                   : 1;
    const std::size_t expected =
        f.history && !history ? 0 : per * static_cast<std::size_t>(f.values);
    const std::size_t size = std::visit([](const auto& v) { return v.size(); }, it->second);
    if (size != expected)
      throw SimulationError(
          std::string("the checkpoint's array '") + f.name + "' holds " + std::to_string(size) +
          " values; a checkpoint of " + std::to_string(count) + " particles with " +
          std::to_string(g.max_neighbours) + " list slots each" +
          (history ? ", with tangential history," : ", without tangential history,") + " holds " +
          std::to_string(expected));
  }
  for (const auto& array : in) {
    const std::string& name = array.first;
    if (std::none_of(std::begin(kCheckpointFields), std::end(kCheckpointFields),
                     [&](const CheckpointField& f) { return name == f.name; }))
      throw SimulationError("the checkpoint holds an array '" + name +
                            "' that a DEM engine does not write");
  }
  // Indices: each read below indexes an array by them.
  auto refuse = [](const char* name, const std::string& what) {
    throw SimulationError(std::string("the checkpoint's array '") + name + "' " + what);
  };
  std::vector<char> seen(n, 0);
  for (const std::int32_t id : state_values<std::int32_t>(in, "id")) {
    if (id < 0 || id >= count || seen[static_cast<std::size_t>(id)])
      refuse("id", "is not a permutation of the particles");
    seen[static_cast<std::size_t>(id)] = 1;
  }
  const auto& neighbour_count = state_values<std::int32_t>(in, "neighbour_count");
  const auto& reverse_count = state_values<std::int32_t>(in, "reverse_count");
  const auto& neighbours = state_values<std::int32_t>(in, "neighbours");
  const auto& partner = state_values<std::int32_t>(in, "partner_id");
  const auto& reverse = state_values<std::int32_t>(in, "reverse");
  const long long slot_count = static_cast<long long>(slots);
  for (std::size_t i = 0; i < n; ++i) {
    const int listed = neighbour_count[i], listing = reverse_count[i];
    if (listed < 0 || padded(listed) > g.max_neighbours)
      refuse("neighbour_count", "holds " + std::to_string(listed) + " partners for a list of " +
                                    std::to_string(g.max_neighbours) + " slots");
    if (listing < 0 || listing > g.max_neighbours)
      refuse("reverse_count", "holds " + std::to_string(listing) + " entries for a list of " +
                                  std::to_string(g.max_neighbours) + " slots");
    const std::size_t base = i * static_cast<std::size_t>(g.max_neighbours);
    for (int k = 0; k < padded(listed); ++k)
      if (neighbours[base + k] < 0 || neighbours[base + k] >= count)
        refuse("neighbours", "names a particle out of range");
    for (int k = 0; k < listed; ++k)
      if (partner[base + k] < 0 || partner[base + k] >= count)
        refuse("partner_id", "names a particle out of range");
    for (int k = 0; k < listing; ++k)
      if (reverse[base + k] < 0 || reverse[base + k] >= slot_count)
        refuse("reverse", "names a list slot out of range");
  }
  return g;
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

// Throws InputError if the backend is unavailable (e.g. "cuda" without a GPU).
std::unique_ptr<DemEngine> make_engine(const EngineConfig& config);

// Name of the kernel variant a config selects, e.g. "hertz/history/gravity/mono/box".
std::string variant_name(const EngineConfig& config);

// Backend factories (kernels/cpu, kernels/cuda).
std::unique_ptr<DemEngine> make_cpu_engine(const EngineConfig& config);
std::unique_ptr<DemEngine> make_cuda_engine(const EngineConfig& config);
bool cuda_device_available(std::string* description = nullptr);

}  // namespace pdsim

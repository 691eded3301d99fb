// The bookkeeping both DEM backends share, written once over the backend's array type
// (std::vector for the CPU engine, kernels/cpu/engine_cpu.cpp; device buffers for the GPU
// engine, kernels/gpu_engine.hpp): the engine's sizes, its arrays, the step's and the neighbour
// build's arguments from them, the particles' mass properties, the rebuild policy and the
// checkpoint. A backend keeps its launches, its buffers and its lists' layout (compact on the
// CPU, a fixed stride of max_neighbours slots per particle on the GPU).
#pragma once

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "kernels/engine.hpp"
#include "kernels/variant_dispatch.hpp"

namespace pdsim {

// ---- sizes --------------------------------------------------------------------------------------

// Both backends index slots with int32 and pack reverse entries (see reverse_entry()); the
// values of a slot (3 or 9 per slot) are addressed in 64 bits (load3()), past 2^31 here.
inline void check_particle_count(int count, int max_neighbours) {
  if (count > kMaxParticles ||
      static_cast<long long>(count) * max_neighbours > std::numeric_limits<std::int32_t>::max())
    throw SimulationError(std::to_string(count) + " particles with " +
                          std::to_string(max_neighbours) +
                          " neighbour slots each are more than a DEM engine indexes (at most " +
                          std::to_string(kMaxParticles) + " particles and 2^31 slots)");
}

// What a config sets before anything is allocated: the radii's range, the Verlet skin and the
// neighbour slots per particle, all checked.
struct EngineSizes {
  int count = 0;
  double r_min = 0, r_max = 0, skin = 0;  // m
  // m: pairs this far apart enter a step (rigid contacts' envelope, 0 for the penalty laws);
  // the skin holds it on top of the drift margin, so that the lists hold every such pair
  double reach = 0;
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
  s.reach = c.nonsmooth ? c.nonsmooth->envelope : 0.0;
  s.skin = default_skin(s.r_min, c.skin) + s.reach;
  s.max_neighbours = neighbour_slots(s.r_min, s.r_max, s.skin);
  check_particle_count(s.count, s.max_neighbours);
  if (2 * s.r_max >= smallest_inner_size(c.shape, c.geometry))
    throw SimulationError("particle diameter " + std::to_string(2 * s.r_max) +
                          " m does not fit in the container");
  return s;
}

inline std::string neighbour_overflow_message(int max_neighbours) {
  return "neighbour list overflow (" + std::to_string(max_neighbours) +
         " slots): particles are packed beyond the densest packing; the simulation has most "
         "likely blown up";
}

// ---- the checkpoint -----------------------------------------------------------------------------

// A DEM engine's checkpoint as both backends write and read it: the particles in the engine's
// order; the lists in the fixed-stride layout (max_neighbours slots per particle, the GPU's own)
// whatever the backend's, so that checkpoints move between backends, reverse entries packed
// (reverse_entry()); the contact history only in scenes with tangential history.
struct EngineCheckpoint {
  std::vector<double> x, y, z, vx, vy, vz, wx, wy, wz;
  std::vector<std::int32_t> id;
  std::vector<double> radius;
  std::vector<double> history, wall_history;  // 3 per slot; kWallSlots x 3 per particle
  std::vector<std::uint8_t> wall_mask;
  std::vector<std::int32_t> wall_key;  // kWallSlots per particle (history only)
  std::vector<std::uint64_t> neighbour_mask;
  std::vector<std::int32_t> neighbours, partner_id, neighbour_count, reverse, reverse_count;
  // The cell grid and the rebuild policy.
  Grid grid{};
  bool needs_rebuild = true;
  int max_neighbours = 0;  // slots per particle in the lists above
  double travel = 0;       // m, the particles' largest drift since the last rebuild
};

// How long an array of the checkpoint is: values per particle, per list slot (particles x
// max_neighbours) or in all; `history`: empty in scenes without tangential history.
enum class CheckpointExtent { particle, slot, total };
struct CheckpointField {
  const char* name;
  CheckpointExtent extent;
  int values;
  bool history;        // empty without tangential history
  bool keyed = false;  // empty unless the walls are keyed (a mesh) too
};

// The checkpoint's arrays, declared once: f(field, array) for each, its element type the
// array's. The grid's six values (kGridArrays) are written by to_arrays() and read by
// from_arrays().
template <class Checkpoint, class F>
void for_each_array(Checkpoint& c, F&& f) {
  using E = CheckpointExtent;
  f(CheckpointField{"x", E::particle, 1, false}, c.x);
  f(CheckpointField{"y", E::particle, 1, false}, c.y);
  f(CheckpointField{"z", E::particle, 1, false}, c.z);
  f(CheckpointField{"vx", E::particle, 1, false}, c.vx);
  f(CheckpointField{"vy", E::particle, 1, false}, c.vy);
  f(CheckpointField{"vz", E::particle, 1, false}, c.vz);
  f(CheckpointField{"wx", E::particle, 1, false}, c.wx);
  f(CheckpointField{"wy", E::particle, 1, false}, c.wy);
  f(CheckpointField{"wz", E::particle, 1, false}, c.wz);
  f(CheckpointField{"id", E::particle, 1, false}, c.id);
  f(CheckpointField{"radius", E::particle, 1, false}, c.radius);
  f(CheckpointField{"history", E::slot, 3, true}, c.history);
  f(CheckpointField{"wall_history", E::particle, 3 * kWallSlots, true}, c.wall_history);
  f(CheckpointField{"wall_mask", E::particle, 1, false}, c.wall_mask);
  f(CheckpointField{"wall_key", E::particle, kWallSlots, true, true}, c.wall_key);
  f(CheckpointField{"neighbour_mask", E::particle, 1, false}, c.neighbour_mask);
  f(CheckpointField{"neighbours", E::slot, 1, false}, c.neighbours);
  f(CheckpointField{"partner_id", E::slot, 1, false}, c.partner_id);
  f(CheckpointField{"neighbour_count", E::particle, 1, false}, c.neighbour_count);
  f(CheckpointField{"reverse", E::slot, 1, false}, c.reverse);
  f(CheckpointField{"reverse_count", E::particle, 1, false}, c.reverse_count);
}
inline constexpr const char* kGridArrays[] = {"grid.origin",   "grid.cell_size", "grid.cells",
                                              "needs_rebuild", "max_neighbours", "travel"};

// The particle state's nine arrays, in ParticleArrays' order.
template <class Checkpoint>
auto state_columns(Checkpoint& c) {
  return std::array<decltype(&c.x), 9>{&c.x, &c.y, &c.z, &c.vx, &c.vy, &c.vz, &c.wx, &c.wy, &c.wz};
}

// Every array's name, as save() writes them.
inline std::vector<std::string> checkpoint_arrays() {
  EngineCheckpoint c;
  std::vector<std::string> names;
  for_each_array(c, [&](const CheckpointField& f, const auto&) { names.push_back(f.name); });
  names.insert(names.end(), std::begin(kGridArrays), std::end(kGridArrays));
  return names;
}

// Contact history as a checkpoint stores it: `slots` slots of 3 values per particle, only those
// whose bit is set in the particle's mask. The others hold stale values that are never read and
// would make two equal states save differently. Scenes without history have none (empty).
template <class T, class Mask>
std::vector<T> live_history(std::vector<T> history, const std::vector<Mask>& mask, int slots,
                            int values = 3) {
  if (history.empty()) return history;
  for (std::size_t i = 0; i < mask.size(); ++i)
    for (int k = 0; k < slots; ++k)
      if (!(static_cast<std::uint64_t>(mask[i]) >> k & 1u))
        for (int c = 0; c < values; ++c)
          history[values * (i * static_cast<std::size_t>(slots) + k) + c] = 0;
  return history;
}

// List slots past a particle's count (padded(count) for the forward lists) hold whatever the
// last build left there, never read; a checkpoint holds -1 there, so that equal states save
// equal bytes whatever the backend's memory held before.
inline std::vector<std::int32_t> live_slots(std::vector<std::int32_t> list,
                                            const std::vector<std::int32_t>& count, int slots,
                                            bool padded_list) {
  for (std::size_t i = 0; i < count.size() && !list.empty(); ++i) {
    const int used = std::clamp(padded_list ? padded(count[i]) : count[i], 0, slots);
    const auto begin = list.begin() + static_cast<std::ptrdiff_t>(i) * slots;
    std::fill(begin + used, begin + slots, -1);
  }
  return list;
}

// A file stores a reverse entry as the flat slot owner * slots + k (-1 where unused;
// check_particle_count keeps it in int32), the engines as a packed reverse_entry().
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

// The arrays a checkpoint file holds, history only where live and reverse entries flat.
inline StateArrays to_arrays(EngineCheckpoint c) {
  c.history = live_history(std::move(c.history), c.neighbour_mask, c.max_neighbours);
  c.wall_history = live_history(std::move(c.wall_history), c.wall_mask, kWallSlots);
  c.wall_key = live_history(std::move(c.wall_key), c.wall_mask, kWallSlots, 1);
  const int m = c.max_neighbours;
  c.neighbours = live_slots(std::move(c.neighbours), c.neighbour_count, m, true);
  c.partner_id = live_slots(std::move(c.partner_id), c.neighbour_count, m, false);
  c.reverse = flat_reverse(live_slots(std::move(c.reverse), c.reverse_count, m, false), m);
  StateArrays out;
  for_each_array(c,
                 [&](const CheckpointField& f, auto& values) { out[f.name] = std::move(values); });
  out[kGridArrays[0]] = std::vector<double>{c.grid.origin.x, c.grid.origin.y, c.grid.origin.z};
  out[kGridArrays[1]] = std::vector<double>{c.grid.cell_size};
  out[kGridArrays[2]] = std::vector<std::int32_t>{c.grid.nx, c.grid.ny, c.grid.nz};
  out[kGridArrays[3]] = std::vector<std::int32_t>{c.needs_rebuild ? 1 : 0};
  out[kGridArrays[4]] = std::vector<std::int32_t>{c.max_neighbours};
  out[kGridArrays[5]] = std::vector<double>{c.travel};
  return out;
}

// StateArray's alternatives, as messages name them.
inline constexpr const char* kTypeNames[] = {"double", "int32", "uint64", "uint8"};

// Reads a checkpoint of `count` particles for an engine with (`history`) or without tangential
// history, refusing (SimulationError, naming the array) one that is not: an array missing,
// unknown, of another type or length, or a particle or list index out of range, so that a
// damaged or foreign checkpoint is never read past an array's end.
inline EngineCheckpoint from_arrays(const StateArrays& in, int count, bool history, bool keyed) {
  EngineCheckpoint c;
  const auto& origin = state_values<double>(in, kGridArrays[0]);
  const auto& cells = state_values<std::int32_t>(in, kGridArrays[2]);
  if (origin.size() != 3 || cells.size() != 3)
    throw SimulationError("the checkpoint's grid arrays should hold three values each");
  c.grid = {{origin[0], origin[1], origin[2]},
            state_value<double>(in, kGridArrays[1]),
            cells[0],
            cells[1],
            cells[2]};
  c.needs_rebuild = state_value<std::int32_t>(in, kGridArrays[3]) != 0;
  c.max_neighbours = state_value<std::int32_t>(in, kGridArrays[4]);
  if (c.max_neighbours <= 0 || c.max_neighbours > 64 || c.max_neighbours % kSlotGroup != 0)
    throw SimulationError(
        "the checkpoint's max_neighbours is not a whole number of slot groups up to 64 (the "
        "width of the slot masks)");
  c.travel = state_value<double>(in, kGridArrays[5]);
  check_particle_count(count, c.max_neighbours);

  const auto n = static_cast<std::size_t>(count);
  const std::size_t slots = n * static_cast<std::size_t>(c.max_neighbours);
  for_each_array(c, [&](const CheckpointField& f, auto& values) {
    using Values = std::decay_t<decltype(values)>;
    const auto it = in.find(f.name);
    if (it == in.end())
      throw SimulationError(std::string("the checkpoint lacks the array '") + f.name + "'");
    const StateArray expected_type{Values{}};
    if (it->second.index() != expected_type.index())
      throw SimulationError(std::string("the checkpoint's array '") + f.name + "' holds " +
                            kTypeNames[it->second.index()] + " values, not " +
                            kTypeNames[expected_type.index()]);
    const std::size_t per = f.extent == CheckpointExtent::particle ? n
                            : f.extent == CheckpointExtent::slot   ? slots
                                                                   : 1;
    const bool absent = (f.history && !history) || (f.keyed && !(history && keyed));
    const std::size_t expected = absent ? 0 : per * static_cast<std::size_t>(f.values);
    values = std::get<Values>(it->second);
    if (values.size() != expected)
      throw SimulationError(
          std::string("the checkpoint's array '") + f.name + "' holds " +
          std::to_string(values.size()) + " values; a checkpoint of " + std::to_string(count) +
          " particles with " + std::to_string(c.max_neighbours) + " list slots each" +
          (history ? ", with tangential history," : ", without tangential history,") + " holds " +
          std::to_string(expected));
  });
  const std::vector<std::string> known = checkpoint_arrays();
  for (const auto& array : in)
    if (std::find(known.begin(), known.end(), array.first) == known.end())
      throw SimulationError("the checkpoint holds an array '" + array.first +
                            "' that a DEM engine does not write");

  // Indices: the engines index arrays by them.
  auto refuse = [](const char* name, const std::string& what) {
    throw SimulationError(std::string("the checkpoint's array '") + name + "' " + what);
  };
  std::vector<char> seen(n, 0);
  for (const std::int32_t id : c.id) {
    if (id < 0 || id >= count || seen[static_cast<std::size_t>(id)])
      refuse("id", "is not a permutation of the particles");
    seen[static_cast<std::size_t>(id)] = 1;
  }
  const long long slot_count = static_cast<long long>(slots);
  for (std::size_t i = 0; i < n; ++i) {
    const int listed = c.neighbour_count[i], listing = c.reverse_count[i];
    if (listed < 0 || padded(listed) > c.max_neighbours)
      refuse("neighbour_count", "holds " + std::to_string(listed) + " partners for a list of " +
                                    std::to_string(c.max_neighbours) + " slots");
    if (listing < 0 || listing > c.max_neighbours)
      refuse("reverse_count", "holds " + std::to_string(listing) + " entries for a list of " +
                                  std::to_string(c.max_neighbours) + " slots");
    const std::size_t base = i * static_cast<std::size_t>(c.max_neighbours);
    for (int k = 0; k < padded(listed); ++k)
      if (c.neighbours[base + k] < 0 || c.neighbours[base + k] >= count)
        refuse("neighbours", "names a particle out of range");
    for (int k = 0; k < listed; ++k)
      if (c.partner_id[base + k] < 0 || c.partner_id[base + k] >= count)
        refuse("partner_id", "names a particle out of range");
    for (int k = 0; k < listing; ++k)
      if (c.reverse[base + k] < 0 || c.reverse[base + k] >= slot_count)
        refuse("reverse", "names a list slot out of range");
  }
  c.reverse = packed_reverse(c.reverse, c.max_neighbours);
  return c;
}

// ---- the engine core ----------------------------------------------------------------------------

// What both engines hold and do alike, over the backend's `Array<T>` (data() is all it reads).
// The backends derive from it and keep their launches, buffers and list layout.
template <template <class> class Array>
class EngineCore : public DemEngine {
 public:
  int count() const override { return count_; }
  std::string variant() const override { return variant_.name; }

 protected:
  // Whether the walls' history is keyed (kernels/shape_mesh.hpp): only then are the keys kept.
  bool keyed_history() const { return variant_.history && config_.shape == WallShape::mesh; }
  struct State {  // the particles' nine columns
    Array<double> x, y, z, vx, vy, vz, wx, wy, wz;
    Array<double>* all[9] = {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz};
    ParticleArrays view() {
      return {x.data(),  y.data(),  z.data(),  vx.data(), vy.data(),
              vz.data(), wx.data(), wy.data(), wz.data()};
    }
  };
  struct History {
    Array<double> neighbour, wall;
    Array<std::uint64_t> neighbour_mask;
    Array<std::uint8_t> wall_mask;
    Array<std::int32_t> wall_key;  // kWallSlots per particle, with history
  };

  EngineCore(const EngineConfig& c, VariantInfo variant)
      : config_(c),
        variant_(std::move(variant)),
        sizes_(engine_sizes(c)),
        count_(sizes_.count),
        max_neighbours_(sizes_.max_neighbours) {}

  // A mesh container's triangles and bins for these particles, in the backend's arrays:
  // place(host vector, array) copies one there, and the particles' memos where `memo` (an
  // engine that permutes them with the particles). Nothing for the other shapes.
  template <class Place>
  void place_mesh(Place&& place, bool memo = false) {
    if (config_.shape != WallShape::mesh) return;
    const MeshSurface& s = *config_.geometry.surface;
    const std::shared_ptr<const MeshBins> bins = mesh_bins(s, sizes_.r_max);
    place(s.triangle, mesh_triangle_);
    place(s.key, mesh_key_);
    place(bins->start, mesh_bin_start_);
    place(bins->triangle, mesh_bin_triangle_);
    MeshView& v = scene_args_.geometry.mesh;
    v = mesh_view(s, *bins);
    v.triangle = mesh_triangle_.data();
    v.key = mesh_key_.data();
    v.bin_start = mesh_bin_start_.data();
    v.bin_triangle = mesh_bin_triangle_.data();
    if (!memo) return;
    const auto n = static_cast<std::size_t>(count_);
    place(std::vector<std::int32_t>(kMemoInts * n, -1), mesh_memo_);  // bin -1: none made
    place(std::vector<double>(4 * n), mesh_memo_at_);
    v.memo = mesh_memo_.data();
    v.memo_at = mesh_memo_at_.data();
  }

  // The particles' inverse masses and inertias, from their radii (one expression for both
  // backends and for restored runs, so that they agree bitwise).
  struct MassProperties {
    std::vector<double> inv_mass, inv_inertia;
  };
  MassProperties mass_properties(const std::vector<double>& radius) const {
    MassProperties m{std::vector<double>(radius.size()), std::vector<double>(radius.size())};
    for (std::size_t i = 0; i < radius.size(); ++i) {
      const SphereMass s = sphere_mass(radius[i], config_.density);
      m.inv_mass[i] = s.inv_mass;
      m.inv_inertia[i] = s.inv_inertia;
    }
    return m;
  }

  // The step from `in` to `out` (the same buffers for a step in place).
  ParticleStepArgs step_args(const ContainerKinematics& container, double dt, State& in, State& out,
                             const History& hin, History& hout, double* pair_load) {
    ParticleStepArgs a = scene_args_;
    a.dt = dt;
    a.container = container;
    a.in = in.view();
    a.out = out.view();
    a.radius = radius_.data();
    a.inv_mass = inv_mass_.data();
    a.inv_inertia = inv_inertia_.data();
    a.neighbours = neighbours_.data();
    a.neighbour_count = neighbour_count_.data();
    a.reverse = reverse_.data();
    a.reverse_count = reverse_count_.data();
    a.slot_start = slot_start_.data();
    a.reverse_start = reverse_start_.data();
    a.history = history_view(hin, hout);
    a.incoming = incoming_.data();
    a.pair_load = pair_load;
    return a;
  }

  // The grid for a rebuild around the container.
  Grid rebuild_grid(const ContainerKinematics& container) const {
    return grid_around(
        container.position, world_half_size(config_.geometry.half_size, config_.orientation),
        2 * sizes_.r_max + sizes_.skin, grid_cells_for(static_cast<std::size_t>(count_)));
  }

  // A neighbour build over `sorted` (the state sorted by cell, grid_ its grid) into the lists'
  // arrays as they are now (a backend that resizes them sets their pointers again).
  NeighbourBuildArgs build_args(const State& sorted, const std::int32_t* cell_start,
                                const std::int32_t* cell_end) {
    NeighbourBuildArgs b{};
    b.count = count_;
    b.grid = grid_;
    b.x = sorted.x.data();
    b.y = sorted.y.data();
    b.z = sorted.z.data();
    b.radius = variant_.polydisperse ? radius_.data() : nullptr;
    b.mono_radius = scene_args_.mono_radius;
    b.skin = sizes_.skin;
    b.cell_start = cell_start;
    b.cell_end = cell_end;
    b.id = id_.data();
    b.max_neighbours = max_neighbours_;
    b.slot_start = slot_start_.data();
    b.reverse_start = reverse_start_.data();
    b.neighbours = neighbours_.data();
    b.neighbour_count = neighbour_count_.data();
    b.partner_id = partner_id_.data();
    b.reverse = reverse_.data();
    b.reverse_count = reverse_count_.data();
    return b;
  }
  // The contact history carried from the lists before the build (`old`, in the order before
  // the sort, `old_index` new -> old) to `fresh`; nothing in scenes without history.
  void carry_history(NeighbourBuildArgs& b, const std::int32_t* old_index,
                     const std::int32_t* old_slot_start, const std::int32_t* old_partner_id,
                     const std::int32_t* old_neighbour_count, const History& old,
                     History& fresh) const {
    if (!variant_.history) return;
    b.old_index = old_index;
    b.old_slot_start = old_slot_start;
    b.old_partner_id = old_partner_id;
    b.old_neighbour_count = old_neighbour_count;
    b.old_mask = old.neighbour_mask.data();
    b.old_history = old.neighbour.data();
    b.new_mask = fresh.neighbour_mask.data();
    b.new_history = fresh.neighbour.data();
  }

  // After a step is accepted: the lists are rebuilt once the particles may have drifted half
  // the skin beyond the reach of a step's pairs.
  void track_drift(const StepTotals& totals) {
    if (lists_expired(travel_, totals.speed_sq, dt_, sizes_.skin - sizes_.reach))
      needs_rebuild_ = true;
  }

  // A checkpoint's grid and rebuild policy, as this engine holds them.
  void save_grid(EngineCheckpoint& c) const {
    c.grid = grid_;
    c.needs_rebuild = needs_rebuild_;
    c.max_neighbours = max_neighbours_;
    c.travel = travel_;
  }
  void restore_grid(const EngineCheckpoint& c) {
    grid_ = c.grid;
    needs_rebuild_ = c.needs_rebuild;
    max_neighbours_ = c.max_neighbours;
    travel_ = c.travel;
  }

  EngineConfig config_;
  VariantInfo variant_;
  EngineSizes sizes_;
  ParticleStepArgs scene_args_ = scene_step_args(config_);
  int count_ = 0, max_neighbours_ = 1;
  double dt_ = 0, travel_ = 0;  // last step size; drift bound since the last build (m)
  Grid grid_{};
  bool needs_rebuild_ = true;
  StepTotals totals_;
  State state_[2];
  History history_[2];
  Array<double> radius_, inv_mass_, inv_inertia_;
  // Particle i's forward list from slot_start_[i], its reverse list from reverse_start_[i].
  Array<std::int32_t> id_, neighbours_, partner_id_, neighbour_count_, reverse_, reverse_count_,
      slot_start_, reverse_start_;
  Array<std::uint32_t> incoming_;
  Array<double> mesh_triangle_;  // a mesh container's (place_mesh())
  Array<std::int32_t> mesh_key_, mesh_bin_start_, mesh_bin_triangle_, mesh_memo_;
  Array<double> mesh_memo_at_;
};

}  // namespace pdsim

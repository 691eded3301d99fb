// Uniform grid and Verlet neighbour lists with a skin, shared by both backends. Each pair is
// listed once, by its lower index (forward lists); reverse lists point back at those slots.
// Particles are reordered by cell at each rebuild (the backend sorts: counting sort on the CPU,
// radix sort on the GPU); the per-particle builds below are written once. Tangential history
// lives in the pair's forward slot and is carried over to the new lists by partner identity.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "kernels/dem_types.hpp"

namespace pdsim {

struct Grid {
  Vec3 origin;       // world position of the lower corner, m
  double cell_size;  // m, >= the largest contact reach (2 r_max + skin)
  int nx, ny, nz;
};

PDSIM_HD int clamp_cell(double coord, int n) {
  const int c = static_cast<int>(floor(coord));
  return c < 0 ? 0 : (c >= n ? n - 1 : c);
}

PDSIM_HD int cell_of(const Grid& g, Vec3 p) {
  const double inv = 1.0 / g.cell_size;
  const int cx = clamp_cell((p.x - g.origin.x) * inv, g.nx);
  const int cy = clamp_cell((p.y - g.origin.y) * inv, g.ny);
  const int cz = clamp_cell((p.z - g.origin.z) * inv, g.nz);
  return (cz * g.ny + cy) * g.nx + cx;
}

// Particles sorted by cell, on the host (the CPU engine's rebuild, the snapshots' contact
// counts; the GPU sorts by radix to the same order): a stable counting sort, so the order is
// reproducible. order[k] is the particle k-th in cell order; cell_start[c] is the first sorted
// index of cell c (one entry a cell and one past the last).
struct CellOrder {
  std::vector<std::int32_t> order, cell_start;
};
template <class Position>
CellOrder sort_by_cell(const Grid& g, std::size_t n, Position&& position) {
  CellOrder s;
  std::vector<std::int32_t> cell(n);
  s.cell_start.assign(static_cast<std::size_t>(g.nx) * g.ny * g.nz + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    cell[i] = cell_of(g, position(i));
    ++s.cell_start[static_cast<std::size_t>(cell[i]) + 1];
  }
  std::partial_sum(s.cell_start.begin(), s.cell_start.end(), s.cell_start.begin());
  std::vector<std::int32_t> fill(s.cell_start.begin(), s.cell_start.end() - 1);
  s.order.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    s.order[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell[i])]++)] =
        static_cast<std::int32_t>(i);
  return s;
}

// Host-side choices both backends share (checkpoints carry their results, so they must agree).

// Verlet skin: 0.3 r_min unless the scene sets one.
inline double default_skin(double r_min, double configured) {
  return configured > 0 ? configured : 0.3 * r_min;
}

// Longest list (and the GPU's slots per particle): the densest packing (0.7405) of the
// smallest spheres in a ball of radius reach + r_min, capped at the 64 bits of the slot masks.
inline int neighbour_slots(double r_min, double r_max, double skin) {
  const double reach = 2 * r_max + skin + r_min;
  const int bound = static_cast<int>(ceil(0.7405 * pow(reach / r_min, 3)));
  // A multiple of kSlotGroup, so that padded lists fit (64 is the width of the slot masks).
  const int rounded = (bound + kSlotGroup - 1) / kSlotGroup * kSlotGroup;
  return rounded < kSlotGroup ? kSlotGroup : (rounded > 64 ? 64 : rounded);
}

// Verlet criterion. A particle moves dt |v_{n+1}| in a step, so the sum over the steps since
// the last build of dt times the step's largest speed bounds every particle's drift (no build
// positions to store or compare); the lists stay valid while it is under half the skin. Adds
// the step to `travel` and says whether the lists must be rebuilt.
inline bool lists_expired(double& travel, double speed_sq, double dt, double skin) {
  travel += dt * sqrt(speed_sq);
  return travel > 0.5 * skin;
}

// The most cells a grid of `particles` spans: 8 a particle, and at least 2^20 (a few MiB).
inline double grid_cells_for(std::size_t particles) {
  return std::max(double(1 << 20), 8.0 * double(particles));
}

// Grid around the container at `centre`, one cell of margin on every side, its cells `reach`
// wide, or wider where that would make more than `max_cells` (grid_cells_for()): a container
// far wider than its particles (a 1 m box of 0.5 mm spheres, 5e9 cells) gets wide cells, not
// gigabytes of empty ones. Partners lie in adjacent cells at any width >= reach, so only the
// cost of a build changes; a grid within the bound is the plain one.
inline Grid grid_around(Vec3 centre, Vec3 half_size, double reach, double max_cells) {
  Grid g;
  double cell = reach;
  for (;;) {
    g.nx = static_cast<int>(ceil(2 * (half_size.x + cell) / cell));
    g.ny = static_cast<int>(ceil(2 * (half_size.y + cell) / cell));
    g.nz = static_cast<int>(ceil(2 * (half_size.z + cell) / cell));
    const double cells = double(g.nx) * g.ny * g.nz;
    if (!(cells > max_cells)) break;  // NaN sizes too: never a loop without end
    cell *= 1.01 * cbrt(cells / max_cells);
  }
  g.origin = centre - half_size - Vec3{cell, cell, cell};
  g.cell_size = cell;
  return g;
}

struct NeighbourBuildArgs {
  int count;
  Grid grid;
  const double *x, *y, *z;  // sorted by cell
  const double* radius;     // polydisperse, else nullptr
  double mono_radius;
  double skin;                     // m
  const std::int32_t* cell_start;  // first sorted index of each cell
  const std::int32_t* cell_end;    // one past the last
  int max_neighbours;              // longest list allowed (<= 64, a multiple of kSlotGroup)
  // Particle i's forward list starts at slot_start[i], its reverse list at reverse_start[i]:
  // i * max_neighbours on the GPU; on the CPU a compact layout the lists are counted for first.
  const std::int32_t* slot_start;
  const std::int32_t* reverse_start;
  std::int32_t* neighbours;       // out, nullptr to count only (into neighbour_count)
  std::int32_t* neighbour_count;  // out
  std::int32_t* partner_id;       // out: identity of each listed partner
  std::int32_t* reverse;          // out: reverse_entry()s, nullptr to count only
  std::int32_t* reverse_count;    // out
  const std::int32_t* id;         // identity of each particle in the new order
  // History carried over (nullptr when the scene has no tangential history).
  const std::int32_t* old_index;  // new index -> index before the reorder
  const std::int32_t* old_slot_start;
  const std::int32_t* old_partner_id;
  const std::int32_t* old_neighbour_count;
  const std::uint64_t* old_mask;
  const double* old_history;
  std::uint64_t* new_mask;
  double* new_history;
};

// A list of `count` entries padded with `self` to the next multiple of kSlotGroup, so that
// slot tests may read whole groups (the padding is masked off).
PDSIM_HD int padded(int count) {
  return (count + kSlotGroup - 1) / kSlotGroup * kSlotGroup;
}
PDSIM_HD void pad_slots(std::int32_t* list, int count, int self) {
  for (int k = count; k < padded(count); ++k) list[k] = self;
}

// Calls f(j) for every particle j in [lo, hi) in the 27 cells around position p, in a fixed
// order (so the lists do not depend on threads). Particles are sorted by cell, so the range
// empties the cells on the other side of a particle's own cell before any distance test.
template <class F>
PDSIM_HD void for_each_nearby(const Grid& g, Vec3 p, const std::int32_t* cell_start,
                              const std::int32_t* cell_end, int lo, int hi, F&& f) {
  const double inv = 1.0 / g.cell_size;
  const int cx = clamp_cell((p.x - g.origin.x) * inv, g.nx);
  const int cy = clamp_cell((p.y - g.origin.y) * inv, g.ny);
  const int cz = clamp_cell((p.z - g.origin.z) * inv, g.nz);
  for (int z = cz > 0 ? cz - 1 : 0; z <= cz + 1 && z < g.nz; ++z)
    for (int y = cy > 0 ? cy - 1 : 0; y <= cy + 1 && y < g.ny; ++y)
      for (int x = cx > 0 ? cx - 1 : 0; x <= cx + 1 && x < g.nx; ++x) {
        const int cell = (z * g.ny + y) * g.nx + x;
        const int first = cell_start[cell] > lo ? cell_start[cell] : lo;
        const int last = cell_end[cell] < hi ? cell_end[cell] : hi;
        for (int j = first; j < last; ++j) f(j);
      }
}

// Slot of `partner` among the first `count` entries of a list, or -1.
PDSIM_HD int find_slot(const std::int32_t* list, int count, std::int32_t partner) {
  for (int k = 0; k < count; ++k)
    if (list[k] == partner) return k;
  return -1;
}

// Forward list of particle i: every particle of higher index within reach + skin, so that each
// pair is listed once, written from slot_start[i] (or only counted). Returns false on list
// overflow.
PDSIM_HD bool build_neighbours_of(int i, const NeighbourBuildArgs& a) {
  const Vec3 p{a.x[i], a.y[i], a.z[i]};
  const double ri = a.radius ? a.radius[i] : a.mono_radius;
  std::int32_t* list = a.neighbours ? a.neighbours + a.slot_start[i] : nullptr;
  std::int32_t* partner = a.neighbours ? a.partner_id + a.slot_start[i] : nullptr;
  int n = 0;
  bool fits = true;
  for_each_nearby(a.grid, p, a.cell_start, a.cell_end, i + 1, a.count, [&](int j) {
    const Vec3 d{p.x - a.x[j], p.y - a.y[j], p.z - a.z[j]};
    const double reach = ri + (a.radius ? a.radius[j] : a.mono_radius) + a.skin;
    if (dot(d, d) >= reach * reach) return;
    if (n == a.max_neighbours) {
      fits = false;
      return;
    }
    if (list) {
      list[n] = j;
      partner[n] = a.id[j];
    }
    ++n;
  });
  a.neighbour_count[i] = n;
  if (!list) return fits;
  pad_slots(list, n, i);
  if (a.new_mask) {
    // Carry the tangential history of contacts that survive the rebuild. A pair's history
    // lives with its owner (the lower index); when the owners swap, it changes sign.
    auto live_slot = [&](int old_owner, std::int32_t partner_id) {  // flat old slot, or -1
      const int start = a.old_slot_start[old_owner];
      const int m =
          find_slot(a.old_partner_id + start, a.old_neighbour_count[old_owner], partner_id);
      return m >= 0 && (a.old_mask[old_owner] >> m & 1u) ? start + m : -1;
    };
    std::uint64_t mask = 0;
    for (int k = 0; k < n; ++k) {
      double sign = 1;
      int from = live_slot(a.old_index[i], partner[k]);
      if (from < 0) {
        sign = -1;
        from = live_slot(a.old_index[list[k]], a.id[i]);
      }
      if (from < 0) continue;
      for (int c = 0; c < 3; ++c)
        a.new_history[3 * (std::int64_t{a.slot_start[i]} + k) + c] =
            sign * a.old_history[3 * std::int64_t{from} + c];
      mask |= std::uint64_t{1} << k;
    }
    a.new_mask[i] = mask;
  }
  return fits;
}

// Reverse list of particle j, after every forward list is built: the forward slots of the
// particles that list j (reverse_entry()s), in a fixed order, written from reverse_start[j] (or
// only counted). Returns false on list overflow.
PDSIM_HD bool build_reverse_of(int j, const NeighbourBuildArgs& a) {
  int n = 0;
  bool fits = true;
  for_each_nearby(a.grid, {a.x[j], a.y[j], a.z[j]}, a.cell_start, a.cell_end, 0, j, [&](int i) {
    const int k = find_slot(a.neighbours + a.slot_start[i], a.neighbour_count[i], j);
    if (k < 0) return;
    if (n == a.max_neighbours) {
      fits = false;
      return;
    }
    if (a.reverse) a.reverse[a.reverse_start[j] + n] = reverse_entry(i, k);
    ++n;
  });
  a.reverse_count[j] = n;
  return fits;
}

// All reverse lists at once from the forward lists (host): one sweep over the owners in
// ascending order, the order build_reverse_of() finds them in (it visits cells in index order,
// and particles are sorted by cell), so both give the same lists, without a neighbour search or
// a list scan per candidate. Only counts while a.reverse is nullptr. Returns false on overflow.
inline bool build_reverse_lists(const NeighbourBuildArgs& a) {
  std::fill_n(a.reverse_count, a.count, 0);
  bool fits = true;
  for (int i = 0; i < a.count; ++i)
    for (int k = 0; k < a.neighbour_count[i]; ++k) {
      const int j = a.neighbours[a.slot_start[i] + k];
      const int n = a.reverse_count[j];
      if (n == a.max_neighbours) {  // capped, as in build_reverse_of()
        fits = false;
        continue;
      }
      if (a.reverse) a.reverse[a.reverse_start[j] + n] = reverse_entry(i, k);
      a.reverse_count[j] = n + 1;
    }
  return fits;
}

}  // namespace pdsim

// Uniform grid and Verlet neighbour lists with a skin, shared by both backends. Particles are
// reordered by cell at each rebuild (the backend sorts: counting sort on the CPU, radix sort on
// the GPU); the per-particle gather below is written once. Tangential history lives in the slot
// of the neighbour list entry and is carried over to the new list by partner identity.
#pragma once

#include <cstdint>

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

// Host-side choices both backends share (checkpoints carry their results, so they must agree).

// Verlet skin: 0.3 r_min unless the scene sets one.
inline double default_skin(double r_min, double configured) {
  return configured > 0 ? configured : 0.3 * r_min;
}

// Slots per particle: the densest packing (0.7405) of the smallest spheres in a ball of radius
// reach + r_min, capped at the 64 bits of the history mask.
inline int neighbour_slots(double r_min, double r_max, double skin) {
  const double reach = 2 * r_max + skin + r_min;
  const int bound = static_cast<int>(ceil(0.7405 * pow(reach / r_min, 3)));
  // A multiple of kSlotGroup, so that padded lists fit (64 is the width of the slot masks).
  const int rounded = (bound + kSlotGroup - 1) / kSlotGroup * kSlotGroup;
  return rounded < kSlotGroup ? kSlotGroup : (rounded > 64 ? 64 : rounded);
}

// Grid around the container at `centre`, one cell of margin on every side.
inline Grid grid_around(Vec3 centre, Vec3 half_size, double cell) {
  Grid g;
  g.origin = centre - half_size - Vec3{cell, cell, cell};
  g.cell_size = cell;
  g.nx = static_cast<int>(ceil(2 * (half_size.x + cell) / cell));
  g.ny = static_cast<int>(ceil(2 * (half_size.y + cell) / cell));
  g.nz = static_cast<int>(ceil(2 * (half_size.z + cell) / cell));
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
  int max_neighbours;
  std::int32_t* neighbours;       // out: count x max_neighbours
  std::int32_t* neighbour_count;  // out
  std::int32_t* partner_id;       // out: identity of each listed partner
  const std::int32_t* id;         // identity of each particle in the new order
  // History carried over (nullptr when the scene has no tangential history).
  const std::int32_t* old_index;  // new index -> index before the reorder
  const std::int32_t* old_partner_id;
  const std::int32_t* old_neighbour_count;
  const std::uint64_t* old_mask;
  const double* old_history;
  std::uint64_t* new_mask;
  double* new_history;
};

// Fills the list of particle i from `count` up to the next multiple of kSlotGroup with i
// itself, so that slot tests may read whole groups (the padding is masked off).
PDSIM_HD void pad_slots(int i, int count, int max_neighbours, std::int32_t* neighbours) {
  for (int k = count; k % kSlotGroup != 0 && k < max_neighbours; ++k)
    neighbours[i * max_neighbours + k] = i;
}

// Lists every particle within reach + skin of particle i (scanning the 27 cells in a fixed
// order, so the list does not depend on threads); returns false on list overflow.
PDSIM_HD bool build_neighbours_of(int i, const NeighbourBuildArgs& a) {
  const Vec3 p{a.x[i], a.y[i], a.z[i]};
  const double ri = a.radius ? a.radius[i] : a.mono_radius;
  const double inv = 1.0 / a.grid.cell_size;
  const int cx = clamp_cell((p.x - a.grid.origin.x) * inv, a.grid.nx);
  const int cy = clamp_cell((p.y - a.grid.origin.y) * inv, a.grid.ny);
  const int cz = clamp_cell((p.z - a.grid.origin.z) * inv, a.grid.nz);
  const int base = i * a.max_neighbours;
  int n = 0;
  bool fits = true;
  for (int dz = -1; dz <= 1; ++dz) {
    const int z = cz + dz;
    if (z < 0 || z >= a.grid.nz) continue;
    for (int dy = -1; dy <= 1; ++dy) {
      const int y = cy + dy;
      if (y < 0 || y >= a.grid.ny) continue;
      for (int dx = -1; dx <= 1; ++dx) {
        const int xcell = cx + dx;
        if (xcell < 0 || xcell >= a.grid.nx) continue;
        const int cell = (z * a.grid.ny + y) * a.grid.nx + xcell;
        for (int j = a.cell_start[cell]; j < a.cell_end[cell]; ++j) {
          if (j == i) continue;
          const Vec3 d{p.x - a.x[j], p.y - a.y[j], p.z - a.z[j]};
          const double reach = ri + (a.radius ? a.radius[j] : a.mono_radius) + a.skin;
          if (dot(d, d) >= reach * reach) continue;
          if (n == a.max_neighbours) {
            fits = false;
            continue;
          }
          a.neighbours[base + n] = j;
          a.partner_id[base + n] = a.id[j];
          ++n;
        }
      }
    }
  }
  a.neighbour_count[i] = n;
  pad_slots(i, n, a.max_neighbours, a.neighbours);
  if (a.new_mask) {
    // Carry the tangential history of contacts that survive the rebuild.
    const int old_i = a.old_index[i];
    const int old_base = old_i * a.max_neighbours;
    const std::uint64_t old_mask = a.old_mask[old_i];
    std::uint64_t mask = 0;
    for (int k = 0; k < n; ++k) {
      const std::int32_t partner = a.partner_id[base + k];
      for (int m = 0; m < a.old_neighbour_count[old_i]; ++m) {
        if (!(old_mask >> m & 1u) || a.old_partner_id[old_base + m] != partner) continue;
        for (int c = 0; c < 3; ++c)
          a.new_history[3 * (base + k) + c] = a.old_history[3 * (old_base + m) + c];
        mask |= std::uint64_t{1} << k;
        break;
      }
    }
    a.new_mask[i] = mask;
  }
  return fits;
}

}  // namespace pdsim

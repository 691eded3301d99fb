// Each particle's contacts in a state, from the positions alone: the partners it overlaps and
// the container walls it touches. These are the contacts the engine computes at that state
// (overlap > 0; a wall's gap below the radius), counted for snapshots, not in the hot loop.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "kernels/neighbours.hpp"
#include "kernels/shapes.hpp"

namespace pdsim {

inline std::vector<std::int32_t> contact_counts(const std::vector<Vec3>& centre,
                                                const std::vector<double>& radius, WallShape shape,
                                                const ContainerGeometry& g,
                                                const ContainerKinematics& container) {
  const int n = static_cast<int>(centre.size());
  std::vector<std::int32_t> count(centre.size(), 0);
  if (n == 0) return count;
  // Pairs: particles sorted by cell (cells 2 r_max wide, so partners are in adjacent cells),
  // each pair tested once, from its lower sorted index.
  const double r_max = *std::max_element(radius.begin(), radius.end());
  const Orientation axes{container.axis_x, container.axis_y, container.axis_z};
  const Grid grid = grid_around(container.position, world_half_size(g.half_size, axes), 2 * r_max,
                                grid_cells_for(centre.size()));
  const CellOrder sorted =
      sort_by_cell(grid, centre.size(), [&](std::size_t i) { return centre[i]; });
  const std::vector<std::int32_t>& order = sorted.order;
  const std::vector<std::int32_t>& start = sorted.cell_start;
  for (int a = 0; a < n; ++a) {
    const int i = order[a];
    for_each_nearby(grid, centre[i], start.data(), start.data() + 1, a + 1, n, [&](int b) {
      const int j = order[b];
      const Vec3 d = centre[i] - centre[j];
      const double reach = radius[i] + radius[j];
      if (dot(d, d) < reach * reach) ++count[i], ++count[j];
    });
  }
  // Walls, in the container's frame, as the step kernels find them (a mesh's from bins of
  // its own: an engine's live on its backend).
  ContainerGeometry walls = g;
  std::shared_ptr<const MeshBins> bins;
  if (shape == WallShape::mesh) {
    bins = mesh_bins(*g.surface, r_max);
    walls.mesh = mesh_view(*g.surface, *bins);
  }
  with_shape(shape, [&](auto shape_type) {
    using S = decltype(shape_type);
    for (int i = 0; i < n; ++i) {
      const Vec3 offset = centre[i] - container.position;
      const Vec3 local{dot(offset, container.axis_x), dot(offset, container.axis_y),
                       dot(offset, container.axis_z)};
      const double r = radius[i];
      S::walls(
          local, r, walls, [&](int, double gap, Vec3) { count[i] += gap < r ? 1 : 0; },
          [](double) {});
    }
  });
  return count;
}

}  // namespace pdsim

// Neighbour lists (kernels/neighbours.hpp): each pair within reach + skin listed exactly once,
// by its lower index, reverse lists that point back at those slots, and tangential history
// carried across a rebuild, with its sign flipped when the pair's owner changes.
#include "kernels/neighbours.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

namespace pdsim {
namespace {

// Particles sorted by grid cell (the order the engines give the builders) and the lists built
// from them. `radius` empty: every particle has `mono_radius`.
struct Cloud {
  Grid grid;
  std::vector<double> x, y, z, radius;
  double mono_radius = 0, skin = 0;
  std::vector<std::int32_t> cell_start, cell_end, id;
  int max = 0;  // slots per list
  std::vector<std::int32_t> neighbours, count, partner, reverse, reverse_count, start;

  // Builder arguments over these particles, with empty lists to fill (no history carried), in
  // the GPU's layout: `max` slots per particle.
  NeighbourBuildArgs args() {
    const std::size_t n = x.size(), slots = n * static_cast<std::size_t>(max);
    neighbours.assign(slots, -1), partner.assign(slots, -1), reverse.assign(slots, -1);
    count.assign(n, 0), reverse_count.assign(n, 0), start.assign(n + 1, 0);
    for (std::size_t i = 0; i <= n; ++i) start[i] = static_cast<std::int32_t>(i) * max;
    NeighbourBuildArgs b{};
    b.count = static_cast<int>(n);
    b.grid = grid;
    b.x = x.data(), b.y = y.data(), b.z = z.data();
    b.radius = radius.empty() ? nullptr : radius.data();
    b.mono_radius = mono_radius;
    b.skin = skin;
    b.cell_start = cell_start.data();
    b.cell_end = cell_end.data();
    b.id = id.data();
    b.max_neighbours = max;
    b.slot_start = start.data();
    b.reverse_start = start.data();
    b.neighbours = neighbours.data();
    b.neighbour_count = count.data();
    b.partner_id = partner.data();
    b.reverse = reverse.data();
    b.reverse_count = reverse_count.data();
    return b;
  }
};

// `max_cells`: the grid's bound (grid_around()), 0 for the engines' (grid_cells_for()).
Cloud sorted_cloud(int count, double half, double r_max, double skin, double max_cells = 0) {
  std::uint64_t seed = 2024;
  auto uniform = [&seed] {  // a fixed linear congruential sequence in [0, 1)
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(seed >> 11) * 0x1.0p-53;
  };
  std::vector<Vec3> p(static_cast<std::size_t>(count));
  std::vector<double> r(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    p[i] = {half * (2 * uniform() - 1), half * (2 * uniform() - 1), half * (2 * uniform() - 1)};
    r[i] = r_max * (0.5 + 0.5 * uniform());
  }
  Cloud c;
  c.skin = skin;
  c.grid = grid_around({0, 0, 0}, {half, half, half}, 2 * r_max + skin,
                       max_cells > 0 ? max_cells : grid_cells_for(p.size()));
  const int cells = c.grid.nx * c.grid.ny * c.grid.nz;
  std::vector<std::int32_t> order(p.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return cell_of(c.grid, p[static_cast<std::size_t>(a)]) <
           cell_of(c.grid, p[static_cast<std::size_t>(b)]);
  });
  c.cell_start.assign(static_cast<std::size_t>(cells), 0);
  c.cell_end.assign(static_cast<std::size_t>(cells), 0);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Vec3 q = p[static_cast<std::size_t>(order[i])];
    c.x.push_back(q.x), c.y.push_back(q.y), c.z.push_back(q.z);
    c.radius.push_back(r[static_cast<std::size_t>(order[i])]);
    c.id.push_back(order[i]);
    const auto cell = static_cast<std::size_t>(cell_of(c.grid, q));
    if (c.cell_end[cell] == 0) c.cell_start[cell] = static_cast<std::int32_t>(i);
    c.cell_end[cell] = static_cast<std::int32_t>(i + 1);
  }
  return c;
}

// The grid as the engines size it (9 cells a side), and one capped at 27 cells, whose cells
// are then wider than the reach (a container far wider than its particles): the same pairs.
TEST_CASE("forward lists hold each close pair once, and reverse lists point back at its slot") {
  for (const double max_cells : {0.0, 27.0}) {
    CAPTURE(max_cells);
    constexpr int kCount = 400, kMax = 32;
    const double r_max = 0.0025, skin = 0.3 * r_max;
    Cloud c = sorted_cloud(kCount, 0.02, r_max, skin, max_cells);
    if (max_cells > 0) {
      CHECK(c.grid.nx * c.grid.ny * c.grid.nz <= max_cells);
      CHECK(c.grid.cell_size > 2 * (2 * r_max + skin));
    } else {
      CHECK(c.grid.cell_size == 2 * r_max + skin);
    }
    c.max = kMax;
    const NeighbourBuildArgs b = c.args();
    const std::vector<std::int32_t>&neighbours = c.neighbours, &count = c.count,
          &partner = c.partner, &reverse = c.reverse, &reverse_count = c.reverse_count;
    for (int i = 0; i < kCount; ++i) REQUIRE(build_neighbours_of(i, b));
    for (int i = 0; i < kCount; ++i) REQUIRE(build_reverse_of(i, b));

    // Brute force over all pairs, with distances from hypot().
    int pairs = 0;
    for (int i = 0; i < kCount; ++i) {
      const std::int32_t* list = neighbours.data() + i * kMax;
      for (int j = 0; j < kCount; ++j) {
        if (j == i) continue;
        const double d = std::hypot(c.x[i] - c.x[j], c.y[i] - c.y[j], c.z[i] - c.z[j]);
        const bool close = d < c.radius[i] + c.radius[j] + skin;
        const auto listed = std::count(list, list + count[i], j);
        CHECK(listed == (close && j > i ? 1 : 0));
        pairs += close && j > i;
      }
      for (int k = count[i]; k % kSlotGroup != 0; ++k) CHECK(list[k] == i);  // padding
      for (int k = 0; k < count[i]; ++k) CHECK(partner[i * kMax + k] == c.id[list[k]]);
    }
    CHECK(pairs > kCount);  // dense enough to mean something

    // Every forward slot appears in its partner's reverse list, once, and nothing else does.
    int reverse_entries = 0;
    for (int j = 0; j < kCount; ++j) {
      for (int r = 0; r < reverse_count[j]; ++r) {
        const int owner = entry_owner(reverse[j * kMax + r]),
                  k = entry_place(reverse[j * kMax + r]);
        CHECK(owner < j);
        CHECK(k < count[owner]);
        CHECK(neighbours[owner * kMax + k] == j);
      }
      reverse_entries += reverse_count[j];
    }
    CHECK(reverse_entries == pairs);
  }
}

TEST_CASE("lists counted first and written compactly equal the fixed-stride lists") {
  // The CPU engine's layout: each list starts where the previous (padded) one ends.
  constexpr int kCount = 300, kMax = 32;
  Cloud c = sorted_cloud(kCount, 0.02, 0.0025, 0.00075);
  c.max = kMax;
  const NeighbourBuildArgs strided = c.args();
  for (int i = 0; i < kCount; ++i) REQUIRE(build_neighbours_of(i, strided));
  for (int i = 0; i < kCount; ++i) REQUIRE(build_reverse_of(i, strided));

  std::vector<std::int32_t> count(kCount), reverse_count(kCount), start(kCount + 1, 0),
      reverse_start(kCount + 1, 0);
  NeighbourBuildArgs b = strided;
  b.neighbours = nullptr, b.reverse = nullptr;
  b.neighbour_count = count.data(), b.reverse_count = reverse_count.data();
  b.slot_start = start.data(), b.reverse_start = reverse_start.data();
  for (int i = 0; i < kCount; ++i) REQUIRE(build_neighbours_of(i, b));  // counts only
  for (int i = 0; i < kCount; ++i) start[i + 1] = start[i] + padded(count[i]);
  std::vector<std::int32_t> neighbours(static_cast<std::size_t>(start[kCount]), -1),
      partner(neighbours.size(), -1);
  b.neighbours = neighbours.data(), b.partner_id = partner.data();
  for (int i = 0; i < kCount; ++i) REQUIRE(build_neighbours_of(i, b));
  // The reverse lists from the forward ones in one sweep, as the CPU engine builds them.
  REQUIRE(build_reverse_lists(b));  // counts only
  for (int i = 0; i < kCount; ++i) reverse_start[i + 1] = reverse_start[i] + reverse_count[i];
  std::vector<std::int32_t> reverse(static_cast<std::size_t>(reverse_start[kCount]), -1);
  b.reverse = reverse.data();
  REQUIRE(build_reverse_lists(b));

  CHECK(count == c.count);
  CHECK(reverse_count == c.reverse_count);
  CHECK(start[kCount] < kCount * kMax / 4);  // compact: far fewer slots than the bound
  for (int i = 0; i < kCount; ++i) {
    CAPTURE(i);
    for (int k = 0; k < padded(count[i]); ++k)
      CHECK(neighbours[start[i] + k] == c.neighbours[i * kMax + k]);
    for (int k = 0; k < count[i]; ++k) CHECK(partner[start[i] + k] == c.partner[i * kMax + k]);
    for (int r = 0; r < reverse_count[i]; ++r)
      CHECK(reverse[reverse_start[i] + r] == c.reverse[i * kMax + r]);
  }
}

TEST_CASE("reverse lists swept in one pass stop at the slot limit as the per-particle build does") {
  constexpr int kCount = 300, kMax = 32, kCap = 2;
  Cloud c = sorted_cloud(kCount, 0.02, 0.0025, 0.00075);
  c.max = kMax;
  NeighbourBuildArgs b = c.args();
  for (int i = 0; i < kCount; ++i) REQUIRE(build_neighbours_of(i, b));
  // Reverse lists of at most kCap slots, in their own arrays, from each builder.
  b.max_neighbours = kCap;
  std::vector<std::int32_t> start(kCount + 1), swept(kCount * kCap, -1), swept_count(kCount),
      each(kCount * kCap, -1), each_count(kCount);
  for (int i = 0; i <= kCount; ++i) start[i] = i * kCap;
  b.reverse_start = start.data();
  b.reverse = swept.data(), b.reverse_count = swept_count.data();
  CHECK_FALSE(build_reverse_lists(b));
  b.reverse = each.data(), b.reverse_count = each_count.data();
  bool fits = true;
  for (int j = 0; j < kCount; ++j) fits &= build_reverse_of(j, b);
  CHECK_FALSE(fits);
  CHECK(*std::max_element(swept_count.begin(), swept_count.end()) == kCap);
  CHECK(swept_count == each_count);
  CHECK(swept == each);
}

// Two particles that stay in contact across a rebuild. `swap`: the cell sort exchanges them, so
// that the pair's owner (the lower index) changes.
std::vector<double> carried_history(bool swap, bool live) {
  constexpr int kMax = 4;
  const Vec3 h{1e-7, -2e-7, 3e-7};
  const std::int32_t ids[2] = {7, 9};  // the old order: old index 0 owns the pair
  std::vector<std::int32_t> old_partner = {9, 0, 0, 0, -1, -1, -1, -1}, old_count = {1, 0};
  std::vector<std::uint64_t> old_mask = {live ? 1u : 0u, 0}, new_mask(2, 0);
  std::vector<double> old_history(3 * 2 * kMax, 0.0), new_history(3 * 2 * kMax, 0.0);
  old_history[0] = h.x, old_history[1] = h.y, old_history[2] = h.z;
  std::vector<std::int32_t> old_index = {0, 1}, id = {ids[0], ids[1]};
  if (swap) old_index = {1, 0}, id = {ids[1], ids[0]};
  Cloud c;  // two spheres 0.1 mm apart, in one cell
  c.grid = {{-1, -1, -1}, 2.0, 1, 1, 1};
  c.x = {0.0, 0.0049}, c.y = {0, 0}, c.z = {0, 0};
  c.mono_radius = 0.0025;
  c.skin = 0.001;
  c.cell_start = {0}, c.cell_end = {2};
  c.id = id;
  c.max = kMax;
  NeighbourBuildArgs b = c.args();
  b.old_index = old_index.data();
  b.old_slot_start = c.start.data();
  b.old_partner_id = old_partner.data();
  b.old_neighbour_count = old_count.data();
  b.old_mask = old_mask.data();
  b.old_history = old_history.data();
  b.new_mask = new_mask.data();
  b.new_history = new_history.data();
  for (int i = 0; i < 2; ++i) REQUIRE(build_neighbours_of(i, b));
  REQUIRE(c.count[0] == 1);
  REQUIRE(c.count[1] == 0);
  CHECK(new_mask[0] == (live ? 1u : 0u));
  CHECK(new_mask[1] == 0u);
  return {new_history[0], new_history[1], new_history[2]};
}

TEST_CASE("tangential history survives a rebuild, with its sign flipped when the owner swaps") {
  // The stored displacement is the owner's (xi_j = -xi_i for the partner), so a swap negates it.
  const std::vector<double> same = carried_history(false, true);
  const std::vector<double> swapped = carried_history(true, true);
  CHECK(same == std::vector<double>{1e-7, -2e-7, 3e-7});
  CHECK(swapped == std::vector<double>{-1e-7, 2e-7, -3e-7});
  // A slot whose contact had ended carries nothing.
  CHECK(carried_history(true, false) == std::vector<double>{0, 0, 0});
}

}  // namespace
}  // namespace pdsim

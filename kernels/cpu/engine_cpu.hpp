// OpenMP backend: launches the shared per-particle functions over particle blocks. Totals are
// reduced per fixed block of particles and then summed in block order, so results are bitwise
// identical for any thread count. Included only by the CMake-generated translation units of
// engine_cpu_variants.cpp.in, each of which instantiates a share of the variants.
#pragma once

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <numeric>

#include "kernels/neighbours.hpp"
#include "kernels/variant_dispatch.hpp"

namespace pdsim {
namespace cpu_engine {

constexpr int kBlock = 256;  // particles per reduction block (independent of thread count)
// Contact batches are padded to whole vector iterations, so that their loops never run a scalar
// remainder. GCC sizes an iteration by the loop's narrowest type: 32-bit entries in 256-bit
// vectors (CMakeLists.txt) make 8. A byte-wide entry had made it 64 with AVX-512, and blocks
// with fewer contacts ran all scalar.
constexpr int kLanes = 8;

// `n` entries rounded up to whole SIMD vectors.
constexpr int padded_lanes(int n) {
  return (n + kLanes - 1) / kLanes * kLanes;
}

struct StateBuffer {
  std::vector<double> x, y, z, vx, vy, vz, wx, wy, wz;
  std::vector<double>* all[9] = {&x, &y, &z, &vx, &vy, &vz, &wx, &wy, &wz};
  void resize(std::size_t n) {
    for (auto* a : all) a->assign(n, 0.0);
  }
  ParticleArrays view() {
    return {x.data(),  y.data(),  z.data(),  vx.data(), vy.data(),
            vz.data(), wx.data(), wy.data(), wz.data()};
  }
};

struct HistoryBuffer {
  std::vector<double> neighbour, wall;
  std::vector<std::uint64_t> neighbour_mask;
  std::vector<std::uint8_t> wall_mask;
};

// a[i] = a[order[i]] (stride entries per particle) through `scratch`, which swaps with a. A
// scratch that lives on (the other history buffer) spares the page faults of a fresh large
// one at each rebuild: 0.7 ms of a 0.9 ms sort for the wall history of 8,000 spheres.
template <class T>
void permute(std::vector<T>& a, const std::vector<std::int32_t>& order, std::size_t stride,
             std::vector<T>& scratch) {
  if (a.empty()) return;
  scratch.resize(a.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(order[i] * stride), stride,
                scratch.begin() + static_cast<std::ptrdiff_t>(i * stride));
  a.swap(scratch);
}
template <class T>
void permute(std::vector<T>& a, const std::vector<std::int32_t>& order) {
  std::vector<T> scratch;
  permute(a, order, 1, scratch);
}

// A block's contacts, listed by scalar loops and then computed in SIMD lanes: the contact laws
// (roots, divisions, the friction cone) are the bulk of a step, and one contact at a time they
// are chains of dependent long-latency instructions. Entries are in particle and slot order.
struct ContactBatch {
  // Pairs: owner and forward slot. Walls: particle and wall-history slot (kWallSlots each).
  std::vector<std::int32_t> particle, slot;
  std::vector<std::int32_t> had;       // the slot holds history (32 bits: see kLanes)
  std::vector<double> xi[3];           // tangential history, in and then out
  std::vector<double> gap, normal[3];  // walls
  // Loads: force and torque on the particle (owner), then the torque on a pair's partner.
  std::vector<double> load[9];
  void resize(std::size_t pairs, std::size_t walls) {
    pairs += kLanes, walls += kLanes;  // room for the padding
    const std::size_t n = std::max(pairs, walls);
    for (auto* v : {&particle, &slot, &had}) v->resize(n);
    for (auto& v : xi) v.resize(n);
    for (auto& v : load) v.resize(n);
    for (auto* v : {&gap, &normal[0], &normal[1], &normal[2]}) v->resize(walls);
  }
  std::size_t bytes() const {
    return particle.size() * (3 * sizeof(std::int32_t) + 12 * sizeof(double)) +
           gap.size() * 4 * sizeof(double);
  }
  // A pair entry's loads; the partner's torque is stored only when it may differ (as in
  // pair_doubles()).
  template <class V>
  ContactOutcome loads(int e) const {
    const int partner = pair_doubles<V>() == 9 ? 6 : 3;
    return {{load[0][e], load[1][e], load[2][e]},
            {load[3][e], load[4][e], load[5][e]},
            {load[partner][e], load[partner + 1][e], load[partner + 2][e]}};
  }
  // Reads the history of entries [0, n) from `history` (3 doubles per slot), pads the entries
  // to padded_lanes(n) with copies of entry n - 1 (walls also its gap and normal): computing
  // a contact again gives the same loads and history. Returns the padded count. The history
  // goes through the batch so that it can be updated in place: a padding entry must not read
  // its slot after entry n - 1 has rewritten it.
  int gather(int n, const double* history, bool walls) {
    if (history) {
#pragma omp simd
      for (int e = 0; e < n; ++e) {
        const Vec3 h = slot_history(history, slot[e], had[e] != 0);
        xi[0][e] = h.x, xi[1][e] = h.y, xi[2][e] = h.z;
      }
    }
    const int end = padded_lanes(n);
    for (int e = n; e < end; ++e) {
      particle[e] = particle[n - 1], slot[e] = slot[n - 1];
      for (auto& v : xi) v[e] = v[n - 1];
      if (walls)
        for (auto* v : {&gap, &normal[0], &normal[1], &normal[2]}) (*v)[e] = (*v)[n - 1];
    }
    return end;
  }
  // Writes the new history of entries [0, n) back to `history`.
  void scatter(int n, double* history) const {
    for (int e = 0; e < n; ++e) store3(history, slot[e], {xi[0][e], xi[1][e], xi[2][e]});
  }
};

// The contact laws of a batch's first `pairs` pair entries, in SIMD lanes, over the padded
// entries (the padding's dissipation is not counted); their loads go to batch.load.
// Flattened: the laws vectorise only when inlined, which GCC's own heuristics did for some
// variants and not others.
template <class V>
[[gnu::flatten]] void pair_contacts_simd(int pairs, ContactBatch& batch,
                                         const ParticleStepArgs& shared, StepTotals& total) {
  if (pairs == 0) return;
  constexpr bool history = V::Tangential::kHistory;
  const int end = batch.gather(pairs, history ? shared.history.neighbour_in : nullptr, false);
  const ParticleStepArgs a = shared;  // private: its pointers stay in registers
  const std::int32_t* const particle = batch.particle.data();
  const std::int32_t* const slot = batch.slot.data();
  double* const xi[3] = {batch.xi[0].data(), batch.xi[1].data(), batch.xi[2].data()};
  double* const out[9] = {batch.load[0].data(), batch.load[1].data(), batch.load[2].data(),
                          batch.load[3].data(), batch.load[4].data(), batch.load[5].data(),
                          batch.load[6].data(), batch.load[7].data(), batch.load[8].data()};
  double dissipated_normal = 0, dissipated_tangential = 0, dissipated_rolling = 0, elastic = 0,
         spring_in = 0, spring_out = 0;
#pragma omp simd reduction(+ : dissipated_normal, dissipated_tangential, dissipated_rolling, \
                               elastic, spring_in, spring_out)
  for (int e = 0; e < end; ++e) {
    Dissipation d;
    Vec3 h{};
    if constexpr (history) h = {xi[0][e], xi[1][e], xi[2][e]};
    const ContactOutcome l = pair_contact<V>(particle[e], slot[e], h, a, d);
    if constexpr (history) xi[0][e] = h.x, xi[1][e] = h.y, xi[2][e] = h.z;
    out[0][e] = l.force.x, out[1][e] = l.force.y, out[2][e] = l.force.z;
    out[3][e] = l.torque.x, out[4][e] = l.torque.y, out[5][e] = l.torque.z;
    if constexpr (pair_doubles<V>() == 9)
      out[6][e] = l.partner_torque.x, out[7][e] = l.partner_torque.y,
      out[8][e] = l.partner_torque.z;
    dissipated_normal += e < pairs ? d.normal : 0.0;
    dissipated_tangential += e < pairs ? d.tangential : 0.0;
    if constexpr (V::kRolling) dissipated_rolling += e < pairs ? d.rolling : 0.0;
    elastic += e < pairs ? d.elastic : 0.0;
    if constexpr (history) {
      spring_in += e < pairs ? d.spring_in : 0.0;
      spring_out += e < pairs ? d.spring_out : 0.0;
    }
  }
  if constexpr (history) batch.scatter(pairs, a.history.neighbour_out);
  add_dissipation(total, {dissipated_normal, dissipated_tangential, dissipated_rolling, elastic,
                          spring_in, spring_out});
}

// The same for the first `walls` wall entries; their loads go to batch.load.
template <class V>
[[gnu::flatten]] void wall_contacts_simd(int walls, ContactBatch& batch,
                                         const ParticleStepArgs& shared, StepTotals& sum) {
  if (walls == 0) return;
  constexpr bool history = V::Tangential::kHistory;
  const int end = batch.gather(walls, history ? shared.history.wall_in : nullptr, true);
  const ParticleStepArgs a = shared;
  const std::int32_t* const particle = batch.particle.data();
  double* const xi[3] = {batch.xi[0].data(), batch.xi[1].data(), batch.xi[2].data()};
  const double *const gap = batch.gap.data(), *const nx = batch.normal[0].data(),
                      *const ny = batch.normal[1].data(), *const nz = batch.normal[2].data();
  double* const out[6] = {batch.load[0].data(), batch.load[1].data(), batch.load[2].data(),
                          batch.load[3].data(), batch.load[4].data(), batch.load[5].data()};
  double dissipated_normal = 0, dissipated_tangential = 0, dissipated_rolling = 0, elastic = 0,
         spring_in = 0, spring_out = 0;
#pragma omp simd reduction(+ : dissipated_normal, dissipated_tangential, dissipated_rolling, \
                               elastic, spring_in, spring_out)
  for (int e = 0; e < end; ++e) {
    Dissipation d;
    Vec3 h{};
    if constexpr (history) h = {xi[0][e], xi[1][e], xi[2][e]};
    const Load l = wall_contact<V>(particle[e], gap[e], {nx[e], ny[e], nz[e]}, h, a, d);
    if constexpr (history) xi[0][e] = h.x, xi[1][e] = h.y, xi[2][e] = h.z;
    dissipated_normal += e < walls ? d.normal : 0.0;
    dissipated_tangential += e < walls ? d.tangential : 0.0;
    if constexpr (V::kRolling) dissipated_rolling += e < walls ? d.rolling : 0.0;
    elastic += e < walls ? d.elastic : 0.0;
    if constexpr (history) {
      spring_in += e < walls ? d.spring_in : 0.0;
      spring_out += e < walls ? d.spring_out : 0.0;
    }
    out[0][e] = l.force.x, out[1][e] = l.force.y, out[2][e] = l.force.z;
    out[3][e] = l.torque.x, out[4][e] = l.torque.y, out[5][e] = l.torque.z;
  }
  if constexpr (history) batch.scatter(walls, a.history.wall_out);
  add_dissipation(sum, {dissipated_normal, dissipated_tangential, dissipated_rolling, elastic,
                        spring_in, spring_out});
}

// When a particle's slot tests find no contact, its nearest partner's gap bounds how long none
// can start: every particle moves at most `travel` (the drift bound of lists_expired()), so a
// pair closes by at most twice that, and twice again allows for positions rounding a small
// step up to one ulp. Until then its tests are skipped, exactly: a skipped test would have
// found no contact. From a lattice start, most spheres are apart for tens of steps at a time.
struct ClearanceSkip {
  double travel;       // drift bound now (m), since the last list build
  double* expiry;      // per particle: test again once travel reaches this
  double reach_bound;  // largest reach of a pair, minus the particle's radius (r_max)
};

// Per particle: force and torque (x, y, z each) of the step's contacts so far; zero between
// steps (the particle pass clears what it integrates).
using LoadArrays = std::array<double*, 6>;

// Pair pass over particles [begin, end): which forward slots touch, listed, then their
// contacts in SIMD lanes, then their loads summed into `load` for both particles when both are
// in the block (in list order, so the sums do not depend on threads). A partner in a later
// block is flagged, and gathers its pairs' loads in its particle pass from their slots, where
// only those pairs store them.
template <class V>
void pair_pass_block(int begin, int end, const ParticleStepArgs& shared, const ClearanceSkip& skip,
                     const LoadArrays& load, ContactBatch& batch, StepTotals& total) {
  const ParticleStepArgs a = shared;  // private: its pointers stay in registers
  std::int32_t* const particle = batch.particle.data();
  std::int32_t* const slot = batch.slot.data();
  std::int32_t* const had = batch.had.data();
  int pairs = 0;
  for (int i = begin; i < end; ++i) {
    if (skip.travel < skip.expiry[i]) {
      a.history.neighbour_mask_out[i] = 0;
      continue;
    }
    const double radius = V::kPolydisperse ? a.radius[i] : a.mono_radius;
    const Vec3 x{a.in.x[i], a.in.y[i], a.in.z[i]};
    const int n = a.neighbour_count[i];
    std::uint64_t touching = 0;
    Double2 nearest_sq = Double2{} + __builtin_inf(), dist_sq;
    for (int k = 0; k < n; k += kSlotGroup) {
      touching |= static_cast<std::uint64_t>(slot_group_hits<V>(i, x, radius, a, k, n, dist_sq))
                  << k;
      nearest_sq = nearest_sq < dist_sq ? nearest_sq : dist_sq;
    }
    std::uint64_t with_history = 0;  // read before the output mask: they may be one array
    if constexpr (V::Tangential::kHistory) with_history = a.history.neighbour_mask_in[i];
    a.history.neighbour_mask_out[i] = touching;
    if (!touching) {
      const double reach = radius + skip.reach_bound;
      const double gap = sqrt(std::min(nearest_sq[0], nearest_sq[1])) - reach;
      skip.expiry[i] = skip.travel + 0.25 * gap - 1e-9 * reach;  // margin: rounding of the gap
      continue;
    }
    skip.expiry[i] = skip.travel;
    const int base = a.slot_start[i];
    for (std::uint64_t m = touching; m; m &= m - 1) {
      const int k = lowest_bit(m);
      particle[pairs] = i;
      slot[pairs] = base + k;
      had[pairs] = static_cast<std::int32_t>(with_history >> k & 1u);
      const int j = a.neighbours[base + k];
      if (j >= end) raise_flag(a.incoming + j);
      ++pairs;
    }
  }
  pair_contacts_simd<V>(pairs, batch, shared, total);
  auto add = [&](int i, Vec3 force, Vec3 torque) {
    load[0][i] += force.x, load[1][i] += force.y, load[2][i] += force.z;
    load[3][i] += torque.x, load[4][i] += torque.y, load[5][i] += torque.z;
  };
  for (int e = 0; e < pairs; ++e) {
    const int i = particle[e], j = a.neighbours[slot[e]];
    const ContactOutcome l = batch.loads<V>(e);
    add(i, l.force, l.torque);
    if (j < end)
      add(j, -1.0 * l.force, l.partner_torque);
    else
      store_slot_loads<V>(slot[e], a, l);  // gathered in the partner's particle pass
  }
}

// f(k) for each k < n, in increasing order, with kinds[k] & bits set; kinds holds zeros up to
// the next multiple of 8. Eight bytes are tested at a time: most particles have no loads to
// gather, and a byte-by-byte scan mispredicted its branch at every one that has.
template <class F>
void for_each_marked(const std::uint8_t* kinds, int n, int bits, F&& f) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "byte k of a word is kinds[k]");
  const std::uint64_t pattern = 0x0101010101010101u * static_cast<std::uint64_t>(bits);
  for (int k = 0; k < n; k += 8) {
    std::uint64_t word;
    std::memcpy(&word, kinds + k, sizeof word);
    for (word &= pattern; word;) {
      const int byte = __builtin_ctzll(word) / 8;
      f(k + byte);
      word &= ~(std::uint64_t{0xff} << (8 * byte));
    }
  }
}

// Lists the walls particle i touches in `batch` from entry `walls`; returns the new count.
template <class V>
PDSIM_COLD int list_walls(int i, const ParticleStepArgs& a, ContactBatch& batch, int walls,
                          StepTotals& sum) {
  std::uint8_t with_history = 0, touched = 0;
  if constexpr (V::Tangential::kHistory) with_history = a.history.wall_mask_in[i];
  touching_walls<V>(i, a, sum, [&](int slot, double gap, Vec3 normal) {
    batch.particle[walls] = i;
    batch.slot[walls] = i * kWallSlots + slot;  // its history's
    batch.had[walls] = with_history >> slot & 1;
    batch.gap[walls] = gap;
    batch.normal[0][walls] = normal.x;
    batch.normal[1][walls] = normal.y;
    batch.normal[2][walls] = normal.z;
    touched = static_cast<std::uint8_t>(touched | (1u << slot));
    ++walls;
  });
  if constexpr (V::Tangential::kHistory) a.history.wall_mask_out[i] = touched;
  return walls;
}

// Particle pass over particles [begin, end) (at most kBlock), so that the common case runs in
// SIMD lanes: which particles have loads (SIMD), the wall contacts (listed, then SIMD), the
// loads of the particles that have some (out of line, one at a time: pairs, then walls in slot
// order), then every particle's integration (SIMD). The vector sums are reduced in an order
// fixed by the block, not by the threads.
template <class V>
void particle_pass_block(int begin, int end, const ParticleStepArgs& shared,
                         const LoadArrays& block_load, ContactBatch& batch, StepTotals& total) {
  const ParticleStepArgs a = shared;  // private: its pointers stay in registers
  const int n = end - begin;
  double* const load[6] = {block_load[0] + begin, block_load[1] + begin, block_load[2] + begin,
                           block_load[3] + begin, block_load[4] + begin, block_load[5] + begin};
  // Pairs within the block are already in `load`; kPairLoads marks pairs from earlier blocks.
  alignas(64) std::uint8_t kinds[kBlock];
  std::fill(kinds + n, kinds + (n + 7) / 8 * 8, 0);  // for for_each_marked()
#pragma omp simd
  for (int k = 0; k < n; ++k) {
    const int i = begin + k;
    const bool near = near_wall<V>(i, a);
    kinds[k] =
        static_cast<std::uint8_t>((a.incoming[i] != 0 ? kPairLoads : 0) | (near ? kWallLoads : 0));
    // list_walls() rewrites the masks of the particles near a wall after reading their input.
    if constexpr (V::Tangential::kHistory)
      a.history.wall_mask_out[i] = near ? a.history.wall_mask_in[i] : 0;
  }
  StepTotals sum;  // wall reactions and dissipation, then the integration's sums
  int walls = 0;
  for_each_marked(kinds, n, kWallLoads,
                  [&](int k) { walls = list_walls<V>(begin + k, shared, batch, walls, sum); });
  wall_contacts_simd<V>(walls, batch, shared, sum);
  int e = 0;  // the next wall entry
  for_each_marked(kinds, n, kPairLoads | kWallLoads, [&](int k) {
    const int i = begin + k;
    Load l{{load[0][k], load[1][k], load[2][k]}, {load[3][k], load[4][k], load[5][k]}};
    if (kinds[k] & kPairLoads) add_incoming_loads<V>(i, begin, shared, l);
    for (; e < walls && batch.particle[e] == i; ++e) {
      const Vec3 force{batch.load[0][e], batch.load[1][e], batch.load[2][e]};
      l.force += force;
      l.torque += Vec3{batch.load[3][e], batch.load[4][e], batch.load[5][e]};
      add_wall_reaction<V>(i, batch.gap[e],
                           {batch.normal[0][e], batch.normal[1][e], batch.normal[2][e]}, force,
                           shared, sum);
    }
    load[0][k] = l.force.x, load[1][k] = l.force.y, load[2][k] = l.force.z;
    load[3][k] = l.torque.x, load[4][k] = l.torque.y, load[5][k] = l.torque.z;
  });
  double kinetic = 0, speed_sq = 0;
#pragma omp simd reduction(+ : kinetic) reduction(max : speed_sq)
  for (int k = 0; k < n; ++k) {
    integrate<V>(begin + k, a,
                 {{load[0][k], load[1][k], load[2][k]}, {load[3][k], load[4][k], load[5][k]}},
                 kinetic, speed_sq);
    for (auto* component : load) component[k] = 0;  // cleared for the next step's pair pass
  }
  sum.kinetic += kinetic;
  sum.speed_sq = max_of(sum.speed_sq, speed_sq);
  accumulate(total, sum);
}

// A pass's blocks shared out among the threads. Each thread owns a contiguous share, the same
// every step (its particles stay in its core's cache), and takes its blocks from the front; a
// thread that has run out takes the others' from the back, so that neither an uneven share
// (the pile's blocks have more contacts) nor a thread delayed by the machine holds the other
// at the barrier. Which thread runs a block does not change the results.
class BlockShares {
 public:
  BlockShares() = default;
  explicit BlockShares(int threads)
      : threads_(threads), shares_(new Share[static_cast<std::size_t>(threads)]) {}
  void reset(int blocks) {  // before the parallel region
    for (int t = 0; t < threads_; ++t)
      shares_[t].range.store(pack(t * blocks / threads_, (t + 1) * blocks / threads_),
                             std::memory_order_relaxed);
  }
  // f(b) for the blocks that thread t takes.
  template <class F>
  void run(int t, F&& f) {
    int b;
    while (take(shares_[t], true, b)) f(b);
    for (int v = 1; v < threads_; ++v)
      while (take(shares_[(t + v) % threads_], false, b)) f(b);
  }

 private:
  struct alignas(64) Share {  // a cache line each: the owners update them at every block
    std::atomic<std::uint64_t> range{0};  // blocks [front, back), front in the low 32 bits
  };
  static std::uint64_t pack(int front, int back) {
    return static_cast<std::uint64_t>(front) | static_cast<std::uint64_t>(back) << 32;
  }
  static bool take(Share& s, bool front, int& b) {
    std::uint64_t r = s.range.load(std::memory_order_relaxed);
    for (;;) {
      const int lo = static_cast<int>(r & 0xffffffffu), hi = static_cast<int>(r >> 32);
      if (lo >= hi) return false;
      // Relaxed: the barriers around the passes order the blocks' data.
      if (s.range.compare_exchange_weak(r, front ? pack(lo + 1, hi) : pack(lo, hi - 1),
                                        std::memory_order_relaxed)) {
        b = front ? lo : hi - 1;
        return true;
      }
    }
  }
  int threads_ = 0;
  std::unique_ptr<Share[]> shares_;
};

template <class V>
class CpuEngine final : public DemEngine {
 public:
  explicit CpuEngine(const EngineConfig& c) : config_(c) {
    count_ = static_cast<int>(c.particles.size());
    threads_ = c.threads > 0 ? c.threads : omp_get_max_threads();
    pair_shares_ = BlockShares(threads_);
    particle_shares_ = BlockShares(threads_);
    const auto [rmin_it, rmax_it] = std::minmax_element(c.radius.begin(), c.radius.end());
    r_min_ = *rmin_it;
    r_max_ = *rmax_it;
    skin_ = default_skin(r_min_, c.skin);
    max_neighbours_ = neighbour_slots(r_min_, r_max_, skin_);
    check_particle_count(count_, max_neighbours_);
    check_fits(c.geometry, r_max_);
    const std::size_t n = static_cast<std::size_t>(count_);
    state_[0].resize(n);
    if (c.recompute) state_[1].resize(n);  // the back buffer
    radius_ = c.radius;
    inv_mass_.resize(n);
    inv_inertia_.resize(n);
    set_mass_properties();
    id_.resize(n);
    std::iota(id_.begin(), id_.end(), 0);
    set_particles(c.particles);
  }

  const StepTotals& compute(const ContainerKinematics& container, double dt) override {
    if (needs_rebuild_) rebuild(container);
    dt_ = dt;
    const ParticleStepArgs a = args(container, dt);
    const ClearanceSkip skip{travel_, expiry_.data(), r_max_};
    const LoadArrays load{loads_[0].data(), loads_[1].data(), loads_[2].data(),
                          loads_[3].data(), loads_[4].data(), loads_[5].data()};
    const int blocks = (count_ + kBlock - 1) / kBlock;
    block_totals_.assign(static_cast<std::size_t>(blocks), StepTotals{});
    auto range = [&](int b) {
      return std::make_pair(b * kBlock, std::min(count_, (b + 1) * kBlock));
    };
    // Each thread lists its blocks' contacts in its own batch.
    auto pair_block = [&](int b, ContactBatch& batch) {
      const auto [begin, end] = range(b);
      pair_pass_block<V>(begin, end, a, skip, load, batch,
                         block_totals_[static_cast<std::size_t>(b)]);
    };
    auto particle_block = [&](int b, ContactBatch& batch) {
      const auto [begin, end] = range(b);
      particle_pass_block<V>(begin, end, a, load, batch,
                             block_totals_[static_cast<std::size_t>(b)]);
    };
    if (blocks == 1 || threads_ == 1) {
      // Small scenes: a parallel region would cost more than it saves. In one thread, a
      // block's particle pass can follow its pair pass while the block is in cache: a
      // particle's pairs are computed by itself and its lower partners, all done by then
      // (+3.5 % at 8,000 spheres). Across threads the blocks waiting for another thread's
      // pairs cost more than that (measured -5 % on 2 threads), so they keep two passes.
      for (int b = 0; b < blocks; ++b) {
        pair_block(b, batches_[0]);
        particle_block(b, batches_[0]);
      }
    } else {
      pair_shares_.reset(blocks);
      particle_shares_.reset(blocks);
#pragma omp parallel num_threads(threads_)
      {
        const int t = omp_get_thread_num();
        ContactBatch& batch = batches_[static_cast<std::size_t>(t)];
        pair_shares_.run(t, [&](int b) { pair_block(b, batch); });
#pragma omp barrier
        particle_shares_.run(t, [&](int b) { particle_block(b, batch); });
      }
    }
    totals_ = StepTotals{};
    for (const auto& t : block_totals_) accumulate(totals_, t);
    flag_non_finite(totals_);
    return totals_;
  }

  void accept() override {
    if (config_.recompute) current_ ^= 1, history_current_ ^= 1;  // the back buffers
    if (lists_expired(travel_, totals_.speed_sq, dt_, skin_)) needs_rebuild_ = true;
  }

  int count() const override {
    return count_;
  }
  std::string variant() const override {
    return variant_string<V>();
  }
  std::string backend() const override {
    return "cpu (" + std::to_string(threads_) + " thread" + (threads_ > 1 ? "s)" : ")");
  }
  int threads() const override {
    return threads_;
  }

  std::vector<ParticleState> particles() const override {
    const StateBuffer& s = state_[current_];
    std::vector<ParticleState> out(static_cast<std::size_t>(count_));
    for (std::size_t i = 0; i < out.size(); ++i)
      out[static_cast<std::size_t>(id_[i])] = {
          {s.x[i], s.y[i], s.z[i]}, {s.vx[i], s.vy[i], s.vz[i]}, {s.wx[i], s.wy[i], s.wz[i]}};
    return out;
  }

  void set_particles(const std::vector<ParticleState>& p) override {
    StateBuffer& s = state_[current_];
    for (std::size_t i = 0; i < p.size(); ++i) {
      const ParticleState& q = p[static_cast<std::size_t>(id_[i])];
      s.x[i] = q.position.x, s.y[i] = q.position.y, s.z[i] = q.position.z;
      s.vx[i] = q.velocity.x, s.vy[i] = q.velocity.y, s.vz[i] = q.velocity.z;
      s.wx[i] = q.spin.x, s.wy[i] = q.spin.y, s.wz[i] = q.spin.z;
    }
    const std::size_t n = static_cast<std::size_t>(count_);
    for (auto& h : history_) {
      h.neighbour.clear();
      h.neighbour_mask.assign(n, 0);
      h.wall.assign(V::Tangential::kHistory ? 3 * kWallSlots * n : 0, 0.0);
      h.wall_mask.assign(n, 0);
    }
    neighbours_.clear();
    partner_id_.clear();
    reverse_.clear();
    neighbour_count_.assign(n, 0);
    reverse_count_.assign(n, 0);
    slot_start_.assign(n + 1, 0);
    reverse_start_.assign(n + 1, 0);
    incoming_.assign(n, 0);
    expiry_.assign(n, 0.0);
    for (auto& component : loads_) component.assign(n, 0.0);
    needs_rebuild_ = true;
  }

  StateArrays save() const override {
    StateArrays out;
    const StateBuffer& s = state_[current_];
    const char* names[9] = {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz"};
    for (int k = 0; k < 9; ++k) out[names[k]] = *s.all[k];
    out["id"] = id_;
    out["radius"] = radius_;
    const HistoryBuffer& h = history_[history_current_];
    // The checkpoint layout: max_neighbours_ slots per particle (see flat_reverse()).
    const std::size_t slots = static_cast<std::size_t>(count_) * max_neighbours_;
    std::vector<std::int32_t> neighbours(slots, -1), partner(slots, -1), reverse(slots, -1);
    std::vector<double> history(V::Tangential::kHistory ? 3 * slots : 0, 0.0);
    for (int i = 0; i < count_; ++i) {
      const std::size_t to = static_cast<std::size_t>(i) * max_neighbours_;
      const int from = slot_start_[i], n = neighbour_count_[i];
      std::copy_n(&neighbours_[from], padded(n), &neighbours[to]);
      std::copy_n(&partner_id_[from], n, &partner[to]);
      std::copy_n(&reverse_[reverse_start_[i]], reverse_count_[i], &reverse[to]);
      for (int k = 0; k < n && !history.empty(); ++k)
        if (h.neighbour_mask[i] >> k & 1u)
          std::copy_n(&h.neighbour[3 * (from + k)], 3, &history[3 * (to + k)]);
    }
    out["history"] = std::move(history);
    out["wall_history"] = live_history(h.wall, h.wall_mask, kWallSlots);
    out["wall_mask"] = h.wall_mask;
    out["neighbour_mask"] = h.neighbour_mask;
    out["neighbours"] = std::move(neighbours);
    out["partner_id"] = std::move(partner);
    out["neighbour_count"] = neighbour_count_;
    out["reverse"] = flat_reverse(reverse, max_neighbours_);
    out["reverse_count"] = reverse_count_;
    put_grid(out, {grid_, needs_rebuild_, max_neighbours_, travel_});
    return out;
  }

  void restore(const StateArrays& in) override {
    const GridState g = get_grid(in);
    max_neighbours_ = g.max_neighbours;
    set_particles(config_.particles);  // sizes every array for max_neighbours_
    StateBuffer& s = state_[current_];
    const char* names[9] = {"x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz"};
    for (int k = 0; k < 9; ++k) *s.all[k] = state_values<double>(in, names[k]);
    id_ = state_values<std::int32_t>(in, "id");
    radius_ = state_values<double>(in, "radius");
    set_mass_properties();
    HistoryBuffer& h = history_[history_current_];
    h.wall = state_values<double>(in, "wall_history");
    h.wall_mask = state_values<std::uint8_t>(in, "wall_mask");
    h.neighbour_mask = state_values<std::uint64_t>(in, "neighbour_mask");
    // From the checkpoint layout (max_neighbours_ slots per particle) to the compact one.
    neighbour_count_ = state_values<std::int32_t>(in, "neighbour_count");
    reverse_count_ = state_values<std::int32_t>(in, "reverse_count");
    const auto& neighbours = state_values<std::int32_t>(in, "neighbours");
    const auto& partner = state_values<std::int32_t>(in, "partner_id");
    const std::vector<std::int32_t> reverse =
        packed_reverse(state_values<std::int32_t>(in, "reverse"), max_neighbours_);
    const std::vector<double>& history = state_values<double>(in, "history");
    set_slot_starts();
    set_reverse_starts();
    for (int i = 0; i < count_; ++i) {
      const std::size_t from = static_cast<std::size_t>(i) * max_neighbours_;
      const int to = slot_start_[i], n = neighbour_count_[i];
      std::copy_n(&neighbours[from], padded(n), &neighbours_[to]);
      std::copy_n(&partner[from], n, &partner_id_[to]);
      std::copy_n(&reverse[from], reverse_count_[i], &reverse_[reverse_start_[i]]);
      if (V::Tangential::kHistory) std::copy_n(&history[3 * from], 3 * n, &h.neighbour[3 * to]);
    }
    travel_ = g.travel;
    grid_ = g.grid;
    needs_rebuild_ = g.needs_rebuild;
  }

  // Memory held now: the lists take what the last build needed (nothing before the first step).
  std::size_t bytes_per_particle() const override {
    auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
    std::size_t sum = pair_capacity_ * pair_doubles<V>() * sizeof(double) + bytes(radius_) +
                      bytes(inv_mass_) + bytes(inv_inertia_) + bytes(incoming_) + bytes(expiry_);
    for (const auto& component : loads_) sum += bytes(component);
    for (const auto& s : state_)
      for (const auto* a : s.all) sum += bytes(*a);
    for (const auto& h : history_)
      sum += bytes(h.neighbour) + bytes(h.wall) + bytes(h.neighbour_mask) + bytes(h.wall_mask);
    for (const auto& batch : batches_) sum += batch.bytes();
    for (const auto* a : {&id_, &neighbours_, &partner_id_, &neighbour_count_, &slot_start_,
                          &reverse_, &reverse_count_, &reverse_start_})
      sum += bytes(*a);
    return sum / static_cast<std::size_t>(count_);
  }

 private:
  void set_mass_properties() {
    for (std::size_t i = 0; i < radius_.size(); ++i) {
      const SphereMass m = sphere_mass(radius_[i], config_.density);
      inv_mass_[i] = m.inv_mass;
      inv_inertia_[i] = m.inv_inertia;
    }
  }

  ParticleStepArgs args(const ContainerKinematics& container, double dt) {
    StateBuffer& in = state_[current_];
    // In place without recompute. Only the particle pass writes the state, each particle its
    // own. On several threads a barrier separates it from the pair pass; on one, a block's
    // particle pass follows its pairs, and later pairs read only particles of higher index.
    StateBuffer& out = state_[config_.recompute ? current_ ^ 1 : current_];
    HistoryBuffer& hin = history_[history_current_];
    // Likewise the tangential history: each slot is read and then rewritten by its one
    // contact, so only a step that may be recomputed needs a second buffer (in place: +5 to
    // +10 % at 8,000 spheres, the history's cache traffic halved).
    HistoryBuffer& hout = config_.recompute ? history_[history_current_ ^ 1] : hin;
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
    a.pair_load = pair_load_.get();
    return a;
  }

  // Sorts the particles by grid cell and rebuilds the neighbour lists, carrying the history.
  void rebuild(const ContainerKinematics& container) {
    const std::size_t n = static_cast<std::size_t>(count_);
    StateBuffer& s = state_[current_];
    grid_ = grid_around(container.position, config_.geometry.half_size, 2 * r_max_ + skin_);
    const int cells = grid_.nx * grid_.ny * grid_.nz;

    // Counting sort by cell (stable, so the order is reproducible).
    std::vector<std::int32_t> cell_of_particle(n);
    std::vector<std::int32_t> cell_start(static_cast<std::size_t>(cells) + 1, 0);
    for (std::size_t i = 0; i < n; ++i) {
      cell_of_particle[i] = cell_of(grid_, {s.x[i], s.y[i], s.z[i]});
      ++cell_start[static_cast<std::size_t>(cell_of_particle[i]) + 1];
    }
    std::partial_sum(cell_start.begin(), cell_start.end(), cell_start.begin());
    std::vector<std::int32_t> order(n);
    {
      std::vector<std::int32_t> fill(cell_start.begin(), cell_start.end() - 1);
      for (std::size_t i = 0; i < n; ++i)
        order[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell_of_particle[i])]++)] =
            static_cast<std::int32_t>(i);
    }
    for (auto* a : s.all) permute(*a, order);
    permute(id_, order);
    permute(radius_, order);
    permute(inv_mass_, order);
    permute(inv_inertia_, order);
    HistoryBuffer& hin = history_[history_current_];
    HistoryBuffer& scratch = history_[history_current_ ^ 1];
    // Through the other history buffer: a scratch, or the back buffer that the next step
    // rewrites (masks whole, history where live).
    permute(hin.wall, order, 3 * kWallSlots, scratch.wall);
    permute(hin.wall_mask, order, 1, scratch.wall_mask);

    NeighbourBuildArgs b{};
    b.count = count_;
    b.grid = grid_;
    b.x = s.x.data();
    b.y = s.y.data();
    b.z = s.z.data();
    b.radius = V::kPolydisperse ? radius_.data() : nullptr;
    b.mono_radius = radius_[0];
    b.skin = skin_;
    b.cell_start = cell_start.data();
    b.cell_end = cell_start.data() + 1;
    b.id = id_.data();
    b.max_neighbours = max_neighbours_;
    b.slot_start = slot_start_.data();
    b.reverse_start = reverse_start_.data();
    b.neighbour_count = neighbour_count_.data();
    b.reverse_count = reverse_count_.data();
    const std::vector<std::int32_t> old_start = slot_start_, old_partner = partner_id_,
                                    old_count = neighbour_count_;
    // The lists are compact: counted first, then written from their starts.
    bool fits = for_all([&](int i) { return build_neighbours_of(i, b); });
    set_slot_starts();
    if (V::Tangential::kHistory) {
      b.old_index = order.data();
      b.old_slot_start = old_start.data();
      b.old_partner_id = old_partner.data();
      b.old_neighbour_count = old_count.data();
      b.old_mask = hin.neighbour_mask.data();
      b.old_history = hin.neighbour.data();
      b.new_mask = scratch.neighbour_mask.data();
      b.new_history = scratch.neighbour.data();
    }
    b.neighbours = neighbours_.data();
    b.partner_id = partner_id_.data();
    fits &= for_all([&](int i) { return build_neighbours_of(i, b); });
    fits &= build_reverse_lists(b);  // counts
    set_reverse_starts();
    b.reverse = reverse_.data();
    build_reverse_lists(b);
    if (!fits)
      throw SimulationError("neighbour list overflow (" + std::to_string(max_neighbours_) +
                            " slots): particles are packed beyond the densest packing; the "
                            "simulation has most likely blown up");
    if (V::Tangential::kHistory) {
      std::swap(hin.neighbour, scratch.neighbour);
      std::swap(hin.neighbour_mask, scratch.neighbour_mask);
    }
    travel_ = 0;
    std::fill(expiry_.begin(), expiry_.end(), 0.0);  // new partners: test every particle
    needs_rebuild_ = false;
  }

  // Whether f(i) holds for every particle, f run over the threads.
  template <class F>
  bool for_all(F&& f) {
    int failed = 0;
#pragma omp parallel for num_threads(threads_) schedule(static) reduction(| : failed)
    for (int i = 0; i < count_; ++i) failed |= f(i) ? 0 : 1;
    return !failed;
  }

  // Compact forward lists: starts from the (padded) counts, and room for their slots. The
  // arrays only grow, so that the old history stays intact while the new lists are written.
  void set_slot_starts() {
    for (int i = 0; i < count_; ++i)
      slot_start_[i + 1] = slot_start_[i] + padded(neighbour_count_[i]);
    const auto slots = static_cast<std::size_t>(slot_start_[count_]);
    // A block lists at most its slots' pairs and kMaxWallContacts walls per particle.
    std::size_t block_slots = 0;
    for (int b = 0; b < count_; b += kBlock)
      block_slots = std::max<std::size_t>(
          block_slots, slot_start_[std::min(count_, b + kBlock)] - slot_start_[b]);
    batches_.resize(static_cast<std::size_t>(threads_));
    for (auto& batch : batches_)
      if (batch.particle.size() < block_slots + kLanes || batch.gap.empty())  // + padding
        batch.resize(block_slots + block_slots / 4,
                     static_cast<std::size_t>(std::min(count_, kBlock)) * kMaxWallContacts);
    grow(neighbours_, slots);
    grow(partner_id_, slots);
    if (V::Tangential::kHistory)
      for (auto& h : history_) grow(h.neighbour, 3 * slots);
    if (slots > pair_capacity_) {
      // Written before it is read, and only for pairs in contact: left uninitialised.
      pair_capacity_ = slots + slots / 4;
      pair_load_.reset(new double[pair_doubles<V>() * pair_capacity_]);
    }
  }
  void set_reverse_starts() {
    for (int i = 0; i < count_; ++i) reverse_start_[i + 1] = reverse_start_[i] + reverse_count_[i];
    grow(reverse_, static_cast<std::size_t>(reverse_start_[count_]));
  }
  template <class T>
  static void grow(std::vector<T>& v, std::size_t size) {
    if (v.size() < size) v.resize(size);
  }

  EngineConfig config_;
  ParticleStepArgs scene_args_ = scene_step_args(config_);
  int count_ = 0, threads_ = 1, max_neighbours_ = 1;
  int current_ = 0, history_current_ = 0;  // the front buffers
  double r_min_ = 0, r_max_ = 0, skin_ = 0;
  double dt_ = 0, travel_ = 0;    // last step size; drift bound since the last build (m)
  std::vector<double> expiry_;    // ClearanceSkip, per particle
  std::vector<double> loads_[6];  // LoadArrays
  StateBuffer state_[2];
  HistoryBuffer history_[2];
  std::vector<double> radius_, inv_mass_, inv_inertia_;
  // Lists in a compact layout: particle i's from slot_start_[i] (reverse_start_[i]).
  std::vector<std::int32_t> id_, neighbours_, partner_id_, neighbour_count_, slot_start_, reverse_,
      reverse_count_, reverse_start_;
  std::vector<std::uint32_t> incoming_;
  std::unique_ptr<double[]> pair_load_;
  std::size_t pair_capacity_ = 0;  // slots pair_load_ holds
  Grid grid_{};
  bool needs_rebuild_ = true;
  std::vector<StepTotals> block_totals_;
  std::vector<ContactBatch> batches_;  // one per thread
  BlockShares pair_shares_, particle_shares_;
  StepTotals totals_;
};

struct MakeCpu {
  const EngineConfig& config;
  template <class V>
  std::unique_ptr<DemEngine> operator()() const {
    return std::make_unique<CpuEngine<V>>(config);
  }
};

}  // namespace cpu_engine

// The CPU engines of the laws N and T and the rolling choice R, for the remaining choices of
// `config` (engine_cpu.cpp picks this factory, a generated translation unit instantiates it).
template <class N, class T, bool R>
std::unique_ptr<DemEngine> make_cpu_engine_of(const EngineConfig& config) {
  return dispatch_detail::by_gravity<N, T, R>(config, cpu_engine::MakeCpu{config});
}

}  // namespace pdsim

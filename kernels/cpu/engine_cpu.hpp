// OpenMP backend: launches the shared per-particle functions over particle blocks. Totals are
// reduced per fixed block of particles and then summed in block order, so results are bitwise
// identical for any thread count. This header holds the passes, compiled per kernel variant in
// the CMake-generated translation units of engine_cpu_variants.cpp.in; engine_cpu.cpp holds the
// engine, compiled once.
#pragma once

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <memory>
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

// Whether variant V's contacts can add to tally T; the others stay zero and are not summed.
template <class V, int T>
constexpr bool tallied() {
  if constexpr (T == kRolling) return V::kRolling;
  if constexpr (T == kSpringIn || T == kSpringOut) return V::Tangential::kHistory;
  return true;
}

// Adds entry e's tally T to its SIMD lane's sum (the padding's, `counted` false, add nothing).
template <class V, int T>
inline void add_lane(double& sum, const Dissipation& d, bool counted) {
  if constexpr (tallied<V, T>()) sum += counted ? tally<T>(d) : 0.0;
}

// The contact loops' lanes' sums are scalars, one per Tally, named in their reduction clauses:
// OpenMP reduces scalars in registers, and an array in memory, which cost a third.
static_assert(kTallyCount == 6, "a lane sum per Tally in the loops below");
template <class V>
inline void add_lanes(const Dissipation& d, bool counted, double& t0, double& t1, double& t2,
                      double& t3, double& t4, double& t5) {
  add_lane<V, 0>(t0, d, counted), add_lane<V, 1>(t1, d, counted);
  add_lane<V, 2>(t2, d, counted), add_lane<V, 3>(t3, d, counted);
  add_lane<V, 4>(t4, d, counted), add_lane<V, 5>(t5, d, counted);
}

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
  double t0 = 0, t1 = 0, t2 = 0, t3 = 0, t4 = 0, t5 = 0;
#pragma omp simd reduction(+ : t0, t1, t2, t3, t4, t5)
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
    add_lanes<V>(d, e < pairs, t0, t1, t2, t3, t4, t5);
  }
  if constexpr (history) batch.scatter(pairs, a.history.neighbour_out);
  add_tallies(total.tally, {t0, t1, t2, t3, t4, t5});  // members in Tally order
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
  double t0 = 0, t1 = 0, t2 = 0, t3 = 0, t4 = 0, t5 = 0;
#pragma omp simd reduction(+ : t0, t1, t2, t3, t4, t5)
  for (int e = 0; e < end; ++e) {
    Dissipation d;
    Vec3 h{};
    if constexpr (history) h = {xi[0][e], xi[1][e], xi[2][e]};
    const Load l = wall_contact<V>(particle[e], gap[e], {nx[e], ny[e], nz[e]}, h, a, d);
    if constexpr (history) xi[0][e] = h.x, xi[1][e] = h.y, xi[2][e] = h.z;
    add_lanes<V>(d, e < walls, t0, t1, t2, t3, t4, t5);
    out[0][e] = l.force.x, out[1][e] = l.force.y, out[2][e] = l.force.z;
    out[3][e] = l.torque.x, out[4][e] = l.torque.y, out[5][e] = l.torque.z;
  }
  if constexpr (history) batch.scatter(walls, a.history.wall_out);
  add_tallies(sum.tally, {t0, t1, t2, t3, t4, t5});
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
  pair_contacts_simd<PairLaws<V>>(pairs, batch, shared, total);
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
  touching_walls<V>(i, a, sum, [&](int slot, bool had, double gap, Vec3 normal) {
    batch.particle[walls] = i;
    batch.slot[walls] = i * kWallSlots + slot;  // its history's
    batch.had[walls] = had;
    batch.gap[walls] = gap;
    batch.normal[0][walls] = normal.x;
    batch.normal[1][walls] = normal.y;
    batch.normal[2][walls] = normal.z;
    ++walls;
  });
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
  wall_contacts_simd<WallLaws<V>>(walls, batch, shared, sum);
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

// What the CPU engine runs per kernel variant: the two passes over a block of particles. Only
// these are compiled per variant; the engine around them (engine_cpu.cpp) is compiled once.
struct CpuStep {
  void (*pair_block)(int begin, int end, const ParticleStepArgs& shared, const ClearanceSkip& skip,
                     const LoadArrays& load, ContactBatch& batch, StepTotals& total);
  void (*particle_block)(int begin, int end, const ParticleStepArgs& shared, const LoadArrays& load,
                         ContactBatch& batch, StepTotals& total);
  VariantInfo variant;
};

struct PickCpuStep {
  template <class V>
  CpuStep operator()() const {
    return {&pair_pass_block<V>, &particle_pass_block<V>, variant_info<V>()};
  }
};

// A non-smooth scene's whole step (kernels/cpu/nonsmooth_cpu.cpp): its contacts, their impulses
// and the integration, over the engine's state, lists and history (the last step's impulses).
class NonsmoothStep {
 public:
  virtual ~NonsmoothStep() = default;
  virtual void step(const ParticleStepArgs& a, int threads, StepTotals& totals) = 0;
};
struct NonsmoothVariant {
  std::unique_ptr<NonsmoothStep> step;
  VariantInfo variant;
};
NonsmoothVariant make_nonsmooth_step(const EngineConfig& config);

}  // namespace cpu_engine

// The CPU passes of the laws N and T and the rolling choice R, for the remaining choices of
// `config`: defined (and compiled) only in the translation units generated from
// engine_cpu_variants.cpp.in, so that engine_cpu.cpp, which picks one, compiles none.
template <class N, class T, bool R>
cpu_engine::CpuStep cpu_step_of(const EngineConfig& config);

}  // namespace pdsim

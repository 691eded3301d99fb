// The energies the contacts tally, declared once. A contact law adds to its members of a
// Dissipation; both engines reduce every tally alike (for_each_tally); the step and period
// records carry the dissipated ones as an array, and the /frf and /energy columns
// (kMechanismColumns), the points' checkpoint and the energy ledger follow from it. A new
// dissipation mechanism is an entry in Tally, a member and its case in tally<T>(), its columns,
// and the law that adds to it.
#pragma once

#include <array>
#include <utility>

#include "kernels/vec3.hpp"

namespace pdsim {

enum Tally : int {
  kNormal,      // J, the normal dashpot
  kTangential,  // J, the tangential dashpot, Coulomb cap or directional friction
  kRolling,     // J, rolling resistance
  kMechanisms,  // the tallies above are dissipated; those below keep the energy ledger
  // J, in the contacts' springs at the start of the step, in the leapfrog form (contact() in
  // particle_step.hpp).
  kElastic = kMechanisms,
  // J, the tangential springs' 1/2 kt s^2 at this step's stiffness, as carried in and as left
  // by the step. Between the last step's spring_out and this step's spring_in the springs lose
  // energy that no force's work accounts for: that of contacts that ended (their history is
  // dropped) and Mindlin's stiffness change (kt follows the overlap while s is held). The
  // coupled system tallies it as friction's (CoupledSystem::account_springs).
  kSpringIn,
  kSpringOut,
  kTallyCount
};

// One contact's, one particle's or one step's tallies, J. Named members taken by a constant
// index (tally<T>), not an array taken by a variable one: in the CPU engine's SIMD contact
// loops GCC keeps a struct of scalars in registers, and an array, a switch or a reference
// returned to a member in memory, which stopped the loops vectorising.
struct Dissipation {  // members in Tally order
  double normal = 0, tangential = 0, rolling = 0, elastic = 0, spring_in = 0, spring_out = 0;
};
static_assert(sizeof(Dissipation) == kTallyCount * sizeof(double), "a member for every Tally");

// Tally T of d, by value (see above).
template <int T>
PDSIM_HD double tally(const Dissipation& d) {
  static_assert(T >= 0 && T < kTallyCount, "a Tally");
  return T == kNormal       ? d.normal
         : T == kTangential ? d.tangential
         : T == kRolling    ? d.rolling
         : T == kElastic    ? d.elastic
         : T == kSpringIn   ? d.spring_in
                            : d.spring_out;
}
// Tally T of d, to add to (outside the SIMD loops).
template <int T>
PDSIM_HD double& tally(Dissipation& d) {
  static_assert(T >= 0 && T < kTallyCount, "a Tally");
  if constexpr (T == kNormal)
    return d.normal;
  else if constexpr (T == kTangential)
    return d.tangential;
  else if constexpr (T == kRolling)
    return d.rolling;
  else if constexpr (T == kElastic)
    return d.elastic;
  else if constexpr (T == kSpringIn)
    return d.spring_in;
  else
    return d.spring_out;
}

// Calls f(std::integral_constant<int, T>{}) for every tally T, in order.
template <class F, int... T>
PDSIM_HD void for_each_tally(F&& f, std::integer_sequence<int, T...>) {
  (f(std::integral_constant<int, T>{}), ...);
}
template <class F>
PDSIM_HD void for_each_tally(F&& f) {
  for_each_tally(f, std::make_integer_sequence<int, kTallyCount>{});
}

PDSIM_HD void add_tallies(Dissipation& sum, const Dissipation& d) {
  for_each_tally([&](auto t) { tally<t>(sum) += tally<t>(d); });
}

// The dissipated energies of a step, a period or a point, J, by mechanism (host side).
using Dissipated = std::array<double, kMechanisms>;
inline Dissipated& operator+=(Dissipated& sum, const Dissipated& d) {
  for (int m = 0; m < kMechanisms; ++m) sum[m] += d[m];
  return sum;
}
inline Dissipated dissipated_part(const Dissipation& d) {
  Dissipated out{};
  for_each_tally([&](auto t) {
    if constexpr (t < kMechanisms) out[t] = tally<t>(d);
  });
  return out;
}

// The mechanisms' /frf (per period) and /energy (cumulative) columns.
struct MechanismColumn {
  const char* name;
  const char* per_period;
  const char* cumulative;
};
inline constexpr MechanismColumn kMechanismColumns[kMechanisms] = {
    {"dissipated_normal", "per period, normal contact damping",
     "cumulative, normal contact damping"},
    {"dissipated_tangential", "per period, friction and tangential damping",
     "cumulative, friction and tangential damping (with the Mindlin spring's energy change as "
     "its stiffness follows the overlap)"},
    {"dissipated_rolling", "per period, rolling resistance", "cumulative, rolling resistance"},
};

}  // namespace pdsim

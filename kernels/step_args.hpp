// What a DEM step is given and what it returns, without the contact laws: the kernel variant's
// choices, the step's arrays and constants, and the per-particle totals. The host engine API
// (kernels/engine.hpp) needs only these, so that a change to a contact law recompiles the
// passes (kernels/particle_step.hpp) and not everything that holds an engine.
#pragma once

#include <cstdint>

#include "kernels/dem_types.hpp"
#include "kernels/shapes.hpp"
#include "kernels/tallies.hpp"

namespace pdsim {

// A scene's physics, fixed at start: disabled effects compile away.
template <class NormalLaw, class TangentialLaw, bool Rolling, bool Gravity, bool Polydisperse,
          WallShape Shape, bool Rotating = false>
struct Variant {
  using Normal = NormalLaw;
  using Tangential = TangentialLaw;
  static constexpr bool kRolling = Rolling;
  static constexpr bool kGravity = Gravity;
  static constexpr bool kPolydisperse = Polydisperse;
  static constexpr WallShape kShape = Shape;
  static constexpr bool kRotating = Rotating;
};

// The contact laws read fewer of a variant's choices than a whole step does: a pair's not the
// container's shape, rotation or gravity, a wall's not its shape or gravity. Code instantiated
// on these is compiled once for every variant that shares it (24 pair and 48 wall variants
// instead of 288 each): the same code, the same results.
template <class V>
using PairLaws = Variant<typename V::Normal, typename V::Tangential, V::kRolling, false,
                         V::kPolydisperse, WallShape::box, false>;
template <class V>
using WallLaws = Variant<typename V::Normal, typename V::Tangential, V::kRolling, false,
                         V::kPolydisperse, WallShape::box, V::kRotating>;

// Live contact-history slots are marked in bit masks, so that absent contacts cost no memory
// traffic (a slot is read only when its bit is set in the input mask). Every scene has the
// masks: the pair pass marks the touching slots there for the particle pass.
struct HistoryArrays {
  const double* neighbour_in;  // 3 per forward slot
  double* neighbour_out;
  const std::uint64_t* neighbour_mask_in;
  std::uint64_t* neighbour_mask_out;  // forward slots in contact, set by the pair pass
  const double* wall_in;              // count x kWallSlots x 3
  double* wall_out;
  const std::uint8_t* wall_mask_in;
  std::uint8_t* wall_mask_out;
  // count x kWallSlots: the feature each slot holds the history of, where shapes name walls by
  // key (the mesh); the others' slots are their walls.
  const std::int32_t* wall_key_in;
  std::int32_t* wall_key_out;
};

// The history pointers of a step: read `in`, write `out` (either backend's buffers).
template <class In, class Out>
HistoryArrays history_view(const In& in, Out& out) {
  return {in.neighbour.data(),       out.neighbour.data(), in.neighbour_mask.data(),
          out.neighbour_mask.data(), in.wall.data(),       out.wall.data(),
          in.wall_mask.data(),       out.wall_mask.data(), in.wall_key.data(),
          out.wall_key.data()};
}

// Mass properties of a solid sphere (I = 2/5 m r^2): one expression for both backends and for
// restored runs, so that they agree bitwise.
struct SphereMass {
  double mass, inertia, inv_mass, inv_inertia;
};
inline SphereMass sphere_mass(double radius, double density) {
  const double mass = density * 4.0 / 3.0 * kPi * radius * radius * radius;
  const double inertia = 0.4 * mass * radius * radius;
  return {mass, inertia, 1.0 / mass, 1.0 / inertia};
}

struct ParticleStepArgs {
  int count;
  double dt;
  ParticleArrays in, out;
  const double* radius;       // polydisperse only
  const double* inv_mass;     // polydisperse only
  const double* inv_inertia;  // polydisperse only
  double mono_radius;         // monodisperse: every particle's radius and mass
  SphereMass mono;
  // Forward lists: partners of higher index within reach + skin, so that each pair is listed
  // once; particle i's list (padded, see neighbours.hpp) starts at slot slot_start[i]. Pair
  // history and loads live in the same slots.
  const std::int32_t* neighbours;
  const std::int32_t* neighbour_count;
  const std::int32_t* slot_start;
  // Reverse lists: the forward slots that list particle i (reverse_entry()s), from
  // reverse_start[i].
  const std::int32_t* reverse;
  const std::int32_t* reverse_count;
  const std::int32_t* reverse_start;
  HistoryArrays history;
  // Written by the pair pass, read by the particle pass (with history.neighbour_mask_out).
  // Set when a lower particle touches i (CPU: one of an earlier block); the particle pass
  // clears it.
  std::uint32_t* incoming;
  double* pair_load;  // pair_doubles<V>() per slot in contact (CPU: partner in a later block)
  ContactParams contact;
  ContainerGeometry geometry;
  ContainerKinematics container;
  Vec3 gravity;  // m/s^2
};

// Per forward slot in contact: force on the owner, torque on the owner, and torque on the
// partner. Equal spheres without rolling resistance have equal torques (the same radius times
// the same tangential force), so the third is not stored.
template <class V>
constexpr int pair_doubles() {
  return V::kPolydisperse || V::kRolling ? 9 : 6;
}

// What one particle adds to the step totals (reduced by the launcher in a fixed order).
struct ParticleContribution {
  Vec3 wall_force;    // on the container
  Vec3 wall_torque;   // on the container, about its centre (Rotating variants only)
  Dissipation tally;  // J, over its contacts (kernels/tallies.hpp)
  double kinetic = 0;
  double speed_sq = 0;  // largest |v|^2 at the end of the step (bounds the drift since a rebuild)
  int flags = 0;
};

PDSIM_HD void accumulate(ParticleContribution& sum, const ParticleContribution& c) {
  sum.wall_force += c.wall_force;
  sum.wall_torque += c.wall_torque;
  add_tallies(sum.tally, c.tally);
  sum.kinetic += c.kinetic;
  sum.speed_sq = max_of(sum.speed_sq, c.speed_sq);
  sum.flags |= c.flags;
}

// Sets kNonFinite when the reduced totals show a non-finite state. Positions advance by finite
// velocities, so a non-finite state always shows in the kinetic energy; checking the sum once
// per step keeps the test out of the per-particle work.
PDSIM_HD void flag_non_finite(ParticleContribution& totals) {
  if (!(totals.kinetic < 1e300)) totals.flags |= kNonFinite;
}

}  // namespace pdsim

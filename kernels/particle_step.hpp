// One DEM step, written once for the CPU and CUDA backends, in two passes over the particles:
//  1. pair pass: each particle tests its forward neighbour list (partners of higher index, so
//     every pair is listed once) and computes the touching pairs' forces, once per pair, into the
//     pair's slot;
//  2. particle pass: each particle gathers its pairs' forces in a fixed order (its own slots,
//     then its reverse list) plus the container walls, and integrates (semi-implicit Euler).
//     The CPU engine adds pairs within a block of particles to both in its pair pass instead,
//     and gathers only those from earlier blocks (engine_cpu.hpp).
// Only the particle pass writes the state, each particle its own, after every pair that reads it:
// the CPU engine advances it in place unless tight coupling re-runs a step from the same input
// (then, like CUDA, it keeps a second buffer). No pass writes another particle's sums, so no
// atomics add forces, and the result does not depend on the thread count.
#pragma once

#include <cstdint>
#if !defined(__CUDACC__) && defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "kernels/contact_tangential.hpp"
#include "kernels/shapes.hpp"
#include "kernels/step_args.hpp"

namespace pdsim {

// Slot and value offsets are 64-bit: a slot index fits int32 (check_particle_count), but 3 or 9
// values per slot do not at the counts a GPU holds.
PDSIM_HD Vec3 load3(const double* a, std::int64_t k) {
  return {a[3 * k], a[3 * k + 1], a[3 * k + 2]};
}
PDSIM_HD void store3(double* a, std::int64_t k, Vec3 v) {
  a[3 * k] = v.x;
  a[3 * k + 1] = v.y;
  a[3 * k + 2] = v.z;
}

// Force and torque of one contact on the particle, and the torque on its partner (of radius
// `partner_radius`; the partner's force is minus `force`). `normal` points from the other body
// to this particle; `vrel` is the velocity of this particle's contact point relative to the
// other's, `omega_rel` its spin relative to the other body's.
struct ContactOutcome {
  Vec3 force, torque, partner_torque;
};

// Solid spheres (I = 2/5 m R^2): a force F in the tangent plane at the contact point changes
// the points' relative velocity by dt F (1/m* + R_i^2/I_i + R_j^2/I_j) = dt F / (2/7 m*).
constexpr double kTangentMassRatio = 2.0 / 7.0;

// The contact's loads, its dissipation into `dissipated`. `mass_eff` is m* (and `inv_mass_eff`
// 1/m*, so that no contact divides by it), `inv_inertia` and
// `partner_inv_inertia` 1/I_i and 1/I_j (0 for a wall): what the contact's own loads act on in
// a step, so that the dissipative elements count their work at the mid-step velocities and
// never reverse a slip or a spin within the step (contact_tangential.hpp).
template <class V>
PDSIM_HD ContactOutcome contact(double overlap, Vec3 normal, Vec3 vrel, Vec3 omega_rel,
                                double radius, double partner_radius, double radius_eff,
                                double mass_eff, double inv_mass_eff, double inv_inertia,
                                double partner_inv_inertia, bool wall, Vec3* history, double dt,
                                const ContactParams& p, Dissipation& dissipated) {
  const NormalResponse r = V::Normal::respond(overlap, radius_eff, mass_eff, wall, p);
  const double vn = dot(vrel, normal);
  const Vec3 vt = vrel - vn * normal;
  const double fn = r.elastic - r.damping * vn;
  // The dashpot's work at the mid-step normal speed (tangential forces and torques leave it).
  dissipated.normal += r.damping * vn * (vn + 0.5 * dt * fn * inv_mass_eff) * dt;
  // The springs' energy in the leapfrog form that the step conserves for a linear spring,
  // 1/2 k x_prev . x with x_prev = x - dt v (contact_tangential.hpp): it goes with the kinetic
  // energy of the input velocities. Exact for a linear normal spring, O(dt^2) otherwise.
  dissipated.elastic += V::Normal::kEnergyRatio * r.elastic * overlap + 0.5 * dt * r.elastic * vn;
  const Vec3 ft = V::Tangential::force(history, normal, vt, r, fn, kTangentMassRatio * mass_eff, dt,
                                       p, dissipated);
  ContactOutcome out{fn * normal + ft, cross(-radius * normal, ft),
                     cross(-partner_radius * normal, ft)};
  if constexpr (V::kRolling) {
    // Rolling resistance |T| = mu_r R* |Fn| against the relative spin in the tangent plane
    // (spin about the normal is torsion, which it does not resist). Where that torque would
    // reverse the spin within the step, it is the torque that stops it.
    const Vec3 rolling = omega_rel - dot(omega_rel, normal) * normal;
    const double rate = norm(rolling);
    const double resistance = p.rolling_friction * radius_eff * fabs(fn);
    const double stop = 1.0 / (dt * (inv_inertia + partner_inv_inertia));
    // Selected, not branched: at rate 0 the division gives inf (or NaN) that is not taken.
    const double scale = resistance < stop * rate ? resistance / rate : stop;
    const Vec3 torque = -scale * rolling;
    out.torque += torque;
    out.partner_torque -= torque;
    // Its work at the mid-step spin, which all of this contact's torques change (a rolling
    // ball's tangential force turns it about as much as the resistance does).
    const Vec3 spin_change =
        dt * (inv_inertia * out.torque - partner_inv_inertia * out.partner_torque);
    dissipated.rolling -= dot(torque, rolling + 0.5 * spin_change) * dt;
  }
  return out;
}

// Index of the lowest set bit of a non-zero mask.
PDSIM_HD int lowest_bit(std::uint64_t m) {
#if defined(__CUDA_ARCH__)
  return __ffsll(static_cast<long long>(m)) - 1;
#else
  return __builtin_ctzll(m);
#endif
}

// Radius and mass properties of particle i.
struct Body {
  double radius, mass, inertia, inv_mass, inv_inertia;
};
template <class V>
PDSIM_HD Body body(int i, const ParticleStepArgs& a) {
  if constexpr (V::kPolydisperse)
    return {a.radius[i], 1.0 / a.inv_mass[i], 1.0 / a.inv_inertia[i], a.inv_mass[i],
            a.inv_inertia[i]};
  else
    return {a.mono_radius, a.mono.mass, a.mono.inertia, a.mono.inv_mass, a.mono.inv_inertia};
}

// Force and torque on a particle from a group of its contacts.
struct Load {
  Vec3 force, torque;
};

// Sets a flag that several threads may set at once (to the same value, so the result is
// deterministic).
PDSIM_HD void raise_flag(std::uint32_t* flag) {
#if defined(__CUDA_ARCH__)
  atomicOr(flag, 1u);
#else
  __atomic_store_n(flag, 1u, __ATOMIC_RELAXED);
#endif
}

// A contact's tangential history from its slot: zero unless `had` (the slot holds history).
// Read unconditionally (every slot holds finite doubles) and then selected: a masked load
// would keep GCC from vectorising the CPU batches.
PDSIM_HD Vec3 slot_history(const double* history, int slot, bool had) {
  const Vec3 xi = load3(history, slot);
  return had ? xi : Vec3{};
}

// The contact of particle i with the partner in its forward slot s, with tangential history
// xi (slot_history(); the new history out): its dissipation into the sums; returns its loads.
// One function for the CUDA threads' loop below and the CPU's SIMD batches; the callers move
// the history and the loads, so that the CPU can keep them in its batches.
template <class V>
PDSIM_HD ContactOutcome pair_contact(int i, int s, Vec3& xi, const ParticleStepArgs& a,
                                     Dissipation& dissipated) {
  const Body b = body<V>(i, a);
  const int j = a.neighbours[s];
  const Vec3 d{a.in.x[i] - a.in.x[j], a.in.y[i] - a.in.y[j], a.in.z[i] - a.in.z[j]};
  double radius_j, mass_eff, inv_mass_eff, inv_inertia_j;
  if constexpr (V::kPolydisperse) {
    radius_j = a.radius[j];
    inv_mass_eff = b.inv_mass + a.inv_mass[j];
    mass_eff = 1.0 / inv_mass_eff;
    inv_inertia_j = V::kRolling ? a.inv_inertia[j] : 0.0;
  } else {
    radius_j = b.radius;
    mass_eff = 0.5 * b.mass;
    inv_mass_eff = 2.0 * b.inv_mass;
    inv_inertia_j = b.inv_inertia;
  }
  const double reach = b.radius + radius_j;
  const double dist = sqrt(dot(d, d));
  const Vec3 normal = (1.0 / dist) * d;
  const Vec3 v{a.in.vx[i], a.in.vy[i], a.in.vz[i]};
  const Vec3 w{a.in.wx[i], a.in.wy[i], a.in.wz[i]};
  const Vec3 vj{a.in.vx[j], a.in.vy[j], a.in.vz[j]};
  const Vec3 wj{a.in.wx[j], a.in.wy[j], a.in.wz[j]};
  const Vec3 vrel = v - vj - cross(b.radius * w + radius_j * wj, normal);
  // The slot test and this distance may round differently (FMA contraction): an overlap
  // of a few ulp below zero is zero, not a NaN in the Hertz root.
  return contact<V>(max_of(reach - dist, 0.0), normal, vrel, w - wj, b.radius, radius_j,
                    b.radius * radius_j / reach, mass_eff, inv_mass_eff, b.inv_inertia,
                    inv_inertia_j, false, &xi, a.dt, a.contact, dissipated);
}

// A pair's loads in its forward slot s, for the partner to gather (slot_loads() reads them).
template <class V>
PDSIM_HD void store_slot_loads(int s, const ParticleStepArgs& a, const ContactOutcome& l) {
  double* slot = a.pair_load + pair_doubles<V>() * std::int64_t{s};
  store3(slot, 0, l.force);
  store3(slot, 1, l.torque);
  if constexpr (pair_doubles<V>() == 9) store3(slot, 2, l.partner_torque);
}
template <class V>
PDSIM_HD ContactOutcome slot_loads(int s, const ParticleStepArgs& a) {
  const double* slot = a.pair_load + pair_doubles<V>() * std::int64_t{s};
  return {load3(slot, 0), load3(slot, 1), load3(slot, pair_doubles<V>() == 9 ? 2 : 1)};
}

// Pair pass, contacts of particle i over the forward slots set in `touching` (CUDA): each
// pair's loads into its slot, and the partner marked.
template <class V>
PDSIM_HD void pair_contacts(int i, std::uint64_t touching, const ParticleStepArgs& a,
                            ParticleContribution& sum) {
  const int base = a.slot_start[i];
  std::uint64_t had = 0;
  if constexpr (V::Tangential::kHistory) had = a.history.neighbour_mask_in[i];
  for (std::uint64_t m = touching; m; m &= m - 1) {
    const int k = lowest_bit(m);
    Vec3 xi{};
    if constexpr (V::Tangential::kHistory)
      xi = slot_history(a.history.neighbour_in, base + k, had >> k & 1u);
    Dissipation dissipated;
    store_slot_loads<V>(base + k, a, pair_contact<V>(i, base + k, xi, a, dissipated));
    add_tallies(sum.tally, dissipated);
    if constexpr (V::Tangential::kHistory) store3(a.history.neighbour_out, base + k, xi);
    raise_flag(a.incoming + a.neighbours[base + k]);
  }
}

// Adds to `load` the loads on particle i of the pairs in contact that particles below
// `owner_limit` list, in reverse-list order, and clears its incoming flag.
template <class V>
PDSIM_COLD void add_incoming_loads(int i, int owner_limit, const ParticleStepArgs& a, Load& load) {
  a.incoming[i] = 0;
  const std::int32_t* reverse = a.reverse + a.reverse_start[i];
  for (int r = 0; r < a.reverse_count[i]; ++r) {
    const int owner = entry_owner(reverse[r]), k = entry_place(reverse[r]);
    if (owner < owner_limit && (a.history.neighbour_mask_out[owner] >> k & 1u)) {
      const ContactOutcome l = slot_loads<V>(a.slot_start[owner] + k, a);
      load.force -= l.force;
      load.torque += l.partner_torque;
    }
  }
}

// Particle pass (CUDA): the loads of particle i's pairs, own slots first, then the slots of
// the particles that list it, each in list order (so the sum does not depend on threads).
template <class V>
PDSIM_COLD Load pair_loads(int i, const ParticleStepArgs& a) {
  Load load;
  const int base = a.slot_start[i];
  for (std::uint64_t m = a.history.neighbour_mask_out[i]; m; m &= m - 1) {
    const ContactOutcome l = slot_loads<V>(base + lowest_bit(m), a);
    load.force += l.force;
    load.torque += l.torque;
  }
  if (a.incoming[i]) add_incoming_loads<V>(i, a.count, a, load);
  return load;
}

// The centre of particle i at x relative to the container centre, in the world frame and in
// the container frame.
template <class V>
PDSIM_HD void container_offset(Vec3 x, const ParticleStepArgs& a, Vec3& offset, Vec3& local) {
  offset = x - a.container.position;
  local = offset;
  if constexpr (V::kRotating)
    local = {dot(offset, a.container.axis_x), dot(offset, a.container.axis_y),
             dot(offset, a.container.axis_z)};
}

// The walls within `reach` of particle i's centre (near them: it passed the bounding test):
// f(slot, had, gap, normal) for each, `slot` its history's (held before this step when `had`),
// `gap` the centre's distance, `normal` in the world frame, pointing into the container. Marks
// the slots in the history's output mask. Flags a centre further than one radius outside the
// container, and a particle near more features of a mesh than it has slots.
template <class V, class F>
PDSIM_HOT void walls_within(int i, double reach, const ParticleStepArgs& a,
                            ParticleContribution& sum, F&& f) {
  using Shape = ShapeOf<V::kShape>;
  constexpr bool history = V::Tangential::kHistory;
  const double radius = V::kPolydisperse ? a.radius[i] : a.mono_radius;
  Vec3 offset, local;
  container_offset<V>({a.in.x[i], a.in.y[i], a.in.z[i]}, a, offset, local);
  const ContainerKinematics& box = a.container;
  auto world = [&](Vec3 n) {
    if constexpr (V::kRotating) return n.x * box.axis_x + n.y * box.axis_y + n.z * box.axis_z;
    return n;
  };
  // A centre further than one radius outside the container stops the run.
  auto escaped = [&](double beyond) {
    if (beyond > radius) sum.flags |= kEscaped;
  };
  std::uint8_t had = 0, touched = 0;
  if constexpr (history) had = a.history.wall_mask_in[i];
  if constexpr (!Shape::kKeyed) {
    auto wall = [&](int slot, double gap, Vec3 local_normal) {
      if (gap >= reach) return;
      touched = static_cast<std::uint8_t>(touched | (1u << slot));
      f(slot, (had >> slot & 1u) != 0, gap, world(local_normal));
    };
    Shape::walls(local, reach, a.geometry, wall, escaped);
  } else {
    // Features by key, each given the slot that held its key before (its history) or a free one.
    int key[kWallSlots], slot[kWallSlots];
    double gap[kWallSlots];
    Vec3 normal[kWallSlots];
    int n = 0;
    bool slots_held = true;  // more touched features than slots: the run stops
    const bool candidates_held = Shape::walls(
        local, reach, a.geometry,
        [&](int k, double g, Vec3 local_normal) {
          if (n == kWallSlots) {
            slots_held = false;
            return;
          }
          key[n] = k, gap[n] = g, normal[n] = local_normal, slot[n] = -1;
          ++n;
        },
        escaped, i);
    if (!slots_held || !candidates_held) sum.flags |= kWallOverflow;
    unsigned used = 0;
    if constexpr (history) {
      const std::int32_t* before = a.history.wall_key_in + i * kWallSlots;
      for (int c = 0; c < n; ++c)
        for (int s = 0; s < kWallSlots; ++s)
          if ((had >> s & 1u) && before[s] == key[c]) {
            slot[c] = s, used |= 1u << s;
            break;
          }
    }
    for (int c = 0; c < n; ++c) {
      const bool kept = slot[c] >= 0;
      if (!kept) {
        int s = 0;
        while (used >> s & 1u) ++s;
        slot[c] = s, used |= 1u << s;
      }
      if constexpr (history) a.history.wall_key_out[i * kWallSlots + slot[c]] = key[c];
      f(slot[c], kept, gap[c], world(normal[c]));
    }
    touched = static_cast<std::uint8_t>(used);
  }
  if constexpr (history) a.history.wall_mask_out[i] = touched;
}
// The walls particle i touches (within its radius), as walls_within().
template <class V, class F>
PDSIM_HD void touching_walls(int i, const ParticleStepArgs& a, ParticleContribution& sum, F&& f) {
  walls_within<V>(i, V::kPolydisperse ? a.radius[i] : a.mono_radius, a, sum, f);
}

// The contact of particle i with a wall at `gap` along `normal`, with tangential history xi
// (as in pair_contact()): its dissipation into the sums; returns its loads on the particle. One
// function for the CUDA threads and the CPU's SIMD batches.
template <class V>
PDSIM_HD Load wall_contact(int i, double gap, Vec3 normal, Vec3& xi, const ParticleStepArgs& a,
                           Dissipation& dissipated) {
  const Body b = body<V>(i, a);
  const Vec3 v{a.in.vx[i], a.in.vy[i], a.in.vz[i]};
  const Vec3 w{a.in.wx[i], a.in.wy[i], a.in.wz[i]};
  Vec3 v_wall_rel = v - a.container.velocity;
  Vec3 w_wall_rel = w;  // the spin relative to the container
  if constexpr (V::kRotating) {
    const Vec3 offset = Vec3{a.in.x[i], a.in.y[i], a.in.z[i]} - a.container.position;
    v_wall_rel -= cross(a.container.angular_velocity, offset);
    w_wall_rel -= a.container.angular_velocity;
  }
  const Vec3 vrel = v_wall_rel - cross(b.radius * w, normal);
  const auto out =
      contact<V>(b.radius - gap, normal, vrel, w_wall_rel, b.radius, 0.0, b.radius, b.mass,
                 b.inv_mass, b.inv_inertia, 0.0, true, &xi, a.dt, a.contact, dissipated);
  return {out.force, out.torque};
}

// The reaction of a wall contact's `force` on the container: force and torque about its centre
// (the force acts at the foot of the normal through the particle centre).
template <class V>
PDSIM_HD void add_wall_reaction(int i, double gap, Vec3 normal, Vec3 force,
                                const ParticleStepArgs& a, ParticleContribution& sum) {
  sum.wall_force -= force;
  if constexpr (V::kRotating) {
    const Vec3 offset = Vec3{a.in.x[i], a.in.y[i], a.in.z[i]} - a.container.position;
    sum.wall_torque -= cross(offset - gap * normal, force);
  }
}

// Contacts of particle i with the container walls, for a particle that passed the bounding
// test (CUDA). Adds the reaction on the container to `sum`.
template <class V>
PDSIM_HD Load wall_contacts(int i, const ParticleStepArgs& a, ParticleContribution& sum) {
  Load load;
  touching_walls<V>(i, a, sum, [&](int slot, bool had, double gap, Vec3 normal) {
    Vec3 xi{};
    if constexpr (V::Tangential::kHistory)
      xi = slot_history(a.history.wall_in, i * kWallSlots + slot, had);
    Dissipation dissipated;
    const Load l = wall_contact<V>(i, gap, normal, xi, a, dissipated);
    add_tallies(sum.tally, dissipated);
    if constexpr (V::Tangential::kHistory) store3(a.history.wall_out, i * kWallSlots + slot, xi);
    load.force += l.force;
    load.torque += l.torque;
    add_wall_reaction<V>(i, gap, normal, l.force, a, sum);
  });
  return load;
}

#if !defined(__CUDACC__) && defined(__GNUC__)
// Two slots' worth of doubles: one SSE2 register (GCC vector extensions).
using Double2 = double __attribute__((vector_size(2 * sizeof(double))));

// Bits 0 and 1 set when slots k and k + 1 of particle i's list (of n partners, padded to a
// multiple of kSlotGroup with the particle itself) overlap it, at x with `radius`. `dist_sq`
// receives the two squared centre distances (infinite for the padding).
template <class V>
inline int slot_group_hits(int i, Vec3 x, double radius, const ParticleStepArgs& a, int k, int n,
                           Double2& dist_sq) {
  static_assert(kSlotGroup == 2, "a group is one SSE2 pair");
  const std::int32_t* slots = a.neighbours + a.slot_start[i];
  const int j0 = slots[k], j1 = slots[k + 1];
  Double2 reach_sq = Double2{} + 4 * radius * radius;
  if constexpr (V::kPolydisperse) {
    reach_sq = radius + Double2{a.radius[j0], a.radius[j1]};
    reach_sq *= reach_sq;
  }
  const Double2 dx = x.x - Double2{a.in.x[j0], a.in.x[j1]};
  const Double2 dy = x.y - Double2{a.in.y[j0], a.in.y[j1]};
  const Double2 dz = x.z - Double2{a.in.z[j0], a.in.z[j1]};
  dist_sq = dx * dx + dy * dy + dz * dz;
  const auto hit = dist_sq < reach_sq;  // lanes: -1 or 0
#if defined(__SSE2__)
  const int hits = _mm_movemask_pd(reinterpret_cast<__m128d>(hit));
#else
  const int hits = static_cast<int>((hit[0] & 1) | (hit[1] & 2));
#endif
  if (k + 1 < n) return hits;
  dist_sq[1] = __builtin_inf();  // the padding is not a partner
  return hits & 1;
}
#endif

// Bit k set when neighbour slot k of particle i overlaps it. On the host, slots are tested
// kSlotGroup (an SSE2 pair) at a time. Groups of 2 test fewer padding slots than groups of 4
// in one AVX register: -4 % instructions at 196 spheres and -1 % at 8,000 (callgrind), where
// lists hold 2.5-2.9 partners. CUDA threads test one slot at a time.
template <class V>
PDSIM_HD std::uint64_t touching_slots(int i, Vec3 x, double radius, const ParticleStepArgs& a) {
  const int n = a.neighbour_count[i];
  std::uint64_t touching = 0;
#if defined(__CUDACC__) || !defined(__GNUC__)
  const std::int32_t* slots = a.neighbours + a.slot_start[i];
  for (int k = 0; k < n; ++k) {
    const int j = slots[k];
    const double dx = x.x - a.in.x[j], dy = x.y - a.in.y[j], dz = x.z - a.in.z[j];
    const double reach = V::kPolydisperse ? radius + a.radius[j] : 2 * radius;
    if (dx * dx + dy * dy + dz * dz < reach * reach) touching |= std::uint64_t{1} << k;
  }
#else
  Double2 dist_sq;
  for (int k = 0; k < n; k += kSlotGroup)
    touching |= static_cast<std::uint64_t>(slot_group_hits<V>(i, x, radius, a, k, n, dist_sq)) << k;
#endif
  return touching;
}

// Pair pass of particle i (one CUDA thread): which forward slots touch (most do not, so this
// test is kept minimal), and the loads of those pairs. Dissipation goes to `sum`.
template <class V>
PDSIM_HD void pair_pass(int i, const ParticleStepArgs& a, ParticleContribution& sum) {
  const double radius = V::kPolydisperse ? a.radius[i] : a.mono_radius;
  const std::uint64_t touching = touching_slots<V>(i, {a.in.x[i], a.in.y[i], a.in.z[i]}, radius, a);
  a.history.neighbour_mask_out[i] = touching;
  if (touching) pair_contacts<V>(i, touching, a, sum);
}

// Bounding test of particle i against the container walls (a centre outside the container
// passes too, for the guard).
template <class V>
PDSIM_HOT bool near_wall(int i, const ParticleStepArgs& a) {
  const double radius = V::kPolydisperse ? a.radius[i] : a.mono_radius;
  Vec3 offset, local;
  container_offset<V>({a.in.x[i], a.in.y[i], a.in.z[i]}, a, offset, local);
  return ShapeOf<V::kShape>::near(local, radius, a.geometry);
}

// Which loads particle i has to gather: bit kPairLoads for pairs in contact, kWallLoads for
// walls near. Most particles have none, so this test and the integration below are all they
// cost.
constexpr int kPairLoads = 1, kWallLoads = 2;
template <class V>
PDSIM_HOT int load_kinds(int i, const ParticleStepArgs& a) {
  const bool pairs = (a.history.neighbour_mask_out[i] != 0) | (a.incoming[i] != 0);
  return (pairs ? kPairLoads : 0) | (near_wall<V>(i, a) ? kWallLoads : 0);
}

// Loads of particle i of the given kinds (not 0): its pairs' (in a fixed order) and the
// walls'. Wall contacts add their reactions to `sum`.
template <class V>
PDSIM_HD Load contact_loads(int i, int kinds, const ParticleStepArgs& a,
                            ParticleContribution& sum) {
  Load load;
  if (kinds & kPairLoads) load = pair_loads<V>(i, a);
  if (kinds & kWallLoads) {
    const Load walls = wall_contacts<V>(i, a, sum);
    load.force += walls.force;
    load.torque += walls.torque;
  }
  return load;
}

// Semi-implicit Euler (symplectic) of particle i under `load`; adds its kinetic energy and
// takes the largest squared speed.
template <class V>
PDSIM_HOT void integrate(int i, const ParticleStepArgs& a, const Load& load, double& kinetic,
                         double& speed_sq_max) {
  const Body b = body<V>(i, a);
  const Vec3 x{a.in.x[i], a.in.y[i], a.in.z[i]};
  const Vec3 v{a.in.vx[i], a.in.vy[i], a.in.vz[i]};
  const Vec3 w{a.in.wx[i], a.in.wy[i], a.in.wz[i]};
  Vec3 accel = b.inv_mass * load.force;
  if constexpr (V::kGravity) accel += a.gravity;
  const Vec3 v_new = v + a.dt * accel;
  const Vec3 x_new = x + a.dt * v_new;
  const Vec3 w_new = w + (a.dt * b.inv_inertia) * load.torque;
  a.out.x[i] = x_new.x;
  a.out.y[i] = x_new.y;
  a.out.z[i] = x_new.z;
  a.out.vx[i] = v_new.x;
  a.out.vy[i] = v_new.y;
  a.out.vz[i] = v_new.z;
  a.out.wx[i] = w_new.x;
  a.out.wy[i] = w_new.y;
  a.out.wz[i] = w_new.z;
  const double speed_sq = dot(v_new, v_new);
  kinetic += 0.5 * (b.mass * speed_sq + b.inertia * dot(w_new, w_new));
  speed_sq_max = max_of(speed_sq_max, speed_sq);
}

// Particle pass of particle i (one CUDA thread): its loads, then the integration.
template <class V>
PDSIM_HD void particle_pass(int i, const ParticleStepArgs& a, ParticleContribution& sum) {
  if constexpr (V::Tangential::kHistory) a.history.wall_mask_out[i] = 0;
  const int kinds = load_kinds<V>(i, a);
  integrate<V>(i, a, kinds ? contact_loads<V>(i, kinds, a, sum) : Load{}, sum.kinetic,
               sum.speed_sq);
}

}  // namespace pdsim

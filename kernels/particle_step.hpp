// One DEM step of one particle, written once for the CPU and CUDA backends: gather the
// contact forces from the neighbour list and the container walls, then integrate
// (semi-implicit Euler, fused into the force pass; state is double buffered so every particle
// reads t_n and writes t_{n+1}, and a step can be re-run from the same input for tight coupling).
// Each particle computes its own half of every pair, so no atomics are needed and the result
// does not depend on the thread count; the pair forces are antisymmetric to the last bit.
#pragma once

#include <cstdint>

#include "kernels/contact_tangential.hpp"

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

// Live contact-history slots are marked in bit masks, so that absent contacts cost no memory
// traffic (a slot is read only when its bit is set in the input mask).
struct HistoryArrays {
  const double* neighbour_in;  // count x max_neighbours x 3
  double* neighbour_out;
  const std::uint64_t* neighbour_mask_in;
  std::uint64_t* neighbour_mask_out;
  const double* wall_in;  // count x kWallSlots x 3
  double* wall_out;
  const std::uint8_t* wall_mask_in;
  std::uint8_t* wall_mask_out;
};

// The history pointers of a step: read `in`, write `out` (either backend's buffers).
template <class In, class Out>
HistoryArrays history_view(const In& in, Out& out) {
  return {in.neighbour.data(),       out.neighbour.data(), in.neighbour_mask.data(),
          out.neighbour_mask.data(), in.wall.data(),       out.wall.data(),
          in.wall_mask.data(),       out.wall_mask.data()};
}

struct ParticleStepArgs {
  int count;
  double dt;
  ParticleArrays in, out;
  const double* radius;       // polydisperse only
  const double* inv_mass;     // polydisperse only
  const double* inv_inertia;  // polydisperse only
  double mono_radius, mono_inv_mass, mono_inv_inertia;
  const std::int32_t* neighbours;  // count x max_neighbours partner indices
  const std::int32_t* neighbour_count;
  int max_neighbours;
  HistoryArrays history;
  const double *x_build, *y_build, *z_build;  // positions at the last neighbour-list build
  ContactParams contact;
  ContainerGeometry geometry;
  ContainerKinematics container;
  Vec3 gravity;  // m/s^2
};

// What one particle adds to the step totals (reduced by the launcher in a fixed order).
struct ParticleContribution {
  Vec3 wall_force;   // on the container
  Vec3 wall_torque;  // on the container, about its centre (Rotating variants only)
  double dissipated_normal = 0, dissipated_tangential = 0, kinetic = 0, drift_sq = 0;
  int flags = 0;
};

PDSIM_HD void accumulate(ParticleContribution& sum, const ParticleContribution& c) {
  sum.wall_force += c.wall_force;
  sum.wall_torque += c.wall_torque;
  sum.dissipated_normal += c.dissipated_normal;
  sum.dissipated_tangential += c.dissipated_tangential;
  sum.kinetic += c.kinetic;
  sum.drift_sq = max_of(sum.drift_sq, c.drift_sq);
  sum.flags |= c.flags;
}

PDSIM_HD Vec3 load3(const double* a, int k) {
  return {a[3 * k], a[3 * k + 1], a[3 * k + 2]};
}
PDSIM_HD void store3(double* a, int k, Vec3 v) {
  a[3 * k] = v.x;
  a[3 * k + 1] = v.y;
  a[3 * k + 2] = v.z;
}

// Force and torque of one contact on the particle. `normal` points from the other body to this
// particle; `vrel` is the velocity of this particle's contact point relative to the other's.
struct ContactOutcome {
  Vec3 force, torque;
};

template <class V>
PDSIM_HD ContactOutcome contact(double overlap, Vec3 normal, Vec3 vrel, Vec3 omega_rel,
                                double radius, double radius_eff, double mass_eff, bool wall,
                                Vec3* history, double dt, const ContactParams& p, double share,
                                double& dissipated_normal, double& dissipated_tangential) {
  const NormalResponse r = V::Normal::respond(overlap, radius_eff, mass_eff, wall, p);
  const double vn = dot(vrel, normal);
  const Vec3 vt = vrel - vn * normal;
  const double fn = r.elastic - r.damping * vn;
  dissipated_normal += share * r.damping * vn * vn * dt;
  double tangential_loss = 0;
  const Vec3 ft = V::Tangential::force(history, normal, vt, r, fn, dt, p, tangential_loss);
  dissipated_tangential += share * tangential_loss;
  ContactOutcome out{fn * normal + ft, cross(-radius * normal, ft)};
  if constexpr (V::kRolling) {
    // Constant directional rolling resistance: |T| = mu_r R* |Fn| against the relative spin.
    const double spin = norm(omega_rel);
    const double scale = p.rolling_friction * radius_eff * fabs(fn) / max_of(spin, 1e-6);
    out.torque -= scale * omega_rel;
  }
  return out;
}

template <class V>
PDSIM_HD ParticleContribution step_particle(int i, const ParticleStepArgs& a) {
  const Vec3 x{a.in.x[i], a.in.y[i], a.in.z[i]};
  const Vec3 v{a.in.vx[i], a.in.vy[i], a.in.vz[i]};
  const Vec3 w{a.in.wx[i], a.in.wy[i], a.in.wz[i]};
  double radius, inv_mass, inv_inertia;
  if constexpr (V::kPolydisperse) {
    radius = a.radius[i];
    inv_mass = a.inv_mass[i];
    inv_inertia = a.inv_inertia[i];
  } else {
    radius = a.mono_radius;
    inv_mass = a.mono_inv_mass;
    inv_inertia = a.mono_inv_inertia;
  }
  const double mass = 1.0 / inv_mass;
  constexpr bool kHistory = V::Tangential::kHistory;
  ParticleContribution c;
  Vec3 force, torque;

  // Particle-particle contacts over the neighbour list.
  const int base = i * a.max_neighbours;
  const int n_count = a.neighbour_count[i];
  std::uint64_t mask_out = 0;
  std::uint64_t mask_in = 0;
  if constexpr (kHistory) mask_in = a.history.neighbour_mask_in[i];
  for (int k = 0; k < n_count; ++k) {
    const int j = a.neighbours[base + k];
    const Vec3 d{x.x - a.in.x[j], x.y - a.in.y[j], x.z - a.in.z[j]};
    double radius_j, mass_eff;
    if constexpr (V::kPolydisperse) {
      radius_j = a.radius[j];
      mass_eff = 1.0 / (inv_mass + a.inv_mass[j]);
    } else {
      radius_j = radius;
      mass_eff = 0.5 * mass;
    }
    const double reach = radius + radius_j;
    const double dist_sq = dot(d, d);
    if (dist_sq >= reach * reach) continue;
    const double dist = sqrt(dist_sq);
    const Vec3 normal = (1.0 / dist) * d;
    const Vec3 vj{a.in.vx[j], a.in.vy[j], a.in.vz[j]};
    const Vec3 wj{a.in.wx[j], a.in.wy[j], a.in.wz[j]};
    const Vec3 vrel = v - vj - cross(radius * w + radius_j * wj, normal);
    Vec3 xi{};
    if constexpr (kHistory) {
      if (mask_in >> k & 1u) xi = load3(a.history.neighbour_in, base + k);
    }
    const auto out =
        contact<V>(reach - dist, normal, vrel, w - wj, radius, radius * radius_j / reach, mass_eff,
                   false, &xi, a.dt, a.contact, 0.5, c.dissipated_normal, c.dissipated_tangential);
    if constexpr (kHistory) {
      store3(a.history.neighbour_out, base + k, xi);
      mask_out |= std::uint64_t{1} << k;
    }
    force += out.force;
    torque += out.torque;
  }
  if constexpr (kHistory) a.history.neighbour_mask_out[i] = mask_out;

  // Container walls, in the container frame. A cheap bounding test per axis skips the walls of
  // particles away from them.
  const ContainerKinematics& box = a.container;
  const Vec3 offset = x - box.position;
  Vec3 local = offset;
  Vec3 v_wall_rel = v - box.velocity;
  if constexpr (V::kRotating) {
    local = {dot(offset, box.axis_x), dot(offset, box.axis_y), dot(offset, box.axis_z)};
    v_wall_rel -= cross(box.angular_velocity, offset);  // wall velocity at the particle
  }
  const Vec3 h = a.geometry.half_size;
  Vec3 wall_force;
  std::uint8_t wall_mask_in = 0, wall_mask_out = 0;
  if constexpr (kHistory) wall_mask_in = a.history.wall_mask_in[i];
  auto wall = [&](int slot, double gap, Vec3 local_normal) {
    if (gap >= radius) return;
    Vec3 normal = local_normal;
    if constexpr (V::kRotating)
      normal =
          local_normal.x * box.axis_x + local_normal.y * box.axis_y + local_normal.z * box.axis_z;
    Vec3 xi{};
    if constexpr (kHistory) {
      if (wall_mask_in >> slot & 1u) xi = load3(a.history.wall_in, i * kWallSlots + slot);
    }
    const Vec3 vrel = v_wall_rel - cross(radius * w, normal);
    const auto out = contact<V>(radius - gap, normal, vrel, w, radius, radius, mass, true, &xi,
                                a.dt, a.contact, 1.0, c.dissipated_normal, c.dissipated_tangential);
    if constexpr (kHistory) {
      store3(a.history.wall_out, i * kWallSlots + slot, xi);
      wall_mask_out = static_cast<std::uint8_t>(wall_mask_out | (1u << slot));
    }
    wall_force += out.force;
    torque += out.torque;
    // The force acts on the wall at the foot of the normal through the particle centre.
    if constexpr (V::kRotating) c.wall_torque -= cross(offset - gap * normal, out.force);
  };
  double escape;  // how far outside the container the centre may go before the run stops
  if constexpr (V::kShape == WallShape::box) {
    if (fabs(local.x) > h.x - radius) {
      wall(0, local.x + h.x, {1, 0, 0});
      wall(1, h.x - local.x, {-1, 0, 0});
    }
    if (fabs(local.y) > h.y - radius) {
      wall(2, local.y + h.y, {0, 1, 0});
      wall(3, h.y - local.y, {0, -1, 0});
    }
    escape = max_of(fabs(local.x) - h.x, fabs(local.y) - h.y);
  } else {
    const double rho_sq = local.x * local.x + local.y * local.y;
    const double inner = a.geometry.radius - radius;
    if (rho_sq > inner * inner) {
      const double rho = sqrt(rho_sq);
      wall(0, a.geometry.radius - rho, {-local.x / rho, -local.y / rho, 0});
    }
    escape = sqrt(rho_sq) - a.geometry.radius;
  }
  if (fabs(local.z) > h.z - radius) {
    wall(4, local.z + h.z, {0, 0, 1});
    wall(5, h.z - local.z, {0, 0, -1});
  }
  escape = max_of(escape, fabs(local.z) - h.z);
  if constexpr (kHistory) a.history.wall_mask_out[i] = wall_mask_out;
  force += wall_force;
  c.wall_force = -wall_force;

  // Semi-implicit Euler (symplectic), fused into the force pass.
  Vec3 accel = inv_mass * force;
  if constexpr (V::kGravity) accel += a.gravity;
  const Vec3 v_new = v + a.dt * accel;
  const Vec3 x_new = x + a.dt * v_new;
  const Vec3 w_new = w + (a.dt * inv_inertia) * torque;
  a.out.x[i] = x_new.x;
  a.out.y[i] = x_new.y;
  a.out.z[i] = x_new.z;
  a.out.vx[i] = v_new.x;
  a.out.vy[i] = v_new.y;
  a.out.vz[i] = v_new.z;
  a.out.wx[i] = w_new.x;
  a.out.wy[i] = w_new.y;
  a.out.wz[i] = w_new.z;

  c.kinetic = 0.5 * mass * dot(v_new, v_new) + 0.5 / inv_inertia * dot(w_new, w_new);
  const Vec3 drift{x_new.x - a.x_build[i], x_new.y - a.y_build[i], x_new.z - a.z_build[i]};
  c.drift_sq = dot(drift, drift);
  if (!(fabs(x_new.x) + fabs(x_new.y) + fabs(x_new.z) + fabs(c.kinetic) < 1e300))
    c.flags |= kNonFinite;
  if (escape > radius) c.flags |= kEscaped;
  return c;
}

}  // namespace pdsim

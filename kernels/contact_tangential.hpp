// Tangential contact laws, chosen per scene as a template tag. `force` returns the tangential
// force on the particle and adds the energy it dissipates in the step to `dissipated`.
#pragma once

#include "kernels/contact_normal.hpp"

namespace pdsim {

struct NoTangential {
  static constexpr const char* name = "none";
  static constexpr bool kHistory = false;
  PDSIM_HD static Vec3 force(Vec3*, Vec3, Vec3, const NormalResponse&, double, double,
                             const ContactParams&, double&) {
    return {};
  }
};

// Directional Coulomb (Saeki 2002; PMB): Ft = -mu |Fn| vt/|vt|, sliding only. Below
// `slip_velocity` the direction is regularised (viscous) so that resting contacts do not chatter.
struct DirectionalCoulomb {
  static constexpr const char* name = "directional";
  static constexpr bool kHistory = false;
  PDSIM_HD static Vec3 force(Vec3*, Vec3, Vec3 vt, const NormalResponse&, double normal_force,
                             double dt, const ContactParams& p, double& dissipated) {
    const double speed = norm(vt);
    const double scale = p.friction * fabs(normal_force) / max_of(speed, p.slip_velocity);
    dissipated += scale * speed * speed * dt;
    return -scale * vt;
  }
};

// Mindlin spring with history, capped by Coulomb: the elastic displacement xi lives with the
// contact, is rotated into the current tangent plane every step and rescaled when sliding
// (the LAMMPS gran/hooke/history treatment).
struct MindlinHistory {
  static constexpr const char* name = "history";
  static constexpr bool kHistory = true;
  PDSIM_HD static Vec3 force(Vec3* xi, Vec3 normal, Vec3 vt, const NormalResponse& r,
                             double normal_force, double dt, const ContactParams& p,
                             double& dissipated) {
    // Project the stored displacement into the current tangent plane, keeping its length.
    Vec3 s = *xi;
    const double old_sq = dot(s, s);
    const double off_plane = dot(s, normal);
    if (off_plane != 0.0) {
      s -= off_plane * normal;
      const double new_sq = dot(s, s);
      if (new_sq > 0) s = sqrt(old_sq / new_sq) * s;
    }
    const double stored_before = 0.5 * r.tangent_stiffness * old_sq;
    s += dt * vt;
    Vec3 f = -r.tangent_stiffness * s - r.tangent_damping * vt;
    const double f_sq = dot(f, f);
    const double f_max = p.friction * fabs(normal_force);
    if (f_sq > f_max * f_max) {
      const double ratio = f_max / sqrt(f_sq);
      if (r.tangent_stiffness > 0) {
        const Vec3 damped = (r.tangent_damping / r.tangent_stiffness) * vt;
        s = ratio * (s + damped) - damped;
      }
      f = ratio * f;
    }
    *xi = s;
    // Work taken from the contact minus what the spring stores (Mindlin's kt varies with the
    // overlap, so this is the usual incremental estimate).
    dissipated += -dot(f, vt) * dt - (0.5 * r.tangent_stiffness * dot(s, s) - stored_before);
    return f;
  }
};

}  // namespace pdsim

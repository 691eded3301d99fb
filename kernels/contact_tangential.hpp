// Tangential contact laws, chosen per scene as a template tag. `force` returns the tangential
// force on the particle and adds to `d` the energy its dissipative elements take out in the
// step (d.tangential) and, for a law with history, its spring's energies (kernels/tallies.hpp).
//
// The particles advance by semi-implicit Euler (particle_step.hpp: v' = v + dt F/m, then
// x' = x + dt v'), a leapfrog whose stored velocity v is the one of the half step before the
// position x. The force computed at x acts while the body moves from the midpoint of the
// previous step to the midpoint of this one, a displacement dt (v + v')/2; that is the
// displacement over which a force's work changes the kinetic energy 1/2 m v^2 exactly, and
// over which an undamped spring conserves the leapfrog energy 1/2 k x_prev x. So a dashpot's
// work is counted at the mid-step velocity, with v' predicted from this contact's own force and
// effective mass: exact for a contact alone on its bodies, O(dt^2) per step otherwise.
#pragma once

#include "kernels/contact_normal.hpp"
#include "kernels/tallies.hpp"

namespace pdsim {

// Work of the dissipative force `f_damp` over the step, at the mid-step relative velocity
// v + dt f / (2 m) of a contact whose total force is `f` (see above).
PDSIM_HD double damper_work(Vec3 f_damp, Vec3 v, Vec3 f, double inv_mass, double dt) {
  return -dot(f_damp, v + (0.5 * dt * inv_mass) * f) * dt;
}

struct NoTangential {
  static constexpr const char* name = "none";
  static constexpr bool kHistory = false;
  template <class Spec>
  static MissingKey missing(const Spec&) {
    return {};
  }
  PDSIM_HD static Vec3 force(Vec3*, Vec3, Vec3, const NormalResponse&, double, double, double,
                             const ContactParams&, Dissipation&) {
    return {};
  }
};

// Directional Coulomb (Saeki 2002; PMB): Ft = -mu |Fn| vt/|vt|, sliding only. Where that force
// would reverse the slip within the step (tangent mass m_t, see contact()), it is the force that
// stops it, m_t vt / dt: the slip never changes sign, and a contact at rest stays at rest, at
// any dt (an explicit viscous regularisation below a slip speed is unstable once
// mu |Fn| dt / (m_t v_s) > 2).
struct DirectionalCoulomb {
  static constexpr const char* name = "directional";
  static constexpr bool kHistory = false;
  template <class Spec>
  static MissingKey missing(const Spec&) {
    return {};
  }
  PDSIM_HD static Vec3 force(Vec3*, Vec3, Vec3 vt, const NormalResponse&, double normal_force,
                             double tangent_mass, double dt, const ContactParams& p,
                             Dissipation& d) {
    const double speed = norm(vt);
    const double coulomb = p.friction * fabs(normal_force);
    const double stop = tangent_mass / dt;
    // Selected, not branched: at speed 0 the division gives inf (or NaN) that is not taken.
    const double scale = coulomb < stop * speed ? coulomb / speed : stop;
    const Vec3 f = -scale * vt;
    d.tangential += damper_work(f, vt, f, 1.0 / tangent_mass, dt);
    return f;
  }
};

// Mindlin spring with history, capped by Coulomb: the elastic displacement xi lives with the
// contact, is rotated into the current tangent plane every step and rescaled when sliding
// (the LAMMPS gran/hooke/history treatment).
struct MindlinHistory {
  static constexpr const char* name = "history";
  static constexpr bool kHistory = true;
  // The tangential stiffness needs G* = f(E, nu), with a linear normal law too.
  template <class Spec>
  static MissingKey missing(const Spec& c) {
    return c.young == 0 ? MissingKey{"young", "a positive number (Pa)"} : MissingKey{};
  }
  PDSIM_HD static Vec3 force(Vec3* xi, Vec3 normal, Vec3 vt, const NormalResponse& r,
                             double normal_force, double tangent_mass, double dt,
                             const ContactParams& p, Dissipation& d) {
    // Project the stored displacement into the current tangent plane, keeping its length.
    Vec3 s = *xi;
    const double old_sq = dot(s, s);
    d.spring_in += 0.5 * r.tangent_stiffness * old_sq;
    const double off_plane = dot(s, normal);
    if (off_plane != 0.0) {
      s -= off_plane * normal;
      const double new_sq = dot(s, s);
      if (new_sq > 0) s = sqrt(old_sq / new_sq) * s;
    }
    const Vec3 s_before = s;
    s += dt * vt;
    Vec3 f_damp = -r.tangent_damping * vt;
    Vec3 f = -r.tangent_stiffness * s + f_damp;
    const double f_sq = dot(f, f);
    const double f_max = p.friction * fabs(normal_force);
    if (f_sq > f_max * f_max) {
      const double ratio = f_max / sqrt(f_sq);
      if (r.tangent_stiffness > 0) {
        const Vec3 trial = s;
        const Vec3 damped = (r.tangent_damping / r.tangent_stiffness) * vt;
        s = ratio * (s + damped) - damped;
        // The spring energy the cap discards, in the leapfrog energy 1/2 kt s_prev . s that an
        // undamped stuck spring conserves: 1/2 kt (trial - s) . (s + s_before).
        d.tangential += 0.5 * r.tangent_stiffness * dot(trial - s, s + s_before);
      } else {
        f_damp = ratio * f_damp;  // no spring: the whole force is the dashpot's
      }
      f = ratio * f;
    }
    *xi = s;
    d.tangential += damper_work(f_damp, vt, f, 1.0 / tangent_mass, dt);
    // Computed here, where s is at hand: the same terms in contact() cost 15-25 % of a step.
    const double spring = 0.5 * r.tangent_stiffness * dot(s, s);
    d.spring_out += spring;
    d.elastic += spring - 0.5 * r.tangent_stiffness * dt * dot(s, vt);  // 1/2 kt s . (s - dt vt)
    return f;
  }
};

// Every tangential law, in the order of TangentialModel; a new one is its struct above (or its
// header, included here), a name and a line.
enum class TangentialModel { none, directional, history };
using TangentialLaws = std::tuple<NoTangential, DirectionalCoulomb, MindlinHistory>;

template <class F>
auto with_tangential_law(TangentialModel m, F&& f) {
  return with_type<TangentialLaws>(m, f);
}

}  // namespace pdsim

// Non-smooth (rigid) contacts: each step one cone complementarity problem over the contacts'
// impulses, the time-stepping of Anitescu and Tasora (Comput. Optim. Appl. 47, 2010) that
// Chrono::NSC uses, solved by the accelerated projected gradient of Mazhar et al. (ACM TOG 34,
// 2015). Spheres are rigid: no stiffness sets the step, only how far a body moves in one.
// What a contact is, what it asks of the step and how its impulse is bounded are written here
// once, for both backends (host/device); the CPU solver is kernels/cpu/nonsmooth_cpu.cpp.
//
// A contact of particle i with a partner j (or a wall) has the normal n from j to i, two
// tangents t1 and t2, and arms -r_i n and r_j n from the centres to the contact point. Its
// relative velocity u = (v_i + w_i x (-r_i n)) - (v_j + w_j x (r_j n)) - w (w: a wall's
// velocity there) in the frame (n, t1, t2). The step is v+ = v + dt g + M^-1 J^T gamma, with
// gamma in the friction cone |gamma_t| <= mu gamma_n and gamma the minimiser of
// 1/2 gamma.N gamma + r.gamma over the cones (N = J M^-1 J^T, r = J (v + dt g) - w - b e_n),
// whose optimality is the complementarity gamma_n >= 0, u+_n + mu |u+_t| >= b, one of them
// zero, and the friction opposing the slip: Coulomb's law, save that a sliding contact leaves
// at mu |u_t| faster than b (the convex relaxation's price; it vanishes when nothing slides).
#pragma once

#include "kernels/dem_types.hpp"

namespace pdsim {

// A non-smooth scene's constants (the deck's [contact] with model = "nonsmooth").
struct NonsmoothParams {
  double restitution = 0.6;   // Newton's: a contact that closes leaves at e times its approach
  double friction = 0;        // Coulomb coefficient
  double rest_speed = 0;      // m/s: contacts approaching slower than this end at rest
  double recovery_speed = 0;  // m/s: the fastest an overlap is pushed out
  double envelope = 0;        // m: pairs and walls within this gap enter a step's problem
  double tolerance = 0;       // m/s: the largest violation of a contact's velocity condition
  int max_iterations = 0;     // per step
};

// A scene's constants where its particles move at most `speed` (m/s) with step dt (s) under
// gravity g (m/s^2, its norm): pairs closing at twice that enter a step; contacts approaching
// slower than twice what gravity adds in a step (without gravity 1e-3 of the speed) end at
// rest, and overlaps recover at that speed; velocities are met to it (slower motion is rest:
// a tenth of it took 2.8x the iterations on the shaken Saeki pile, 62 against 22 a step).
// A scene lowers the tolerance to a tenth of its containers' speed where that is slower, and
// the deck's keys replace these where given (src/scene.cpp).
inline NonsmoothParams nonsmooth_params(double restitution, double friction, double speed,
                                        double dt, double g) {
  NonsmoothParams p;
  p.restitution = restitution;
  p.friction = friction;
  p.envelope = 2 * speed * dt;
  p.rest_speed = g > 0 ? 2 * g * dt : 1e-3 * speed;
  p.recovery_speed = p.rest_speed;
  p.tolerance = p.rest_speed;
  p.max_iterations = 300;
  return p;
}

// The kernel variants' laws: the normal law's name, and whether contacts have friction (three
// impulse rows a contact, or one). The impulses of the last step are each contact's history
// (its warm start), so both keep it.
struct NonsmoothNormal {
  static constexpr const char* name = "nonsmooth";
};
struct ConeFriction {
  static constexpr const char* name = "coulomb";
  static constexpr bool kHistory = true;
  static constexpr int kRows = 3;
};
struct NoFriction {
  static constexpr const char* name = "frictionless";
  static constexpr bool kHistory = true;
  static constexpr int kRows = 1;
};

// Two unit tangents completing the unit normal n to a right-handed frame.
PDSIM_HD void tangent_frame(Vec3 n, Vec3& t1, Vec3& t2) {
  // Across the normal's smallest component, so that the cross product never degenerates.
  const Vec3 a = fabs(n.x) < 0.57735   ? Vec3{1, 0, 0}
                 : fabs(n.y) < 0.57735 ? Vec3{0, 1, 0}
                                       : Vec3{0, 0, 1};
  const Vec3 c = cross(n, a);
  t1 = (1.0 / norm(c)) * c;
  t2 = cross(n, t1);
}

// The normal speed a contact at `gap` (m; negative: overlapping), approaching at `approach`
// (its normal relative speed at the step's start, negative when closing), must leave with:
// a contact that closes within the step at more than the rest speed rebounds at e times that
// speed (Newton); any other may close its gap and no more; an overlap is pushed out at most
// at the recovery speed.
PDSIM_HD double target_speed(double gap, double approach, double dt, const NonsmoothParams& p) {
  const double closing = gap >= 0 ? -gap / dt : fmin(-gap / dt, p.recovery_speed);
  const bool impact = approach < -p.rest_speed && gap + dt * approach <= 0;
  return impact ? max_of(-p.restitution * approach, closing) : closing;
}

// The impulse gamma = (normal, t1, t2) projected on the cone |gamma_t| <= mu gamma_n (the
// nearest point of the cone).
PDSIM_HD void project_cone(double& gn, double& g1, double& g2, double mu) {
  const double gt = sqrt(g1 * g1 + g2 * g2);
  if (gt <= mu * gn) return;
  if (mu * gt <= -gn) {
    gn = g1 = g2 = 0;
    return;
  }
  const double n = (gn + mu * gt) / (1 + mu * mu);
  const double scale = mu * n / gt;
  gn = n, g1 *= scale, g2 *= scale;
}

}  // namespace pdsim

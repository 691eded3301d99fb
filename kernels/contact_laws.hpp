// The contact laws (normal: contact_normal.hpp; tangential: contact_tangential.hpp) and the
// deck's words for them, from which the scene derives the kernels' constants and time step.
#pragma once

#include "kernels/contact_tangential.hpp"

namespace pdsim {

// The deck's [contact]: the same material for particle-particle and particle-wall contacts.
struct ContactSpec {
  NormalModel model = NormalModel::hertz;
  TangentialModel tangential = TangentialModel::history;
  double young = 0;  // Pa
  double poisson = 0.3;
  double restitution = 0.6;     // (0, 1]
  double friction = 0.0;        // Coulomb coefficient
  double stiffness = 0;         // N/m, linear model normal stiffness (required for `linear`)
  double rolling_friction = 0;  // dimensionless rolling resistance coefficient (0 = off)
  // model = "nonsmooth": rigid contacts (kernels/nonsmooth.hpp) instead of `model`'s law; 0 =
  // the default the scene derives.
  bool nonsmooth = false;
  double tolerance = 0;       // m/s, the impulse solver's
  int max_iterations = 0;     // per step
  double rest_speed = 0;      // m/s
  double recovery_speed = 0;  // m/s
};

}  // namespace pdsim

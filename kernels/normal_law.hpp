// What every normal contact law gives: the kernels' response of a contact, and on the host the
// time step it asks for and the deck keys it needs (the laws: kernels/contact_normal.hpp).
#pragma once

#include "kernels/dem_types.hpp"

namespace pdsim {

struct NormalResponse {
  double elastic;            // N, repulsive elastic force
  double damping;            // N s/m, normal damping coefficient (Fn = elastic - damping * vn)
  double tangent_stiffness;  // N/m, Mindlin or linear tangential spring
  double tangent_damping;    // N s/m
};

// The time step a law asks for: dt = safety x basis_time, no longer than dt_limit.
struct TimeStepRule {
  double contact_time = 0;        // s, of a binary impact (pdsim check)
  double rayleigh_time = 0;       // s, 0 when the law has none
  double basis_time = 0;          // s, the time dt is a fraction of
  const char* basis = "";         // what that time is ("Rayleigh time")
  double default_safety = 0;      // the fraction when solver.dt_safety is not given
  double dt_limit = 0;            // s, the stability limit of an explicit dt
  const char* contact_note = "";  // how contact_time was taken, for pdsim check
};

// A deck key a law cannot run without: nullptr key when all are given.
struct MissingKey {
  const char* key = nullptr;
  const char* expected = "";
};

}  // namespace pdsim

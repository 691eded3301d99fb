// What a structural model is built from, as plain values (SI units): the deck parser fills
// them, the scene hands them to build_structure(). No Eigen here, so that the deck does not
// compile against it.
#pragma once

#include <array>
#include <functional>
#include <optional>
#include <string>

#include "kernels/errors.hpp"
#include "kernels/vec3.hpp"

namespace pdsim {

enum class StructureKind { none, sdof, beam };
enum class Support { clamped, pinned, free };
enum class IntegratorKind { exact, cvode };

struct BeamSpec {
  double length = 0;  // m
  int elements = 0;
  double young = 0;           // Pa
  double density = 0;         // kg/m^3
  double poisson = 0.3;       // for the Timoshenko shear modulus
  double area = 0;            // m^2, from `section`
  double inertia = 0;         // m^4, second moment about the bending axis
  double shear_factor = 0;    // Timoshenko shear coefficient (5/6 rectangle, 0.9 circle)
  double section_height = 0;  // m, section depth along `direction` (0 = not given)
  bool timoshenko = false;
  Vec3 axis{1, 0, 0};  // unit, along the beam; a damper turns about axis x direction
  Support start = Support::clamped;
  Support end = Support::free;
};

struct StructureSpec {
  StructureKind kind = StructureKind::none;
  // sdof
  double mass = 0;           // kg
  double stiffness = 0;      // N/m
  double damping = 0;        // N s/m (sdof: resolved from damping_ratio when that is given)
  double damping_ratio = 0;  // sdof: of the bare system; beam: modal damping ratio on every mode
  std::optional<std::array<double, 2>> rayleigh;  // beam: C = alpha M + beta K
  Vec3 direction{1, 0, 0};  // unit; sdof: motion direction; beam: bending direction ([0,0,1])
  BeamSpec beam;
  IntegratorKind integrator = IntegratorKind::exact;
  int modes = 0;  // beam: keep the first N modes (0 = full model)
};

// Where a damper is bolted to a beam: node `node`, or the node nearest to `x` (m) when given.
struct Mount {
  int node = -1;
  std::optional<double> x;
};

// A key's place in the input, so that the structure's errors name it (file:line:column).
using Locate = std::function<SourcePos(const std::string& key)>;

}  // namespace pdsim

// Linear structural models (SDOF, FEM beam) and their time integrators.
// Equation of motion in generalised coordinates q (boundary conditions applied):
//   M q'' + C q' + K q = f(t)
// For base excitation q is measured relative to the moving base and the base acceleration
// enters as f = -M r a_base (r: rigid-body influence vector).
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <memory>
#include <string>
#include <vector>

#include "structure/structure_spec.hpp"

namespace pdsim {

// Where a damper sits on the structure. Indices are into the physical (unreduced) free DOFs,
// for information only: couple through the LinearStructure maps, which also hold for a modally
// reduced model.
struct Attachment {
  int translation_dof = -1;  // displacement along StructureSpec::direction; -1 if constrained
  int rotation_dof = -1;     // beam rotation (see LinearStructure); -1 for sdof or constrained
  double x = 0;              // beam: position along the beam, m
  int node = 0;              // beam: node index
};

// Beam DOFs per node are (w, theta): w the displacement along `direction`, theta the
// cross-section rotation, a right-handed rotation about (beam axis x direction); for
// Euler-Bernoulli theta = dw/dx. With `modes` = N the coordinates q are the amplitudes of the
// first N mass-normalised modes Phi (physical displacements = Phi q) and every vector and map
// below is projected: mass = I, stiffness = diag(omega^2), force_shape = Phi^T f,
// base_influence = Phi^T M r (so that -mass * base_influence * y'' is still the load).
struct LinearStructure {
  Eigen::MatrixXd mass, damping, stiffness;  // n x n, SI units
  // r: the supports moving by y(t) along `direction` load q with -M r y''. For an SDOF r = 1;
  // for a beam M r also holds the consistent-mass coupling to the support DOFs, so r is close
  // to, but not exactly, 1 on translations: use it for the load only, never for kinematics
  // (absolute displacement = y + relative displacement from the maps below).
  Eigen::VectorXd base_influence;
  Eigen::VectorXd force_shape;  // unit external force: where excitation.input = "force" acts
  // kg: the mass that moves with the base when the structure moves rigidly with it (a beam's
  // supports included), r^T M r over every DOF: with base input the structure's kinetic energy
  // in the inertial frame is 1/2 v^T M v + y' v^T M base_influence + 1/2 base_mass y'^2.
  double base_mass = 0;
  std::vector<Attachment> attachments;  // one per damper, in deck order
  int response_dof = 0;  // reported displacement (first damper's node, or sdof); information
  // Kinematic maps, so that callers never index q: for damper i the displacement along
  // `direction` is attachment_translation.row(i) * q (velocity: same row times v) and the
  // rotation attachment_rotation.row(i) * q (zero rows for sdof). A damper force F along
  // `direction` and torque T about the rotation axis load the structure with
  // attachment_translation.row(i)^T F + attachment_rotation.row(i)^T T.
  Eigen::MatrixXd attachment_translation, attachment_rotation;  // dampers x n
  Eigen::RowVectorXd response;  // reported displacement = response * q
  int size() const { return static_cast<int>(mass.rows()); }
};

// Builds the model (beam: assembly, supports, optional modal reduction) with a damper at each
// mount. Throws InputError for inconsistent input (e.g. a mount beyond the beam), at the key
// `where` places.
LinearStructure build_structure(const StructureSpec& spec, const std::vector<Mount>& mounts,
                                const Locate& where);
// Refuses, at [structure], a structure whose matrices have no modes (absurd values).
[[noreturn]] void throw_no_modes(const Locate& where);

// Steady harmonic response to the load phasor `load` at omega (rad/s): q = Im(Q e^{i phase})
// for a load Im(P e^{i phase}). Damper k acts on the structure as the impedance Z_k (N/m, the
// force it takes per unit displacement, complex) of its absolute displacement t_k Q + base,
// t_k = attachment_translation.row(k):
//   (K - w^2 M + i w C + sum_k Z_k t_k^T t_k) Q = P - sum_k Z_k t_k^T base.
// A rigid mass m in a container is Z = -m w^2.
Eigen::VectorXcd harmonic_response(const LinearStructure& s, double omega,
                                   const Eigen::VectorXcd& load,
                                   const std::vector<std::complex<double>>& impedance,
                                   std::complex<double> base);

// Static displacement K q = load; zero when K is singular (a structure free to move as a body
// has no static state under a net load).
Eigen::VectorXd static_response(const LinearStructure& s, const Eigen::VectorXd& load);

// Undamped natural frequencies, Hz, ascending (rigid-body modes give 0).
std::vector<double> natural_frequencies(const LinearStructure& s);

// `pdsim modes`: one line "mode <k> <frequency> Hz" per mode, k from 1, frequency with 6
// significant digits, for the first `count` modes (all if count <= 0 or beyond the model).
std::string format_modes(const std::vector<double>& hz, int count);

// Advances the state over fixed steps of length h with the load vector held constant over
// the step. `exact`: discrete propagator (matrix exponential, exact for piecewise-constant
// load); `cvode`: SUNDIALS CVODE (BDF, dense), re-initialised at each step.
class StructureIntegrator {
 public:
  virtual ~StructureIntegrator() = default;
  // q, v at time t -> t + h under constant generalised load `load` (size n).
  virtual void step(double h, const Eigen::VectorXd& load) = 0;
  // v += M^{-1} impulse (kick for energy-consistent coupling).
  virtual void kick(const Eigen::VectorXd& impulse) = 0;
  Eigen::VectorXd q, v;  // state, public so that coupling can save/restore it
};

// h (s) is the step the exact propagator is precomputed for; step() accepts any other h (it
// then computes and caches a second propagator, e.g. for a final partial step). Starts at rest.
std::unique_ptr<StructureIntegrator> make_integrator(const LinearStructure& s, IntegratorKind kind,
                                                     double h);

}  // namespace pdsim

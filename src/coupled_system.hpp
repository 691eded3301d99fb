// The structure and its particle dampers advanced together, one DEM step at a time, with the
// coupling scheme of the deck (kernels/physics.md, Coupling):
//   loose:       the structure takes the damper force of t_n, held constant over its step;
//   interleaved: the damper impulse kicks the structure, then both drift (the leapfrog split the
//                particles use too, so momentum is exchanged at one instant and energy stays
//                bounded); the structure's drift can run while the DEM step runs;
//   tight:       trapezoidal predictor-corrector: the structure step uses (F_n + F_{n+1})/2 and
//                is repeated until F_{n+1} changes less than coupling.tolerance.
#pragma once

#include <memory>
#include <vector>

#include "src/scene.hpp"
#include "structure/structure.hpp"

namespace pdsim {

// Harmonic input at angular frequency omega (rad/s); amplitude in N, m or m/s^2 by `input`.
// Its phase is omega (t - t0) + phase0, so that a new frequency can continue the old phase.
struct Drive {
  ExcitationInput input = ExcitationInput::force;
  double amplitude = 0;
  double omega = 0;
  double t0 = 0, phase0 = 0;  // s, rad
  double angle(double t) const { return omega * (t - t0) + phase0; }
  double force(double t) const;  // N, on the structure (force input only)
  double base_acceleration(double t) const;
  double base_displacement(double t) const;
  double base_velocity(double t) const;
};

// What the last step saw at its start time (the sample the steady-state detector takes).
struct StepRecord {
  double time = 0;
  double displacement = 0;      // m, response DOF (relative to the base for base input)
  double velocity = 0;          // m/s
  double damper_force = 0;      // N, force of the particles on the container(s) along `direction`
  double power_in = 0;          // W, power the containers put into the particles
  Dissipated dissipated{};      // J, this step, by mechanism (kernels/tallies.hpp)
  double particle_kinetic = 0;  // J after the step
  // J, work of the input in this step in the inertial frame: the external force's, or the
  // base's (on the structure, and through it on the dampers; prescribed motion: the
  // containers' on the particles).
  double work_external = 0;
  double dissipated_structure = 0;  // J, structural damping in this step
  double contact_elastic = 0;       // J, in the contact springs at the start of the step
};

// Kinetic and potential energy of a state, J.
struct Energy {
  double kinetic = 0, potential = 0;
};

// The drive's phasors at omega on `s` (against e^{i angle}): the load on its coordinates and the
// base's displacement. Force input: P = A f, no base; base input y = Im(Y e^{i angle}) loads the
// relative coordinates with -M r y'' = w^2 M r Y.
struct DrivePhasors {
  Eigen::VectorXcd load;
  std::complex<double> base;
};
DrivePhasors drive_phasors(const LinearStructure& s, ExcitationInput input, double amplitude,
                           double omega);

class CoupledSystem {
 public:
  explicit CoupledSystem(const Scene& scene);

  // Fixes the step and the drive for the coming steps (a new stepped-sine frequency).
  void configure(double dt, const Drive& drive);
  // Advances the system from `time()` by one coupling interval (coupling.every DEM steps).
  void advance();
  int steps_per_advance() const { return every_; }

  double time() const { return time_; }
  const StepRecord& last() const { return last_; }
  bool has_structure() const { return static_cast<bool>(integrator_); }
  const LinearStructure& structure() const { return structure_; }
  double structure_kinetic() const;  // J, relative to the base
  double structure_elastic() const;  // J
  // The current state's energy in the inertial frame, the contact springs excepted (the DEM
  // step reports them, StepRecord::contact_elastic): the structure's, its kinetic energy with
  // the base's motion; the particles' translation and rotation at their stored half-step
  // velocities, and their weight's potential at the matching positions x - dt v / 2 (zero at
  // the origin).
  Energy state_energy() const;
  long long particle_steps() const { return particle_steps_; }
  // Damper k's container now (its pose and motion in the world frame).
  ContainerKinematics container_now(std::size_t k) const;
  int particle_count() const;
  const std::vector<std::unique_ptr<DemEngine>>& engines() const { return engines_; }
  void set_initial_displacement(double x0);  // free decay: displace the response DOF statically
  const Drive& drive() const { return drive_; }

  // One DEM step of every damper with its container held at rest where it is (the bed settling
  // before the excitation); time stands still. Returns the largest particle speed, m/s.
  double settle_step(double dt);
  // Per damper, over the last advance(): the container's absolute displacement along
  // `direction` at its start (m) and the mean force of the particles on it (N).
  const std::vector<double>& damper_displacements() const { return displacement_; }
  const std::vector<double>& damper_forces() const { return force_mean_; }
  // The structure's steady harmonic state predicted for the drive (q = Im(Q e^{i angle})), each
  // damper acting as the impedance Z_k (N/m, complex: its first-harmonic force on the container
  // is -Z_k times the container's displacement).
  Eigen::VectorXcd predicted_harmonic(const std::vector<std::complex<double>>& impedance) const;
  // Puts the structure on that state, displaced statically by the dampers' constant forces
  // mean_force_k (N, e.g. a weight along `direction`), and carries the particles along with
  // their containers.
  void start_on(const Eigen::VectorXcd& harmonic, const std::vector<double>& mean_force);
  // The response DOF's part of a harmonic state, m.
  std::complex<double> response_of(const Eigen::VectorXcd& harmonic) const {
    return structure_.response.cast<std::complex<double>>() * harmonic;
  }

  // Particle states of every damper as CSV (damper, id, x, y, z, vx, vy, vz, wx, wy, wz).
  void dump(const std::string& path) const;

  StateArrays save() const;
  void restore(const StateArrays& state);

 private:
  // Container k at displacement u (m) and rotation theta (rad) about rotation_axis_, its axes
  // turned from their orientation at rest.
  const Orientation& orientation(std::size_t k) const;  // damper k's container axes at rest
  ContainerKinematics container(std::size_t k, double u, double u_dot, double theta,
                                double theta_dot) const;
  // Generalised external load at t, written into `load` (no allocation in the step loop).
  void external_load(double t, Eigen::VectorXd& load) const;
  double response(const Eigen::VectorXd& q) const;
  // J: what the base's motion adds at t to the structure's kinetic energy relative to the
  // base, y' v^T M r + 1/2 base_mass y'^2 (structure.hpp).
  double base_energy(double t) const;
  double damping_power(const Eigen::VectorXd& v);      // W, v^T C v
  double container_displacement(std::size_t k) const;  // absolute, along direction_, m
  void step_prescribed();
  void step_explicit(bool impulse);
  void step_tight();
  double compute_dampers(double t, double lead, std::vector<double>& force_along);
  void check(const StepTotals& totals, std::size_t damper, const ContainerKinematics& container,
             const std::string& when);
  std::string when(double t) const;  // "at t = ... s (step ..., dt ... s)"

  const Scene& scene_;
  CouplingSpec coupling_;
  IntegratorKind integrator_kind_;
  Vec3 direction_;
  Vec3 rotation_axis_;  // beam: axis x direction, about which a node's slope turns a damper
  std::optional<Vec3> prescribed_axis_;  // no structure: the containers move along it
  bool rigid_ = false;                   // the dampers' contacts are non-smooth
  const LinearStructure& structure_;     // the scene's (an empty one without a structure)
  std::unique_ptr<StructureIntegrator> integrator_;
  std::vector<std::unique_ptr<DemEngine>> engines_;
  Drive drive_;
  double dt_ = 0, time_ = 0;
  int every_ = 1;
  bool pending_ = false;  // tight: the DEM holds a computed, not yet accepted step
  std::vector<double> pending_force_;
  StepRecord last_, pending_record_;
  long long particle_steps_ = 0;
  // Work buffers of the step loop, sized once.
  std::vector<double> force_, force_sum_, guess_, torque_, torque_sum_, pending_torque_;
  std::vector<double> displacement_, force_mean_;  // per damper, see damper_displacements()
  // Per damper, J: the tangential springs' energy after the last accepted DEM step, and after
  // the computed one (tight). What of it the next step does not carry in (StepTotals::
  // spring_in: ended contacts, Mindlin's stiffness change) is tallied as friction's.
  std::vector<double> spring_energy_, pending_spring_energy_;
  void account_springs(std::size_t k, const StepTotals& totals, double& tangential);
  std::vector<ContainerKinematics> kinematics_at_configure_;  // until the next step
  Eigen::VectorXd load_, damper_load_, q_start_, v_start_, damping_force_;
  Eigen::VectorXd base_inertia_;  // M r, N per m/s^2 of base acceleration
};

}  // namespace pdsim

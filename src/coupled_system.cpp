#include "src/coupled_system.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

namespace pdsim {

double Drive::force(double t) const {
  return input == ExcitationInput::force ? amplitude * std::sin(angle(t)) : 0.0;
}

// Base motion is the periodic solution of y'' = a: for a displacement amplitude Y,
// y = Y sin wt; for an acceleration amplitude A, y = -(A / w^2) sin wt.
double Drive::base_displacement(double t) const {
  if (input == ExcitationInput::base_displacement) return amplitude * std::sin(angle(t));
  if (input == ExcitationInput::base_acceleration)
    return -amplitude / (omega * omega) * std::sin(angle(t));
  return 0.0;
}

double Drive::base_velocity(double t) const {
  if (input == ExcitationInput::base_displacement) return amplitude * omega * std::cos(angle(t));
  if (input == ExcitationInput::base_acceleration) return -amplitude / omega * std::cos(angle(t));
  return 0.0;
}

double Drive::base_acceleration(double t) const {
  if (input == ExcitationInput::base_displacement)
    return -amplitude * omega * omega * std::sin(angle(t));
  if (input == ExcitationInput::base_acceleration) return amplitude * std::sin(angle(t));
  return 0.0;
}

namespace {

// Moves the particles of `engine` rigidly with their container from `from` to `to` (position,
// velocity and spin relative to the container kept), contact histories kept. Through the
// engine's checkpoint, which both backends write with the same state arrays.
void carry_with_container(DemEngine& engine, const ContainerKinematics& from,
                          const ContainerKinematics& to) {
  StateArrays state = engine.save();
  auto array = [&](const char* key) { return &state_values<double>(state, key); };
  std::vector<double>*x = array("x"), *y = array("y"), *z = array("z");
  std::vector<double>*vx = array("vx"), *vy = array("vy"), *vz = array("vz");
  std::vector<double>*wx = array("wx"), *wy = array("wy"), *wz = array("wz");
  // Local frame components of a world vector, and back.
  auto local = [&](Vec3 e) {
    return Vec3{dot(e, from.axis_x), dot(e, from.axis_y), dot(e, from.axis_z)};
  };
  auto world = [&](Vec3 l) { return l.x * to.axis_x + l.y * to.axis_y + l.z * to.axis_z; };
  for (std::size_t i = 0; i < x->size(); ++i) {
    const Vec3 r{(*x)[i] - from.position.x, (*y)[i] - from.position.y, (*z)[i] - from.position.z};
    const Vec3 v{(*vx)[i], (*vy)[i], (*vz)[i]}, w{(*wx)[i], (*wy)[i], (*wz)[i]};
    const Vec3 r_local = local(r);
    const Vec3 v_local = local(v - from.velocity - cross(from.angular_velocity, r));
    const Vec3 w_local = local(w - from.angular_velocity);
    const Vec3 r_to = world(r_local);
    const Vec3 p = to.position + r_to;
    const Vec3 v_to = to.velocity + cross(to.angular_velocity, r_to) + world(v_local);
    const Vec3 w_to = to.angular_velocity + world(w_local);
    (*x)[i] = p.x, (*y)[i] = p.y, (*z)[i] = p.z;
    (*vx)[i] = v_to.x, (*vy)[i] = v_to.y, (*vz)[i] = v_to.z;
    (*wx)[i] = w_to.x, (*wy)[i] = w_to.y, (*wz)[i] = w_to.z;
  }
  state_values<std::int32_t>(state, "needs_rebuild") = {1};  // moved: the lists are rebuilt
  engine.restore(state);
}

}  // namespace

DrivePhasors drive_phasors(const LinearStructure& s, ExcitationInput input, double amplitude,
                           double omega) {
  if (input == ExcitationInput::force)
    return {amplitude * s.force_shape.cast<std::complex<double>>(), 0.0};
  const double w = omega;
  const std::complex<double> base =
      input == ExcitationInput::base_displacement ? amplitude : -amplitude / (w * w);
  return {(w * w * base) * (s.mass * s.base_influence).cast<std::complex<double>>(), base};
}

namespace {

const LinearStructure& structure_of(const Scene& scene) {
  static const LinearStructure none;
  return scene.structure ? *scene.structure : none;
}

}  // namespace

CoupledSystem::CoupledSystem(const Scene& scene)
    : scene_(scene),
      coupling_(scene.coupling),
      integrator_kind_(scene.integrator),
      direction_(scene.direction),
      structure_(structure_of(scene)),
      every_(scene.coupling.every) {
  if (scene.structure) {
    // At rest until configure() fixes the step; holds the state restore() brings back.
    integrator_ = make_integrator(structure_, integrator_kind_, 1e-4);
    integrator_->q = integrator_->v = Eigen::VectorXd::Zero(structure_.size());
  } else {
    prescribed_axis_ = scene.motion_axis;
    rigid_ = !scene.dampers.empty() && scene.dampers[0].engine.nonsmooth.has_value();
    every_ = 1;
  }
  for (const DamperScene& d : scene.dampers) engines_.push_back(make_engine(d.engine));
  pending_force_.assign(engines_.size(), 0.0);
  force_ = force_sum_ = guess_ = torque_ = torque_sum_ = pending_torque_ = pending_force_;
  displacement_ = force_mean_ = spring_energy_ = pending_spring_energy_ = pending_force_;
  if (scene.rotation_axis) rotation_axis_ = *scene.rotation_axis;
  const int n = structure_.size();
  load_ = damper_load_ = q_start_ = v_start_ = damping_force_ = Eigen::VectorXd::Zero(n);
  if (integrator_) base_inertia_ = structure_.mass * structure_.base_influence;
}

int CoupledSystem::particle_count() const {
  int n = 0;
  for (const auto& e : engines_) n += e->count();
  return n;
}

void CoupledSystem::configure(double dt, const Drive& drive) {
  // The containers as the particles last saw them, under the old drive: a new base input's
  // velocity is not one the particles had (start_on carries them from here).
  kinematics_at_configure_.clear();
  if (integrator_)
    for (std::size_t k = 0; k < engines_.size(); ++k)
      kinematics_at_configure_.push_back(container_now(k));
  dt_ = dt;
  drive_ = drive;
  if (structure_.size() > 0) {
    const Eigen::VectorXd q = integrator_->q, v = integrator_->v;
    integrator_ = make_integrator(structure_, integrator_kind_, dt * every_);
    integrator_->q = q;
    integrator_->v = v;
  }
  pending_ = false;  // a tight step is re-primed with the new step size
}

void CoupledSystem::set_initial_displacement(double x0) {
  // Static deflection shape under the excitation force pattern, scaled to x0 at the response.
  const Eigen::VectorXd shape = structure_.stiffness.ldlt().solve(structure_.force_shape);
  std::vector<ContainerKinematics> before;
  for (std::size_t k = 0; k < engines_.size(); ++k) before.push_back(container_now(k));
  integrator_->q = x0 / response(shape) * shape;
  integrator_->v.setZero();
  for (std::size_t k = 0; k < engines_.size(); ++k)
    carry_with_container(*engines_[k], before[k], container_now(k));
}

double CoupledSystem::response(const Eigen::VectorXd& q) const {
  return structure_.response * q;
}

void CoupledSystem::external_load(double t, Eigen::VectorXd& load) const {
  if (drive_.input == ExcitationInput::force)
    load.noalias() = drive_.force(t) * structure_.force_shape;
  else
    load.noalias() = -drive_.base_acceleration(t) * (structure_.mass * structure_.base_influence);
}

const Orientation& CoupledSystem::orientation(std::size_t k) const {
  static const Orientation kIdentity;
  return k < scene_.dampers.size() ? scene_.dampers[k].engine.orientation : kIdentity;
}

ContainerKinematics CoupledSystem::container(std::size_t damper, double u, double u_dot,
                                             double theta, double theta_dot) const {
  ContainerKinematics k;
  k.position = u * direction_;
  k.velocity = u_dot * direction_;
  const Orientation& rest = orientation(damper);
  if (theta != 0.0 || theta_dot != 0.0) {
    // Rodrigues: R e = e cos(theta) + (a x e) sin(theta) + a (a . e)(1 - cos(theta)).
    const Vec3& a = rotation_axis_;
    const double c = std::cos(theta), s = std::sin(theta);
    auto turn = [&](Vec3 e) { return c * e + s * cross(a, e) + (dot(a, e) * (1 - c)) * a; };
    k.axis_x = turn(rest.x);
    k.axis_y = turn(rest.y);
    k.axis_z = turn(rest.z);
    k.angular_velocity = theta_dot * a;
  } else {
    set_axes(k, rest);
  }
  return k;
}

double CoupledSystem::structure_kinetic() const {
  if (!integrator_) return 0.0;
  return 0.5 * integrator_->v.dot(structure_.mass * integrator_->v);
}

double CoupledSystem::structure_elastic() const {
  if (!integrator_) return 0.0;
  return 0.5 * integrator_->q.dot(structure_.stiffness * integrator_->q);
}

double CoupledSystem::base_energy(double t) const {
  if (!integrator_) return 0.0;
  const double y_dot = drive_.base_velocity(t);
  return y_dot * integrator_->v.dot(base_inertia_) + 0.5 * structure_.base_mass * y_dot * y_dot;
}

double CoupledSystem::damping_power(const Eigen::VectorXd& v) {
  damping_force_.noalias() = structure_.damping * v;
  return v.dot(damping_force_);
}

Energy CoupledSystem::state_energy() const {
  Energy e;
  e.kinetic = structure_kinetic() + base_energy(time_);
  e.potential = structure_elastic();
  for (std::size_t k = 0; k < engines_.size(); ++k) {
    const EngineConfig& c = scene_.dampers[k].engine;
    const Vec3 g = c.gravity.value_or(Vec3{});
    const auto particles = engines_[k]->particles();
    for (std::size_t i = 0; i < particles.size(); ++i) {
      const ParticleState& p = particles[i];
      const SphereMass m = sphere_mass(c.radius.at(i), c.density);
      e.kinetic += 0.5 * (m.mass * dot(p.velocity, p.velocity) + m.inertia * dot(p.spin, p.spin));
      e.potential -= m.mass * dot(g, p.position - (0.5 * dt_) * p.velocity);
    }
  }
  return e;
}

void CoupledSystem::account_springs(std::size_t k, const StepTotals& totals, double& tangential) {
  tangential += spring_energy_[k] - totals.tally.spring_in;
  pending_spring_energy_[k] = totals.tally.spring_out;
}

// Runs one DEM step of every damper with the container at displacement u_k(t) + lead * u_dot_k,
// accepting it unless `accept` is false; returns the power the containers put into the particles.
double CoupledSystem::compute_dampers(double t, double lead, std::vector<double>& force_along) {
  double power = 0;
  last_.dissipated = {};
  last_.particle_kinetic = last_.contact_elastic = last_.work_external = 0;
  for (std::size_t k = 0; k < engines_.size(); ++k) {
    const int row = static_cast<int>(k);
    const auto translation = structure_.attachment_translation.row(row);
    const auto rotation = structure_.attachment_rotation.row(row);
    const double u = drive_.base_displacement(t) + translation.dot(integrator_->q);
    const double u_dot = drive_.base_velocity(t) + translation.dot(integrator_->v);
    const double theta = rotation.dot(integrator_->q), theta_dot = rotation.dot(integrator_->v);
    const ContainerKinematics kin =
        container(k, u + lead * u_dot, u_dot, theta + lead * theta_dot, theta_dot);
    const StepTotals& totals = engines_[k]->compute(kin, dt_);
    if (totals.flags) check(totals, k, kin, when(t));
    force_along[k] = dot(totals.wall_force, direction_);
    torque_[k] = dot(totals.wall_torque, rotation_axis_);
    power -= dot(totals.wall_force, kin.velocity) + dot(totals.wall_torque, kin.angular_velocity);
    // The part of that power the base's motion supplies (the structure supplies the rest).
    last_.work_external -= force_along[k] * drive_.base_velocity(t) * dt_;
    last_.dissipated += dissipated_part(totals.tally);
    account_springs(k, totals, last_.dissipated[kTangential]);
    last_.contact_elastic += totals.tally.elastic;
    last_.particle_kinetic += totals.kinetic;
    particle_steps_ += engines_[k]->count();
  }
  return power;
}

void CoupledSystem::advance() {
  kinematics_at_configure_.clear();
  if (prescribed_axis_)
    step_prescribed();
  else if (coupling_.scheme == CouplingScheme::tight && !engines_.empty())
    step_tight();
  else
    step_explicit(coupling_.scheme == CouplingScheme::interleaved);
}

void CoupledSystem::step_prescribed() {
  const Vec3 axis = *prescribed_axis_;
  ContainerKinematics moving = container_now(0);  // every container moves alike
  const double u = dot(moving.position, axis);
  last_ = StepRecord{};
  last_.time = time_;
  last_.displacement = u;
  last_.velocity = dot(moving.velocity, axis);
  if (rigid_) {
    // Rigid contacts hold the walls' velocity through the step, and their impulses meet the
    // velocity conditions at its end: the chord's velocity moves the walls where the motion has
    // them then. Their velocity at the step's start lagged the motion by half a step, which a
    // rolling ball's reaction showed as a loss factor of omega dt / 2 (0.024 at the default step
    // on a 15 Hz map; validation/results/nonsmooth.md).
    const double x = drive_.amplitude;
    moving.velocity =
        (x * (std::sin(drive_.angle(time_ + dt_)) - std::sin(drive_.angle(time_))) / dt_) * axis;
  }
  for (std::size_t k = 0; k < engines_.size(); ++k) {
    ContainerKinematics kin = moving;  // computed once a step; each container its own axes
    set_axes(kin, orientation(k));
    const StepTotals& totals = engines_[k]->compute(kin, dt_);
    if (totals.flags) check(totals, k, kin, when(time_));
    engines_[k]->accept();
    account_springs(k, totals, last_.dissipated[kTangential]);
    spring_energy_[k] = pending_spring_energy_[k];
    displacement_[k] = u;
    force_mean_[k] = dot(totals.wall_force, axis);
    last_.damper_force += force_mean_[k];
    last_.power_in -= dot(totals.wall_force, kin.velocity);
    last_.contact_elastic += totals.tally.elastic;
    last_.dissipated += dissipated_part(totals.tally);
    last_.particle_kinetic += totals.kinetic;
    particle_steps_ += engines_[k]->count();
  }
  last_.work_external = last_.power_in * dt_;
  time_ += dt_;
}

// Container k's absolute displacement along `direction` now, m.
double CoupledSystem::container_displacement(std::size_t k) const {
  return drive_.base_displacement(time_) +
         structure_.attachment_translation.row(static_cast<int>(k)).dot(integrator_->q);
}

void CoupledSystem::step_explicit(bool impulse) {
  const double t0 = time_;
  last_.time = t0;
  last_.displacement = response(integrator_->q);
  last_.velocity = response(integrator_->v);
  for (std::size_t k = 0; k < engines_.size(); ++k) displacement_[k] = container_displacement(k);
  // The DEM sub-steps see the container extrapolated linearly over the coupling interval.
  std::fill(force_sum_.begin(), force_sum_.end(), 0.0);
  std::fill(torque_sum_.begin(), torque_sum_.end(), 0.0);
  double power = 0, work_base = 0;
  Dissipated dissipated{};
  double elastic = 0;
  const double base_before = base_energy(t0);
  for (int s = 0; s < every_; ++s) {
    power += compute_dampers(t0 + s * dt_, s * dt_, force_);
    work_base += last_.work_external;
    if (s == 0) elastic = last_.contact_elastic;  // the interval's start
    for (auto& e : engines_) e->accept();
    spring_energy_ = pending_spring_energy_;
    for (std::size_t k = 0; k < force_.size(); ++k) {
      force_sum_[k] += force_[k];
      torque_sum_[k] += torque_[k];
    }
    dissipated += last_.dissipated;
  }
  const double h = every_ * dt_;
  damper_load_.setZero();
  double total_force = 0;
  for (std::size_t k = 0; k < force_sum_.size(); ++k) {
    const double mean = force_sum_[k] / every_;
    force_mean_[k] = mean;
    damper_load_ += mean * structure_.attachment_translation.row(static_cast<int>(k)).transpose();
    damper_load_ += (torque_sum_[k] / every_) *
                    structure_.attachment_rotation.row(static_cast<int>(k)).transpose();
    total_force += mean;
  }
  q_start_ = integrator_->q;
  external_load(t0 + 0.5 * h, load_);
  if (impulse) {
    damper_load_ *= h;  // impulse over the interval
    integrator_->kick(damper_load_);
    v_start_ = integrator_->v;
    integrator_->step(h, load_);
  } else {
    v_start_ = integrator_->v;
    load_ += damper_load_;
    integrator_->step(h, load_);
    load_ -= damper_load_;
  }
  last_.damper_force = total_force;
  last_.power_in = engines_.empty() ? 0.0 : power / every_;
  last_.dissipated = dissipated;
  last_.contact_elastic = elastic;
  // Over the drift, the trapezoidal rule (h is a DEM step or a few: O((omega h)^2) small).
  last_.dissipated_structure = 0.5 * h * (damping_power(v_start_) + damping_power(integrator_->v));
  time_ = t0 + h;
  last_.work_external =
      load_.dot(integrator_->q - q_start_) + work_base + base_energy(time_) - base_before;
}

void CoupledSystem::step_tight() {
  if (!pending_) {
    // Prime: the DEM step from the current particle state with the container at t_n.
    last_.time = time_;
    const double power = compute_dampers(time_, 0.0, force_);
    pending_force_ = force_;
    pending_torque_ = torque_;
    pending_record_ = last_;
    pending_record_.power_in = power;
    pending_ = true;
  }
  const double t0 = time_;
  StepRecord record = pending_record_;
  record.time = t0;
  record.displacement = response(integrator_->q);
  record.velocity = response(integrator_->v);
  record.damper_force = 0;
  for (double f : pending_force_) record.damper_force += f;
  force_mean_ = pending_force_;
  for (std::size_t k = 0; k < engines_.size(); ++k) displacement_[k] = container_displacement(k);
  for (auto& e : engines_) e->accept();  // particles t_n -> t_{n+1}
  spring_energy_ = pending_spring_energy_;

  q_start_ = integrator_->q;
  v_start_ = integrator_->v;
  const double base_before = base_energy(t0);
  external_load(t0 + 0.5 * dt_, load_);
  guess_ = pending_force_;
  double power = 0;
  for (int iteration = 0; iteration < coupling_.max_iterations; ++iteration) {
    integrator_->q = q_start_;
    integrator_->v = v_start_;
    damper_load_ = load_;
    for (std::size_t k = 0; k < guess_.size(); ++k) {
      const int row = static_cast<int>(k);
      damper_load_ += 0.5 * (pending_force_[k] + guess_[k]) *
                      structure_.attachment_translation.row(row).transpose();
      // The torque rides along with the last evaluation (the force drives the iteration).
      damper_load_ += 0.5 * (pending_torque_[k] + torque_[k]) *
                      structure_.attachment_rotation.row(row).transpose();
    }
    integrator_->step(dt_, damper_load_);
    power = compute_dampers(t0 + dt_, 0.0, force_);
    double change = 0, scale = 1e-12;
    for (std::size_t k = 0; k < force_.size(); ++k) {
      change = std::max(change, std::fabs(force_[k] - guess_[k]));
      scale = std::max(scale, std::max(std::fabs(force_[k]), std::fabs(pending_force_[k])));
    }
    guess_ = force_;
    if (change <= coupling_.tolerance * scale) break;
  }
  record.dissipated_structure =
      0.5 * dt_ * (damping_power(v_start_) + damping_power(integrator_->v));
  StepRecord computed = last_;  // tallies of the step just computed, reported once accepted
  computed.power_in = power;
  pending_force_ = force_;
  pending_torque_ = torque_;
  pending_record_ = computed;
  time_ = t0 + dt_;
  // The accepted particle step's base work (its record), the structure's step's own.
  record.work_external += load_.dot(integrator_->q - q_start_) + base_energy(time_) - base_before;
  last_ = record;
}

double CoupledSystem::settle_step(double dt) {
  double speed_sq = 0;
  for (std::size_t k = 0; k < engines_.size(); ++k) {
    ContainerKinematics kin = container_now(k);
    kin.velocity = {};
    kin.angular_velocity = {};
    const StepTotals& totals = engines_[k]->compute(kin, dt);
    if (totals.flags)
      check(totals, k, kin, "while the bed settled (dt " + std::to_string(dt) + " s)");
    engines_[k]->accept();
    spring_energy_[k] = totals.tally.spring_out;
    speed_sq = std::max(speed_sq, totals.speed_sq);
    particle_steps_ += engines_[k]->count();
  }
  pending_ = false;
  return std::sqrt(speed_sq);
}

ContainerKinematics CoupledSystem::container_now(std::size_t k) const {
  if (prescribed_axis_) {
    // The drive holds the point's amplitude (pdsim map steps it at one frequency).
    const Vec3 axis = *prescribed_axis_;
    const double x = drive_.amplitude;
    ContainerKinematics c = translating(x * std::sin(drive_.angle(time_)) * axis,
                                        x * drive_.omega * std::cos(drive_.angle(time_)) * axis);
    set_axes(c, orientation(k));
    return c;
  }
  const int row = static_cast<int>(k);
  const auto rotation = structure_.attachment_rotation.row(row);
  const double u_dot =
      drive_.base_velocity(time_) + structure_.attachment_translation.row(row).dot(integrator_->v);
  return container(k, container_displacement(k), u_dot, rotation.dot(integrator_->q),
                   rotation.dot(integrator_->v));
}

Eigen::VectorXcd CoupledSystem::predicted_harmonic(
    const std::vector<std::complex<double>>& impedance) const {
  const DrivePhasors p = drive_phasors(structure_, drive_.input, drive_.amplitude, drive_.omega);
  return harmonic_response(structure_, drive_.omega, p.load, impedance, p.base);
}

void CoupledSystem::start_on(const Eigen::VectorXcd& harmonic,
                             const std::vector<double>& mean_force) {
  if (!integrator_) return;
  const std::complex<double> i(0, 1);
  Eigen::VectorXd constant = Eigen::VectorXd::Zero(structure_.size());
  for (std::size_t k = 0; k < mean_force.size(); ++k)
    constant +=
        mean_force[k] * structure_.attachment_translation.row(static_cast<int>(k)).transpose();
  const std::complex<double> turn = std::exp(i * drive_.angle(time_));
  std::vector<ContainerKinematics> before = kinematics_at_configure_;
  if (before.size() != engines_.size()) {  // a step ran since configure(): the drive is current
    before.clear();
    for (std::size_t d = 0; d < engines_.size(); ++d) before.push_back(container_now(d));
  }
  integrator_->q = static_response(structure_, constant) + (harmonic * turn).imag();
  kinematics_at_configure_.clear();
  integrator_->v = (i * drive_.omega * harmonic * turn).imag();
  for (std::size_t k = 0; k < engines_.size(); ++k)
    carry_with_container(*engines_[k], before[k], container_now(k));
  pending_ = false;
}

// Blow-up guard: a non-finite value or a particle outside its container stops the run with
// the step, time and first offending particle (its state at the end of the failing step).
std::string CoupledSystem::when(double t) const {
  std::ostringstream s;
  s.precision(6);
  s << "at t = " << t << " s (step " << std::llround(t / dt_) << ", dt " << dt_ << " s)";
  return s.str();
}

void CoupledSystem::check(const StepTotals& totals, std::size_t damper,
                          const ContainerKinematics& c, const std::string& when) {
  engines_[damper]->accept();  // show the state the step produced
  const EngineConfig& e = scene_.dampers[damper].engine;
  std::ostringstream s;
  s.precision(6);
  if (totals.flags & kWallOverflow)
    throw SimulationError(
        "stopped " + when + ", damper " + std::to_string(damper) +
        ": a particle touches more than " + std::to_string(kWallSlots) +
        " surfaces, edges or corners of the container's mesh at once. Mesh the cavity more "
        "coarsely where it bends, or raise the container's curvature (degrees) so that faces "
        "meeting at smaller angles count as one surface");
  s << "blow-up " << when << ", damper " << damper << ": "
    << ((totals.flags & kNonFinite) ? "non-finite particle state"
                                    : "a particle left its container");
  const auto particles = engines_[damper]->particles();
  for (std::size_t i = 0; i < particles.size(); ++i) {
    const ParticleState& p = particles[i];
    const Vec3 offset = p.position - c.position;  // in the container's frame:
    const Vec3 local{dot(offset, c.axis_x), dot(offset, c.axis_y), dot(offset, c.axis_z)};
    const bool finite = std::isfinite(norm(p.position) + norm(p.velocity));
    const bool outside = with_shape(
        e.shape, [&](auto shape) { return !decltype(shape)::inside(local, 0.0, e.geometry); });
    if (!finite || outside) {
      s << "; first particle " << i << " at (" << local.x << ", " << local.y << ", " << local.z
        << ") m from the container centre (container axes), speed " << norm(p.velocity) << " m/s";
      break;
    }
  }
  s << ". Typical causes: dt too large for the contact stiffness (see pdsim check), or loose "
       "coupling with particles heavy against the structure (use interleaved or tight)";
  throw SimulationError(s.str());
}

void CoupledSystem::dump(const std::string& path) const {
  std::ofstream out(path);
  out.precision(17);
  out << "damper,id,x,y,z,vx,vy,vz,wx,wy,wz\n";
  for (std::size_t k = 0; k < engines_.size(); ++k) {
    const auto particles = engines_[k]->particles();
    for (std::size_t i = 0; i < particles.size(); ++i) {
      const ParticleState& p = particles[i];
      out << k << ',' << i << ',' << p.position.x << ',' << p.position.y << ',' << p.position.z
          << ',' << p.velocity.x << ',' << p.velocity.y << ',' << p.velocity.z << ',' << p.spin.x
          << ',' << p.spin.y << ',' << p.spin.z << '\n';
    }
  }
}

StateArrays CoupledSystem::save() const {
  StateArrays out;
  for (std::size_t k = 0; k < engines_.size(); ++k)
    put_state(out, "damper" + std::to_string(k) + ".", engines_[k]->save());
  if (integrator_) {
    const Eigen::VectorXd &q = integrator_->q, &v = integrator_->v;
    out["structure.q"] = std::vector<double>(q.data(), q.data() + q.size());
    out["structure.v"] = std::vector<double>(v.data(), v.data() + v.size());
  }
  out["spring_energy"] = spring_energy_;
  out["time"] = std::vector<double>{time_};
  out["particle_steps"] = std::vector<std::uint64_t>{static_cast<std::uint64_t>(particle_steps_)};
  return out;
}

void CoupledSystem::restore(const StateArrays& state) {
  for (std::size_t k = 0; k < engines_.size(); ++k)
    engines_[k]->restore(get_state(state, "damper" + std::to_string(k) + "."));
  if (integrator_) {
    const auto& q = state_values<double>(state, "structure.q");
    const auto& v = state_values<double>(state, "structure.v");
    integrator_->q = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<int>(q.size()));
    integrator_->v = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<int>(v.size()));
  }
  spring_energy_ = state_values<double>(state, "spring_energy");
  time_ = state_value<double>(state, "time");
  particle_steps_ = static_cast<long long>(state_value<std::uint64_t>(state, "particle_steps"));
  pending_ = false;
}

}  // namespace pdsim

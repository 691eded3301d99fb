#include "src/frequency_run.hpp"

#include <cmath>
#include <limits>

#include "kernels/contact_count.hpp"
#include "src/interrupt.hpp"

namespace pdsim {

namespace {
// The predicted start's refinement: rounds of a few periods each (see begin_frequency).
constexpr int kRefinements = 4, kProbePeriods = 3;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
}  // namespace

FrequencyRun::FrequencyRun(const Scene& scene, const RunPlan& plan, Progress progress)
    : scene_(scene), plan_(plan), system_(scene), progress_(std::move(progress)) {
  const double f_top = plan.highest_frequency() > 0 ? plan.highest_frequency() : first_mode();
  sample_every_ = plan.output.every > 0 ? plan.output.every : 1.0 / (32 * f_top);
  if (plan.output.energy) energy_.emplace();
  if (plan.output.particles_every > 0) {
    ParticleSnapshots& s = particles_.emplace();
    for (std::size_t k = 0; k < scene.dampers.size(); ++k) {
      const EngineConfig& c = scene.dampers[k].engine;
      DamperSnapshots& d = s.dampers.emplace_back();
      const Vec3 h = c.geometry.half_size;
      d.shape = shape_name(c.shape);
      d.size = {2 * h.x, 2 * h.y, 2 * h.z};
      d.radius = c.radius;
      std::vector<Vec3> points;
      std::vector<int> segments;
      with_shape(c.shape,
                 [&](auto shape) { decltype(shape)::wireframe(c.geometry, points, segments); });
      for (const Vec3& p : points) d.outline_points.insert(d.outline_points.end(), {p.x, p.y, p.z});
      d.outline_segments.assign(segments.begin(), segments.end());
    }
  }
  // Before anything is measured the bed moves with its container: a rigid mass carrying its
  // weight's component along the structure's direction.
  const double along =
      scene.gravity && scene.structure ? dot(*scene.gravity, scene.direction) : 0.0;
  for (const DamperScene& d : scene.dampers) {
    effective_mass_.push_back(d.particle_mass);
    effective_damping_.push_back(0.0);
    mean_force_.push_back(d.particle_mass * along);
  }
}

double FrequencyRun::first_mode() const {
  return scene_.natural_hz.empty() ? 1.0 : scene_.natural_hz.front();
}

BedReport FrequencyRun::settle_bed() {
  BedReport report;
  if (!plan_.bed.settle || system_.engines().empty()) return report;
  report.ran = true;
  const double dt = scene_.dt;
  const long long hold = std::llround(std::ceil(kBedHold_s / dt));
  const long long most = std::llround(std::ceil(plan_.bed.max_time / dt));
  long long calm = 0, steps = 0;
  while (steps < most && calm < hold) {
    if (stop_requested()) throw Interrupted();
    report.speed = system_.settle_step(dt);
    calm = report.speed <= plan_.bed.speed ? calm + 1 : 0;
    ++steps;
    if (progress_ && steps % 2000 == 0) progress_(0.0, double(steps) / double(most));
  }
  report.settled = calm >= hold;
  report.time_s = double(steps) * dt;
  return report;
}

// Fixes the step for frequency f: an integer number of steps (a multiple of the coupling
// interval) per period, no longer than the scene's dt. The drive continues the phase it had,
// so that the input has no jump (a base does not teleport).
int FrequencyRun::configure(double frequency, double amplitude) {
  const double period = 1.0 / frequency;
  const int every = system_.steps_per_advance();
  const double intervals = std::ceil(period / scene_.dt / every - 1e-9);
  if (!(intervals < double(1 << 30) / every))
    throw SimulationError("a period of " + std::to_string(frequency) + " Hz takes " +
                          std::to_string(intervals * every) +
                          " steps of dt; more than a run can count (raise dt or the frequency)");
  const int steps = std::max(static_cast<int>(intervals), 32) * every;
  const Drive& old = system_.drive();
  const double angle = restored_ ? restored_angle_ : old.omega > 0 ? old.angle(system_.time()) : 0;
  restored_ = false;
  Drive drive{plan_.input, amplitude, 2 * kPi * frequency, system_.time(),
              std::fmod(angle, 2 * kPi)};
  jump([&] { system_.configure(period / steps, drive); });
  dt_ = period / steps;
  frequency_ = frequency;
  return steps / every;
}

template <class Change>
void FrequencyRun::jump(Change&& change) {
  if (!energy_) return change();
  const Energy before = system_.state_energy();
  change();
  const Energy after = system_.state_energy();
  work_in_ += after.kinetic + after.potential - before.kinetic - before.potential;
}

void FrequencyRun::snapshot() {
  ParticleSnapshots& s = *particles_;
  s.time.push_back(system_.time());
  auto push = [](std::vector<double>& to, Vec3 v) { to.insert(to.end(), {v.x, v.y, v.z}); };
  for (std::size_t k = 0; k < s.dampers.size(); ++k) {
    DamperSnapshots& d = s.dampers[k];
    std::vector<Vec3> centre;
    for (const ParticleState& p : system_.engines()[k]->particles()) {
      push(d.position, p.position);
      push(d.velocity, p.velocity);
      push(d.spin, p.spin);
      centre.push_back(p.position);
    }
    const ContainerKinematics c = system_.container_now(k);
    const EngineConfig& e = scene_.dampers[k].engine;
    const std::vector<std::int32_t> contacts =
        contact_counts(centre, e.radius, e.shape, e.geometry, c);
    d.contacts.insert(d.contacts.end(), contacts.begin(), contacts.end());
    push(d.container_position, c.position);
    for (const Vec3& axis : {c.axis_x, c.axis_y, c.axis_z}) push(d.container_axes, axis);
  }
  next_snapshot_ += plan_.output.particles_every;
}

void FrequencyRun::step() {
  if (stop_requested()) throw Interrupted();
  if (particles_ && system_.time() + 1e-12 >= next_snapshot_) snapshot();
  // A sample is the state at the start of the step, with the tallies up to it.
  const bool sample = system_.time() + 1e-12 >= next_sample_;
  const Energy state = energy_ && sample ? system_.state_energy() : Energy{};
  system_.advance();
  const StepRecord& r = system_.last();
  if (sample) {
    next_sample_ += sample_every_;
    TimeSeries& ts = timeseries_;
    ts.time.push_back(r.time);
    ts.displacement.push_back(r.displacement);
    ts.velocity.push_back(r.velocity);
    ts.damper_force.push_back(r.damper_force);
    ts.damper_force_mean.push_back(impulse_time_ > 0 ? impulse_ / impulse_time_
                                                     : std::numeric_limits<double>::quiet_NaN());
    impulse_ = impulse_time_ = 0;
    ts.frequency.push_back(frequency_);
    if (energy_) {
      EnergySeries& e = *energy_;
      e.time.push_back(r.time);
      e.work_in.push_back(work_in_);
      e.dissipated_structure.push_back(dissipated_s_);
      for (int m = 0; m < kMechanisms; ++m) e.dissipated[m].push_back(dissipated_[m]);
      e.kinetic.push_back(state.kinetic);
      e.potential.push_back(state.potential + r.contact_elastic);
      // Against the first sample, the ledger's origin.
      auto change = [&](const std::vector<double>& column) { return column.back() - column[0]; };
      double balance = change(e.work_in) - change(e.dissipated_structure);
      for (const auto& column : e.dissipated) balance -= change(column);
      e.imbalance.push_back(balance - change(e.kinetic) - change(e.potential));
    }
  }
  const double h = system_.time() - r.time;  // the step (or coupling interval) just taken
  impulse_ += r.damper_force * h;
  impulse_time_ += h;
  dissipated_s_ += r.dissipated_structure;
  dissipated_ += r.dissipated;
  work_in_ += r.work_external;
  if (!std::isfinite(r.displacement))
    throw SimulationError(
        "the structure response became non-finite at t = " + std::to_string(r.time) + " s");
}

std::vector<std::complex<double>> FrequencyRun::impedance() const {
  const double w = system_.drive().omega;
  std::vector<std::complex<double>> z;
  for (std::size_t k = 0; k < effective_mass_.size(); ++k)
    z.emplace_back(-effective_mass_[k] * w * w, w * effective_damping_[k]);
  return z;
}

std::complex<double> FrequencyRun::predict_start() {
  const Eigen::VectorXcd harmonic = system_.predicted_harmonic(impedance());
  // An undamped structure driven at its own frequency has no steady state: carry on instead.
  if (!harmonic.allFinite()) return system_.response_of(Eigen::VectorXcd::Zero(harmonic.size()));
  jump([&] { system_.start_on(harmonic, mean_force_); });
  return system_.response_of(harmonic);
}

// The damper as an equivalent mass and viscous damper, Z = -m w^2 + i c w, from its measured
// first harmonics (Z = -F / U): exact for a bed that moves as a rigid body, and the
// equivalent-linear estimate otherwise, carried to the next frequency.
void FrequencyRun::learn_impedance(const PeriodSummary& mean, double omega) {
  for (std::size_t k = 0; k < effective_mass_.size(); ++k) {
    const std::complex<double> u = mean.container[k];
    if (std::abs(u) == 0) continue;
    const std::complex<double> z = -mean.damper_force[k] / u;
    effective_mass_[k] = -z.real() / (omega * omega);
    effective_damping_[k] = z.imag() / omega;
    mean_force_[k] = mean.damper_force_mean[k];
  }
}

void FrequencyRun::run_period() {
  Ongoing& o = *ongoing_;
  const double h = dt_ * system_.steps_per_advance();
  for (int s = 0; s < o.samples; ++s) {
    const double angle = system_.drive().angle(system_.time());
    step();
    o.tracker.add(system_.last(), h, angle, system_.damper_displacements(),
                  system_.damper_forces());
  }
  periods_running_.store(o.tracker.periods(), std::memory_order_relaxed);
  if (progress_) progress_(o.frequency, double(o.tracker.periods()) / o.max_periods);
}

// The periods after the predicted start's refinement, and how they are judged.
std::pair<std::vector<std::complex<double>>, SteadyStateCriteria> FrequencyRun::measured() const {
  const Ongoing& o = *ongoing_;
  const SettleRule& settle = plan_.settle;
  const auto all =
      o.tracker.series(o.prescribed ? &PeriodSummary::force : &PeriodSummary::displacement);
  // Each fill settles on its own to the tolerance: its value is one member of the point's
  // ensemble, and one fill can be a branch of its own (src/steady_state.hpp).
  // A fixed run is judged once, on what it has: an interval from two batches is wide but
  // says what the periods show.
  // min_periods counts the measured periods; where the refinement took some of max_periods,
  // what is left of them is enough (min_periods = max_periods asks for a fixed dwell).
  const int min_periods = std::min(settle.min_periods, o.max_periods - o.settled_from);
  return {{all.begin() + o.settled_from, all.end()},
          {settle.tolerance, min_periods, o.fixed ? std::min(settle.batches, 2) : settle.batches,
           !o.fixed, o.floors.amplitude, o.floors.phase}};
}

Stationary FrequencyRun::judge() const {
  const auto [series, criteria] = measured();
  const int n = static_cast<int>(series.size()), average = plan_.settle.average_periods;
  Stationary s = analyse_periods(series, criteria,
                                 average > 0 ? std::max(0, n - average) : ongoing_->look_first);
  s.periods += ongoing_->settled_from;
  s.discarded += ongoing_->settled_from;
  return s;
}

bool FrequencyRun::look(const Floors& floors) {
  Ongoing& o = *ongoing_;
  o.floors = floors;
  const auto [series, criteria] = measured();
  // Its value is then the last half's mean: a climb's tail that MSER's warm-up keeps hides in
  // the wider interval the floors allow (steady_state_test: 8 fills climbing with T = 60
  // periods end 1.8 % low with MSER's mean, 1.0 % with the last half's).
  if (known_at_look(series, criteria))
    return o.look_first = static_cast<int>(series.size()) / 2, true;
  o.floors = {};
  return false;
}

void FrequencyRun::begin_frequency(double frequency, double amplitude, FrequencyStart start) {
  const SettleRule& settle = plan_.settle;
  const bool prescribed = plan_.prescribed;
  const int samples = configure(frequency, amplitude);
  const bool fixed = plan_.fixed;
  const int max_periods =
      fixed ? std::max(1, static_cast<int>(std::lround(plan_.duration * frequency)))
            : settle.max_periods;
  ongoing_.emplace(Ongoing{frequency, samples, max_periods, 0, fixed, prescribed,
                           PeriodTracker(samples, system_.engines().size()), Floors{}, -1});
  Ongoing& o = *ongoing_;
  const double omega = 2 * kPi * frequency;
  // The predicted start, refined: the damper's impedance measured over a few periods at this
  // frequency gives a better prediction, and while that moves the structure's state by more
  // than a quarter of the tolerance the structure is put on it again, so that it does not ring
  // at its own frequency for hundreds of periods (a transient decays over 1 / (zeta w) seconds).
  // A prediction that stops improving by half a round is limited by the bed's own scatter, and
  // is left. Those periods are warm-up.
  if (!prescribed && start != FrequencyStart::carried) {
    std::complex<double> predicted = predict_start();
    double moved_before = kInfinity;
    for (int round = 0; round < kRefinements && !system_.engines().empty() &&
                        o.tracker.periods() + kProbePeriods <= max_periods / 2;
         ++round) {
      for (int k = 0; k < kProbePeriods; ++k) run_period();
      learn_impedance(o.tracker.mean_from(o.tracker.periods() - kProbePeriods), omega);
      const std::complex<double> next =
          system_.response_of(system_.predicted_harmonic(impedance()));
      const double moved = std::abs(next - predicted);
      if (moved <= 0.25 * settle.tolerance * std::abs(next) || moved > 0.5 * moved_before) break;
      moved_before = moved;
      predicted = predict_start();
      o.settled_from = o.tracker.periods();
    }
  }
}

bool FrequencyRun::run_until(int periods) {
  Ongoing& o = *ongoing_;
  const int min_periods = plan_.settle.min_periods;
  while (o.tracker.periods() < std::min(periods, o.max_periods)) {
    run_period();
    if (!o.fixed && o.tracker.periods() - o.settled_from >= min_periods && judge().converged)
      return true;
  }
  return o.tracker.periods() >= o.max_periods;
}

FrequencyPoint FrequencyRun::finish() {
  const Ongoing& o = *ongoing_;
  periods_running_.store(0, std::memory_order_relaxed);
  FrequencyPoint point;
  point.frequency = o.frequency;
  point.judged = judge();
  if (o.fixed) {  // no tolerance was asked for: a fixed run is done when its periods are stationary
    Stationary& j = point.judged;
    j.converged = !j.trend && j.batches >= 2;
    j.reason = j.converged ? "" : j.trend ? "drifting" : "too few periods for an interval";
  }
  point.mean = o.tracker.mean_from(point.judged.discarded);
  std::vector<double> energy;
  for (const PeriodSummary& p : o.tracker.all()) energy.push_back(p.energy_in);
  point.energy_in = batch_mean_interval(energy, point.judged.discarded, point.judged.batch_length);
  // Learned again from all the periods after an extension: it replaces the earlier estimate.
  if (!o.prescribed) learn_impedance(point.mean, 2 * kPi * o.frequency);
  point.periods = o.tracker.all();
  for (PeriodSummary& p : point.periods) {  // the point keeps only what /periods reports
    p.container.clear();
    p.damper_force.clear();
    p.damper_force_mean.clear();
  }
  return point;
}

void FrequencyRun::begin_point(double frequency, double amplitude) {
  begin_frequency(frequency, amplitude, plan_.start);
}

FrequencyPoint FrequencyRun::run_point(double frequency, double amplitude) {
  if (!plan_.harmonics) {
    run_free_decay();
    return {};
  }
  begin_point(frequency, amplitude);
  run_until(ongoing_->max_periods);
  return finish();
}

void FrequencyRun::run_free_decay() {
  const double f1 = first_mode(), duration = plan_.duration;
  configure(f1, 0.0);
  system_.set_initial_displacement(plan_.initial_displacement);
  long long done = 0;
  while (system_.time() < duration - 1e-12) {
    step();
    if (progress_ && ++done % 4096 == 0) progress_(f1, system_.time() / duration);
  }
}

template <class Run>
auto FrequencyRun::tally_places(Run& run) {
  auto places = std::vector{&run.dissipated_[kNormal],
                            &run.dissipated_[kTangential],
                            &run.work_in_,
                            &run.next_sample_,
                            &run.restored_angle_,
                            &run.dissipated_[kRolling],
                            &run.dissipated_s_,
                            &run.impulse_,
                            &run.impulse_time_};
  for (int m = kRolling + 1; m < kMechanisms; ++m) places.push_back(&run.dissipated_[m]);
  return places;
}

StateArrays FrequencyRun::save() const {
  StateArrays out = system_.save();
  const Drive& d = system_.drive();
  const double phase = d.omega > 0 ? std::fmod(d.angle(system_.time()), 2 * kPi) : 0.0;
  std::vector<double> tallies;
  for (const double* place : tally_places(*this))
    tallies.push_back(place == &restored_angle_ ? phase : *place);
  out["run.tallies"] = std::move(tallies);
  if (particles_) out["run.next_snapshot"] = std::vector<double>{next_snapshot_};
  out["run.effective_mass"] = effective_mass_;
  out["run.effective_damping"] = effective_damping_;
  out["run.mean_force"] = mean_force_;
  return out;
}

void FrequencyRun::restore(const StateArrays& state) {
  system_.restore(state);
  ongoing_.reset();  // a restored state is between frequencies
  const auto& t = state_values<double>(state, "run.tallies");
  const std::vector<double*> places = tally_places(*this);
  if (t.size() != places.size())
    throw SimulationError("the checkpoint's run.tallies should hold " +
                          std::to_string(places.size()) + " values");
  for (std::size_t k = 0; k < t.size(); ++k) *places[k] = t[k];
  if (particles_) next_snapshot_ = state_value<double>(state, "run.next_snapshot");
  restored_ = true;
  effective_mass_ = state_values<double>(state, "run.effective_mass");
  effective_damping_ = state_values<double>(state, "run.effective_damping");
  mean_force_ = state_values<double>(state, "run.mean_force");
}

}  // namespace pdsim

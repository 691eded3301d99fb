// One coupled system driven through frequencies: the bed settled first, each frequency started
// on its predicted steady state (or carried on, or from the settled bed), run period by period
// until its first harmonic is stationary and known to the tolerance, then summarised. The
// drivers of src/run.cpp run one of these, or several side by side (independent frequencies,
// realisations), and combine what they measure.
#pragma once

#include <atomic>
#include <functional>
#include <optional>
#include <string>

#include "io/results.hpp"
#include "src/harmonics.hpp"
#include "src/run_plan.hpp"
#include "src/steady_state.hpp"

namespace pdsim {

// What one run measured at one frequency.
struct FrequencyPoint {
  double frequency = 0;    // Hz
  Stationary judged;       // the displacement harmonic (prescribed motion: the force harmonic)
  PeriodSummary mean;      // means over the stationary periods
  MeanInterval energy_in;  // J per period
  std::vector<PeriodSummary> periods;  // every period run (dampers' harmonics left out)
};

struct BedReport {
  bool ran = false, settled = false;
  double time_s = 0;  // s of settling
  double speed = 0;   // m/s, largest particle speed at the end
};

class FrequencyRun {
 public:
  // `progress(frequency, fraction of this frequency done)` is called after every period.
  // frequency 0 while the bed settles
  using Progress = std::function<void(double frequency, double fraction)>;
  // Both are kept by reference: they outlive the run.
  FrequencyRun(const Scene& scene, const RunPlan& plan, Progress progress = {});

  // Lets the particles settle under gravity, containers at rest (plan.bed); time stands still.
  BedReport settle_bed();

  // One point of the plan: `frequency` at the drive's `amplitude` (PlanPoint), started as
  // plan.start says, whole periods until converged or settle.max_periods (or the fixed number
  // of periods of a `sine` or a prescribed duration); or the free decay (an empty point; see
  // RunPlan::harmonics).
  FrequencyPoint run_point(double frequency, double amplitude);
  // The same in steps, for a driver that looks at a point's fills together: begin_point()
  // starts it (configure, predicted start); run_until(n) runs periods until the point is done
  // on its own (converged to the tolerance, or max_periods: returns true) or has n periods;
  // judge() says what its periods show now; look(floors) judges them with the floors that the
  // fills' spread allows (known_at_look()) and, when they pass, keeps those floors and the
  // last half of the periods (its mean is the fill's value) for finish(), which ends the point.
  void begin_point(double frequency, double amplitude);
  bool run_until(int periods);
  Stationary judge() const;
  bool look(const Floors& floors);
  FrequencyPoint finish();
  // Periods of the frequency now running, for other threads to read while it runs: 0 before
  // begin_point() and once a point is returned (its Stationary::periods has the count then).
  int periods_running() const { return periods_running_.load(std::memory_order_relaxed); }
  // A free decay: `duration` seconds of time history from the initial displacement.
  void run_free_decay();

  // Time series (and /energy when asked for) recorded so far.
  const TimeSeries& timeseries() const { return timeseries_; }
  const std::optional<EnergySeries>& energy() const { return energy_; }
  const std::optional<ParticleSnapshots>& particles() const { return particles_; }
  void set_records(const TimeSeries& t, const std::optional<EnergySeries>& e,
                   const std::optional<ParticleSnapshots>& p) {
    timeseries_ = t;
    energy_ = e;
    particles_ = p;
  }
  CoupledSystem& system() { return system_; }
  const CoupledSystem& system() const { return system_; }

  // Everything the next frequency depends on: the system, the drive's phase, the tallies and
  // the damper model the prediction uses.
  StateArrays save() const;
  void restore(const StateArrays& state);

 private:
  double first_mode() const;
  // Starts `frequency` (Hz) at the drive's `amplitude` as `start` says.
  void begin_frequency(double frequency, double amplitude, FrequencyStart start);
  void run_period();  // one period, not judged
  std::pair<std::vector<std::complex<double>>, SteadyStateCriteria> measured() const;
  int configure(double frequency, double amplitude);
  void step();
  // Runs `change` (a jump of the state: a new drive, a predicted start) and counts the energy
  // it adds in work_in_ when the ledger is kept.
  template <class Change>
  void jump(Change&& change);
  std::vector<std::complex<double>> impedance() const;  // the dampers' model at the drive's w
  std::complex<double> predict_start();                 // returns the predicted response, m
  void learn_impedance(const PeriodSummary& mean, double omega);
  // The frequency being run: its periods so far, and how they are judged.
  struct Ongoing {
    double frequency = 0;
    int samples = 0, max_periods = 0;
    int settled_from = 0;  // periods of the predicted start's refinement (warm-up)
    bool fixed = false, prescribed = false;
    PeriodTracker tracker;
    Floors floors;  // the half-widths a look found enough (none: the tolerance's)
    // A look's pass keeps the last half of the periods (the first of them; -1: MSER's warm-up).
    int look_first = -1;
  };
  std::optional<Ongoing> ongoing_;
  std::atomic<int> periods_running_{0};

  const Scene& scene_;
  const RunPlan& plan_;
  CoupledSystem system_;
  Progress progress_;
  TimeSeries timeseries_;
  std::optional<EnergySeries> energy_;
  std::optional<ParticleSnapshots> particles_;
  double dt_ = 0, sample_every_ = 0, next_sample_ = 0, frequency_ = 0, next_snapshot_ = 0;
  void snapshot();  // the particles and containers now, into particles_
  // The ledger's cumulative terms, J (see energy_columns).
  Dissipated dissipated_{};
  double dissipated_s_ = 0, work_in_ = 0;
  // The damper force's impulse (N s) over the time (s) since the last time-series sample.
  double impulse_ = 0, impulse_time_ = 0;
  // The drive's phase at a restored state (the restored system has no drive yet).
  double restored_angle_ = 0;
  // The tallies above as the checkpoint keeps them (run.tallies), in their places; a new one is
  // appended (mechanisms after the first three are, from kMechanisms). restored_angle_'s place
  // holds the drive's phase when saved.
  template <class Run>
  static auto tally_places(Run& run);
  bool restored_ = false;
  // The dampers as the prediction sees them: an effective mass (kg) and viscous damping
  // (N s/m) from the last frequency's measured impedance, and the mean force (N); before
  // anything is measured, the bed as a rigid mass carrying its weight.
  std::vector<double> effective_mass_, effective_damping_, mean_force_;
};

}  // namespace pdsim

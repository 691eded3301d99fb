// Steady state of a periodically driven response, judged as statistics: one value per excitation
// period (the period's first harmonic, or its dissipated energy) forms a series whose warm-up is
// found and discarded (MSER), whose remaining drift is tested, and whose stationary mean is given
// with a 95 % confidence interval from batch means, batches two autocorrelation times long. A
// deterministic response converges by the same rule, because its scatter is zero; a chaotic one
// converges when its mean is known to the tolerance asked for.
#pragma once

#include <complex>
#include <limits>
#include <string>
#include <vector>

namespace pdsim {

struct SteadyStateCriteria {
  double tolerance = 1e-2;  // relative 95 % half-width of |H| wanted (and of the phase, rad)
  int min_periods = 10;     // never converged before this many periods
  int min_batches = 4;      // batch means needed for an interval
  // Judged after every period until it passes (a steady-state run), or once at the end of a
  // fixed duration, where an early underestimate of the correlation cannot stop the run.
  bool sequential = true;
  // Half-widths (the amplitude's unit; rad) that are enough whatever the tolerance asks: where
  // the fills of a point spread widely, a fraction of that spread (spread_floors()). The
  // tolerance still sets the resolution and which drift counts.
  double amplitude_floor = 0, phase_floor = 0;
};

// The stationary part of a per-period series of complex first harmonics H_k.
struct Stationary {
  int periods = 0;            // in the series
  int discarded = 0;          // warm-up periods dropped (MSER truncation, in the first half)
  int batch_length = 0;       // periods per batch: 2 tau, rounded up
  int batches = 0;            // batches in the interval (the earliest remainder is not used)
  double lag1 = 0;            // lag-1 autocorrelation of the retained periods
  double tau = 1;             // their integrated autocorrelation time, periods
  std::complex<double> mean;  // over the retained periods
  double amplitude_ci = 0, phase_ci = 0;  // 95 % half-widths of |mean| (its unit) and arg (rad)
  bool correlated = false;  // too few batches of the needed length: run longer (or realisations)
  bool trend = false;       // the retained periods drift, significantly and by a relevant amount
  double drift = 0;         // the amplitude's fitted change across the retained periods, its unit
  // Held still: min_periods run, no relevant drift, and at least two batches (an interval,
  // however wide), whether or not the mean is known to the tolerance: a fill near resonance can
  // wander within its states (at 14.75 Hz on the Saeki deck between 1.75 and 1.97 mm, an
  // autocorrelation time of 90 periods) for longer than any affordable run settles it to 2 %.
  bool stationary = false;
  bool converged = false;  // stationary, and the mean known to the tolerance (or its floors)
  bool by_spread = false;  // converged on the floors only: its interval is wider than tolerance
  std::string reason;      // why not converged ("" when converged)
};

// Analyses H_0..H_{n-1}. Deviations below a tenth of tolerance x |H| are resolution, not signal:
// they neither hold up the warm-up nor count as drift. With first >= 0 the warm-up is taken to
// be periods 0..first-1 instead of being searched for (settle.average_periods).
Stationary analyse_periods(const std::vector<std::complex<double>>& series,
                           const SteadyStateCriteria& criteria, int first = -1);

// What a fill's own interval must reach at a point where fills spread: the fraction
// kSpreadFraction of the sample standard deviation of the fills' amplitudes (its unit), and of
// their phases (rad, about their mean direction) or the amplitude's relative floor, whichever is
// larger, from their current means (two at least; else 0).
// The ensemble mean's variance is (s_b^2 + se^2) / R for a between-fill spread s_b and a
// fill's own standard error se; a fill whose 95 % half-width is s_b / 3 (se about s_b / 6)
// adds 3 % to that variance (1.4 % to the interval), which more periods of it cannot remove
// and another fill divides by R + 1. Measured (resonance_statistics.md): 43 % fewer periods on
// synthetic fills 14 % apart; 10 % fewer near the Saeki resonance, where a fill's own interval
// needs four batches of two autocorrelation times (20-90 periods there) whatever the floors.
constexpr double kSpreadFraction = 1.0 / 3.0;
struct Floors {
  double amplitude = 0, phase = 0;
};
Floors spread_floors(const std::vector<std::complex<double>>& fills);

// A fill judged at a look with the floors of its point's spread (criteria): converged from the
// warm-up found, and also from the last half of its periods alone. A fill climbing to its state
// after a step (a time constant of 60-80 periods near the Saeki resonance) leaves a tail that
// MSER's warm-up keeps: at a floor of 4.7 % a bias of -7.6 % of the level (T = 80), against
// -2.8 % with the last half too; 8 fills climbing with T = 60 end -1.8 % low with MSER's
// mean, -1.0 % with the last half's (the value a look keeps: FrequencyRun::look()), the
// tolerance alone -0.7 % (steady_state_test, resonance_statistics.md).
bool known_at_look(const std::vector<std::complex<double>>& series,
                   const SteadyStateCriteria& criteria);

// Mean and 95 % half-width of a real per-period series over periods first..n-1, in batches of
// `batch_length` (the earliest remainder dropped). A single batch gives a zero half-width only
// when the series is constant, otherwise infinity.
struct MeanInterval {
  double mean = 0, half_width = 0;
};
MeanInterval batch_mean_interval(const std::vector<double>& series, int first, int batch_length);

// Mean of independent values with the 95 % Student-t half-width (realisations of a point).
MeanInterval independent_mean_interval(const std::vector<double>& values);

// One run's mean with its 95 % half-width from batch means of `dof` + 1 batches.
struct RunMean {
  double mean = 0, half_width = 0;
  int dof = 0;
};
// The mean of several independent runs (realisations) of one point. When their means agree
// within their own intervals (Cochran's Q below its 99 % chi-square quantile, each run's
// standard error at least `resolution` / 1.96, so that differences below about twice
// `resolution` never count), the runs sample one state and their intervals pool: the average
// with sqrt(sum se^2) / R, widened to hold every run's mean. When they disagree (coexisting regimes
// of the bed, each run locked in one), no single run's interval means anything and the interval is
// the spread of the runs' means (Student t, R - 1 degrees of freedom).
struct Combined {
  MeanInterval interval;
  bool consistent = true;
};
Combined combine_runs(const std::vector<RunMean>& runs, double resolution);

// One fill (a realisation: a random packing of the damper) at one point: its own stationary
// mean first harmonic and 95 % half-widths (src/frequency_run.cpp), batches - 1 degrees of
// freedom, and whether it settled on its own: its mean known to the tolerance, or held still
// (Stationary::stationary) when max_periods ended it, its interval then as wide as it is.
struct FillValue {
  std::complex<double> harmonic;
  double amplitude_ci = 0, phase_ci = 0;  // its unit, rad
  int dof = 0;
  bool settled = false;
  // A fill not settled at max_periods (drifting, or too correlated for two batches): its
  // amplitude's fitted change over its retained periods (Stationary::drift); NaN: unknown.
  double drift = std::numeric_limits<double>::quiet_NaN();
};

// Mean amplitude and phase of a group of fills with their 95 % intervals (combine_runs():
// pooled when the fills agree within their own intervals, else the Student-t spread of the
// fills' values), and the 95 % prediction half-widths: where one more fill would lie,
// t(R-1) s sqrt(1 + 1/R) over the fills' values (NaN for a single fill: not estimable).
struct GroupMean {
  MeanInterval amplitude, phase;  // phase in rad, of the group's mean direction
  double amplitude_spread = 0, phase_spread = 0;
  bool consistent = true;        // amplitudes and phases agree within the fills' intervals
  bool amplitudes_agree = true;  // the amplitudes alone do
  int fills = 0;
  // Its share of the point's fills, and the 95 % Wilson score interval of that proportion.
  double share = 1, share_low = 0, share_high = 1;
  // The amplitude (the FRF's quantity) known to `tolerance`, relative; the phase is reported
  // with its interval (each fill's own phase has settled to the tolerance in rad).
  bool within(double tolerance) const { return amplitude.half_width <= tolerance * amplitude.mean; }
};

// A point's result over its fills. Near resonance the fills of one damper design hold distinct
// steady states; the result is their distribution: the ensemble mean with its interval, the
// spread where one fill lies, and the branches: fills linked (single linkage) when their
// amplitudes differ by at most the tolerance of the larger or by their own intervals, so that
// fills in one state form one branch and states apart beyond the tolerance are told apart.
enum class PointResult { none = 0, one_state = 1, branches = 2 };
struct Ensemble {
  GroupMean mean;                 // over every fill
  std::vector<GroupMean> branch;  // ordered by amplitude, highest first
  std::vector<int> branch_of;     // per fill, index into branch
  std::vector<FillValue> fills;   // as judged: a drift that counts is in its half-width
  PointResult result = PointResult::none;
  // More fills would help: every fill settled, but the ensemble mean's interval misses the
  // tolerance (its branches may each meet it: a result of several branches all the same); or
  // a fill still moving at max_periods, whose change more fills' spread would judge.
  bool wants_fills = false;
  std::string reason;  // why not a result, or what the branches are ("" for one state)
};
// Result rules: every fill must have settled on its own, or moved over its retained periods at
// max_periods (drifting, or wandering too slowly for two batches) by no more than the standard
// deviation of the fills' amplitudes, or the tolerance where they agree closer (it then counts
// with that change added to its half-width, and the ensemble mean's half-width grows by the sum
// of such changes over the number of fills); else not a result (a fill still moving at
// max_periods by more); then one state when the
// ensemble mean amplitude's interval meets `tolerance` (relative), several branches when there are
// two or more and each branch's mean meets it (the ensemble mean then carries its wide interval).
// With `last` (no more fills will come: settle.max_realisations reached), fills that are distinct
// beyond their own intervals (Cochran's Q, combine_runs()) are a result of several states even
// where a branch's mean misses the tolerance: the distribution over fills is what this damper has
// there, and the mean, the spread and each branch carry their own intervals (GroupMean::within says
// which meet the tolerance). Fills that agree on one state whose mean misses the tolerance are not
// a result: their own intervals are too wide (more periods, settle.max_periods, would narrow them).
Ensemble judge_ensemble(const std::vector<FillValue>& fills, double tolerance, bool last = false);

// Two-sided 95 % and 99 % quantiles of Student's t with `dof` degrees of freedom (infinity for
// dof < 1).
double student_t975(int dof);
double student_t995(int dof);

}  // namespace pdsim

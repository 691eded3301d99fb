#include "src/steady_state.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "kernels/vec3.hpp"

namespace pdsim {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

double mean_of(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double sample_sd(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = mean_of(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

// Means of consecutive batches of `length` values of v[first..], the earliest remainder dropped.
std::vector<double> batch_means(const std::vector<double>& v, int first, int length) {
  const int n = static_cast<int>(v.size()) - first, count = n / length;
  std::vector<double> means;
  for (int b = 0; b < count; ++b) {
    double s = 0;
    const int from = first + (n - count * length) + b * length;
    for (int k = 0; k < length; ++k) s += v[static_cast<std::size_t>(from + k)];
    means.push_back(s / length);
  }
  return means;
}

// Quantiles of Student's t for dof 1..30 (tables), beyond by the Cornish-Fisher expansion about
// the normal quantile z (Abramowitz & Stegun 26.7.5).
double student_t(int dof, const double (&table)[30], double z) {
  if (dof < 1) return kInfinity;
  if (dof <= 30) return table[dof - 1];
  const double n = dof;
  const double z3 = z * z * z, z5 = z3 * z * z, z7 = z5 * z * z;
  return z + (z3 + z) / (4 * n) + (5 * z5 + 16 * z3 + 3 * z) / (96 * n * n) +
         (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / (384 * n * n * n);
}

// Integrated autocorrelation time tau = 1 + 2 sum rho_k of zero-mean deviations (the sum of
// their components' lagged products), summed by Geyer's initial monotone sequence (Statist.
// Sci. 7:473, 1992): pairs rho_2m + rho_2m+1 while they stay positive and decrease. An
// exponential correlation (AR(1), a bed that relaxes) gives (1 + phi) / (1 - phi); an
// oscillating one (the structure ringing against the drive: a beat) cancels itself over its
// period, although neighbouring periods correlate strongly. The variance of a mean of m values
// is var tau / m. Also returns the lag-1 autocorrelation.
double autocorrelation_time(const std::vector<std::vector<double>>& components, double* lag1) {
  const int m = static_cast<int>(components[0].size());
  auto lagged = [&](int lag) {
    double sum = 0;
    for (const auto& e : components)
      for (int k = 0; k + lag < m; ++k)
        sum += e[static_cast<std::size_t>(k)] * e[static_cast<std::size_t>(k + lag)];
    return sum;
  };
  const double scatter = lagged(0);
  *lag1 = 0;
  if (!(scatter > 0)) return 1;
  *lag1 = lagged(1) / scatter;
  double sum = 0, previous = kInfinity;
  for (int k = 0; 2 * k + 1 < m; ++k) {
    const double pair = std::min((lagged(2 * k) + lagged(2 * k + 1)) / scatter, previous);
    if (pair <= 0) break;
    sum += pair;
    previous = pair;
  }
  return std::max(1.0, 2 * sum - 1);
}

// Least-squares slope of y_k against k (per period) and whether it differs from zero at the
// 99 % level. The residuals' own autocorrelation time tau (a drift must not count as
// correlation) widens the slope's variance by tau and leaves about m / tau independent values.
// (A stricter level than the intervals': the test is repeated after every period, and a false
// alarm only costs periods.)
bool significant_slope(const std::vector<double>& y, double* slope) {
  const int m = static_cast<int>(y.size());
  if (m < 3) return false;
  const double kbar = 0.5 * (m - 1), ybar = mean_of(y);
  double skk = 0, sky = 0;
  for (int k = 0; k < m; ++k) {
    skk += (k - kbar) * (k - kbar);
    sky += (k - kbar) * (y[static_cast<std::size_t>(k)] - ybar);
  }
  *slope = sky / skk;
  std::vector<double> residual(static_cast<std::size_t>(m));
  double squares = 0;
  for (int k = 0; k < m; ++k) {
    const double r = y[static_cast<std::size_t>(k)] - ybar - *slope * (k - kbar);
    residual[static_cast<std::size_t>(k)] = r;
    squares += r * r;
  }
  double lag1 = 0;
  const double tau = autocorrelation_time({residual}, &lag1);
  const double independent = m / tau;
  if (independent < 3) return false;
  const double se = std::sqrt(squares / (m - 2) * tau / skk);
  return std::fabs(*slope) > student_t995(static_cast<int>(independent) - 2) * se;
}

}  // namespace

double student_t975(int dof) {
  static const double table[30] = {12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306,
                                   2.262,  2.228, 2.201, 2.179, 2.160, 2.145, 2.131, 2.120,
                                   2.110,  2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
                                   2.060,  2.056, 2.052, 2.048, 2.045, 2.042};
  return student_t(dof, table, 1.959963984540054);
}

double student_t995(int dof) {
  static const double table[30] = {63.657, 9.925, 5.841, 4.604, 4.032, 3.707, 3.499, 3.355,
                                   3.250,  3.169, 3.106, 3.055, 3.012, 2.977, 2.947, 2.921,
                                   2.898,  2.878, 2.861, 2.845, 2.831, 2.819, 2.807, 2.797,
                                   2.787,  2.779, 2.771, 2.763, 2.756, 2.750};
  return student_t(dof, table, 2.5758293035489004);
}

MeanInterval batch_mean_interval(const std::vector<double>& series, int first, int batch_length) {
  MeanInterval out;
  if (first >= static_cast<int>(series.size())) return {0, kInfinity};
  const std::vector<double> retained(series.begin() + first, series.end());
  out.mean = mean_of(retained);
  const std::vector<double> means = batch_means(series, first, std::max(1, batch_length));
  const int b = static_cast<int>(means.size());
  if (retained.size() < 2) return {out.mean, kInfinity};
  const double sd = b >= 2 ? sample_sd(means) : sample_sd(retained);
  out.half_width = sd == 0 ? 0 : b >= 2 ? student_t975(b - 1) * sd / std::sqrt(b) : kInfinity;
  return out;
}

MeanInterval independent_mean_interval(const std::vector<double>& values) {
  if (values.empty()) return {0, kInfinity};
  const int r = static_cast<int>(values.size());
  if (r < 2) return {values[0], kInfinity};
  return {mean_of(values), student_t975(r - 1) * sample_sd(values) / std::sqrt(r)};
}

Combined combine_runs(const std::vector<RunMean>& runs, double resolution) {
  const int r = static_cast<int>(runs.size());
  if (r == 1) return {{runs[0].mean, runs[0].half_width}, true};
  // Standard errors with the resolution as a floor, and the precision-weighted mean for Q.
  std::vector<double> means, variances;
  double weights = 0, weighted = 0, pooled = 0;
  int dof = 0;
  for (const RunMean& run : runs) {
    const double se = run.half_width == 0 ? 0
                      : run.dof < 1 || !std::isfinite(run.half_width)
                          ? kInfinity
                          : run.half_width / student_t975(run.dof);
    const double floor = resolution / 1.959963984540054;
    means.push_back(run.mean);
    variances.push_back(se * se + floor * floor);
    pooled += se * se;
    dof += run.dof;
  }
  for (int k = 0; k < r; ++k) {
    const double w = variances[std::size_t(k)] > 0 ? 1 / variances[std::size_t(k)] : kInfinity;
    weights += w;
    weighted += w * means[std::size_t(k)];
  }
  // Runs without an interval of their own weigh nothing; when no run has one, plain mean.
  const double centre = weights > 0 && std::isfinite(weights) ? weighted / weights : mean_of(means);
  double q = 0;
  for (int k = 0; k < r; ++k) {
    const double d = means[std::size_t(k)] - centre;
    q += d == 0 ? 0 : d * d / variances[std::size_t(k)];
  }
  // 99 % chi-square quantile by Wilson and Hilferty (within 1 % from one degree of freedom).
  const double k = r - 1, z = 2.3263478740408408;
  const double a = 2 / (9 * k), chi2 = k * std::pow(1 - a + z * std::sqrt(a), 3);
  const MeanInterval spread = independent_mean_interval(means);
  const double pooled_width = student_t975(dof) * std::sqrt(pooled) / r;
  if (q <= chi2) {  // one state: the pooled interval, wide enough to hold every run's mean
    double farthest = 0;
    for (double m : means) farthest = std::max(farthest, std::fabs(m - spread.mean));
    return {{spread.mean, std::max(pooled_width, farthest)}, true};
  }
  // The runs' means scatter with their own noise as well as the regimes: their Student-t
  // interval holds both (a run without an interval of its own still counts).
  return {spread, false};
}

namespace {

// Everything but the verdict: warm-up, mean, autocorrelation, intervals, drift.
Stationary summarise(const std::vector<std::complex<double>>& series,
                     const SteadyStateCriteria& criteria, int first) {
  Stationary s;
  const int n = static_cast<int>(series.size());
  s.periods = n;
  if (n < 2) return s;
  // Values about the mean of the last half, so that sums of squares keep their digits.
  std::complex<double> reference = 0;
  for (int k = n / 2; k < n; ++k) reference += series[static_cast<std::size_t>(k)];
  reference /= double(n - n / 2);
  const double resolution = 0.1 * criteria.tolerance * std::abs(reference);
  std::vector<std::complex<double>> x(series.size());
  for (std::size_t k = 0; k < x.size(); ++k) x[k] = series[k] - reference;

  // MSER truncation (White 1997) on the one-period values: the warm-up d minimises the squared
  // standard error of the mean of what remains, sum |x_k - mean_d|^2 / (n - d)^2, with the
  // resolution as a floor on every deviation so that a converged deterministic response stops
  // at its first resolved period instead of chasing rounding. d is sought in the first half
  // only (White's own rule): on a smooth, correlated series, such as a structure ringing
  // against the drive, the statistic keeps falling towards the last few periods, whose naive
  // variance says nothing. A transient that lasts into the second half shows as a drift there.
  int best = 0;
  double best_value = kInfinity, sum_x_re = 0, sum_x_im = 0, sum_sq = 0;
  for (int d = n - 1; d >= 0; --d) {
    const std::complex<double> v = x[static_cast<std::size_t>(d)];
    sum_x_re += v.real();
    sum_x_im += v.imag();
    sum_sq += std::norm(v);
    const double m = n - d;
    if (d > n / 2) continue;
    const double ss = std::max(0.0, sum_sq - (sum_x_re * sum_x_re + sum_x_im * sum_x_im) / m);
    const double mser = (ss + m * resolution * resolution) / (m * m);
    if (mser <= best_value) {  // the earliest of equal minima
      best_value = mser;
      best = d;
    }
  }
  if (first >= 0) best = std::min(first, n - 1);
  s.discarded = best;

  const int retained = n - best;
  std::complex<double> mean = 0;
  for (int k = best; k < n; ++k) mean += x[static_cast<std::size_t>(k)];
  mean /= double(retained);
  s.mean = mean + reference;
  // How long the retained periods remember (autocorrelation_time); deviations below the
  // resolution are none.
  std::vector<std::vector<double>> deviation(
      2, std::vector<double>(static_cast<std::size_t>(retained)));
  double scatter = 0;
  for (int k = best; k < n; ++k) {
    const std::complex<double> e = x[static_cast<std::size_t>(k)] - mean;
    deviation[0][static_cast<std::size_t>(k - best)] = e.real();
    deviation[1][static_cast<std::size_t>(k - best)] = e.imag();
    scatter += std::norm(e);
  }
  const double tau =
      scatter > retained * resolution * resolution ? autocorrelation_time(deviation, &s.lag1) : 1.0;
  s.tau = tau;
  // Batch means of 2 tau periods (rounded up): nearly independent for any correlation shape
  // (adjacent batches of an AR(1) correlate by 0.13 at phi = 0.5). At least 5 periods when
  // there is scatter: tau from a few dozen periods is biased low, and a sequential test runs
  // after every period, so an early underestimate would stop a run with too narrow an interval.
  const int shortest = criteria.sequential && scatter > retained * resolution * resolution ? 5 : 1;
  s.batch_length = std::max(shortest, static_cast<int>(std::ceil(2 * tau - 1e-9)));
  // Judged once, a short fixed run takes the batches it has room for: its interval then
  // follows the periods' scatter even where they correlate (a wider one needs a longer run).
  if (!criteria.sequential)
    s.batch_length = std::min(s.batch_length, std::max(1, retained / criteria.min_batches));

  // Components along and across the mean: their intervals are those of |H| and of arg H.
  const double size = std::abs(s.mean);
  const std::complex<double> along = size > 0 ? s.mean / size : 1.0;
  std::vector<double> amplitude(static_cast<std::size_t>(n)), across(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const std::complex<double> turned = std::conj(along) * series[static_cast<std::size_t>(k)];
    amplitude[static_cast<std::size_t>(k)] = turned.real();
    across[static_cast<std::size_t>(k)] = turned.imag();
  }
  const std::vector<double> a = batch_means(amplitude, best, s.batch_length);
  const std::vector<double> p = batch_means(across, best, s.batch_length);
  s.batches = static_cast<int>(a.size());
  s.correlated = 2 * tau > shortest && s.batches < criteria.min_batches;
  if (s.batches >= 2) {
    const double t = student_t975(s.batches - 1), root = std::sqrt(double(s.batches));
    s.amplitude_ci = t * sample_sd(a) / root;
    const double spread = t * sample_sd(p) / root;
    s.phase_ci = size > 0 ? spread / size : (spread == 0 ? 0 : kPi);
  } else {
    s.amplitude_ci = s.phase_ci = kInfinity;
  }
  // A drift matters when it is significant and moves the mean by half the tolerance across the
  // retained periods.
  double slope_a = 0, slope_p = 0;
  const double relevant = 0.5 * criteria.tolerance * size;
  const std::vector<double> kept_a(amplitude.begin() + best, amplitude.end());
  const std::vector<double> kept_p(across.begin() + best, across.end());
  const bool drift_a =
      significant_slope(kept_a, &slope_a) && std::fabs(slope_a) * retained > relevant;
  const bool drift_p =
      significant_slope(kept_p, &slope_p) && std::fabs(slope_p) * retained > relevant;
  s.trend = drift_a || drift_p;
  s.drift = std::fabs(slope_a) * retained;
  s.stationary = n >= criteria.min_periods && !s.trend && s.batches >= 2;
  return s;
}

}  // namespace

Stationary analyse_periods(const std::vector<std::complex<double>>& series,
                           const SteadyStateCriteria& criteria, int first) {
  Stationary s = summarise(series, criteria, first);
  const int n = s.periods;
  const double tol = criteria.tolerance, size = std::abs(s.mean);
  // The half-widths enough here: the tolerance's, or the floors where the fills spread wider.
  const double amplitude_enough = std::max(tol * size, criteria.amplitude_floor);
  const double phase_enough = std::max(tol, criteria.phase_floor);
  auto enough = [&] { return s.amplitude_ci <= amplitude_enough && s.phase_ci <= phase_enough; };
  char text[64];
  if (n < 2) {
    s.reason = "fewer than 2 periods";
  } else if (n < criteria.min_periods) {
    s.reason = "fewer than min_periods (" + std::to_string(criteria.min_periods) + ") periods";
  } else if (s.trend) {
    s.reason = "drifting";
  } else if (s.batches < criteria.min_batches) {
    std::snprintf(text, sizeof text, "%.1f", s.tau);
    s.reason = s.correlated
                   ? std::string("periods too correlated (autocorrelation time ") + text +
                         " periods) for " + std::to_string(criteria.min_batches) + " batches of " +
                         std::to_string(s.batch_length) + " periods"
                   : "too few periods for " + std::to_string(criteria.min_batches) + " batches";
  } else if (!enough()) {
    s.reason = "interval wider than the tolerance";
  } else if (first < 0) {
    // The mean must also hold still. The test runs after every period, so a slow drift, or a
    // wander slower than the periods' autocorrelation shows, would pass at some look: the mean
    // of the first half of the periods, judged the same way, is compared with the whole's, and
    // their difference widens the interval (it is direct evidence of how well the mean is known).
    const int earlier = (n + 1) / 2;
    if (earlier < n) {
      const Stationary before = summarise({series.begin(), series.begin() + earlier}, criteria, -1);
      const std::complex<double> moved = s.mean - before.mean;
      const std::complex<double> along = size > 0 ? s.mean / size : 1.0;
      const std::complex<double> turned = std::conj(along) * moved;
      s.amplitude_ci = std::max(s.amplitude_ci, std::fabs(turned.real()));
      s.phase_ci = std::max(s.phase_ci, size > 0 ? std::fabs(turned.imag()) / size : 0.0);
      if (!enough()) {
        std::snprintf(text, sizeof text, "%.2g %%", 100 * std::abs(moved) / std::max(size, 1e-300));
        s.reason = "still moving (the mean moved " + std::string(text) + " since period " +
                   std::to_string(earlier) + ")";
      }
    }
  }
  s.converged = s.reason.empty();
  s.by_spread = s.converged && (s.amplitude_ci > tol * size || s.phase_ci > tol);
  return s;
}

bool known_at_look(const std::vector<std::complex<double>>& series,
                   const SteadyStateCriteria& criteria) {
  const int n = static_cast<int>(series.size());
  return analyse_periods(series, criteria).converged &&
         analyse_periods(series, criteria, n / 2).converged;
}

Floors spread_floors(const std::vector<std::complex<double>>& fills) {
  if (fills.size() < 2) return {};
  std::complex<double> sum = 0;
  for (const auto& h : fills) sum += h;
  const std::complex<double> along = std::abs(sum) > 0 ? sum / std::abs(sum) : 1.0;
  std::vector<double> amplitudes, phases;
  for (const auto& h : fills) {
    amplitudes.push_back(std::abs(h));
    phases.push_back(std::arg(std::conj(along) * h));
  }
  // The phase to the same relative precision as the amplitude at least (a harmonic known to a
  // circle about its mean), or to its own spread's share.
  const double amplitude = kSpreadFraction * sample_sd(amplitudes);
  return {amplitude,
          std::max(kSpreadFraction * sample_sd(phases), amplitude / mean_of(amplitudes))};
}

}  // namespace pdsim

namespace pdsim {
namespace {

// Mean of the fills `members` (indices into fills) about their mean direction; see GroupMean.
// `moved`: per fill, the change of a fill that counts though it still moved at the cap (0 for
// the others); their sum over the members, divided by their number, widens the mean's interval.
GroupMean group_mean(const std::vector<FillValue>& fills, const std::vector<int>& members,
                     double tolerance, const std::vector<double>& moved) {
  GroupMean g;
  g.fills = static_cast<int>(members.size());
  std::complex<double> sum = 0;
  for (int k : members) sum += fills[std::size_t(k)].harmonic;
  // Amplitudes and phases are combined separately: fills in states of different phase would
  // shrink a mean of their complex harmonics below every fill's amplitude. Each fill's phase is
  // taken about the direction of that mean.
  const std::complex<double> along = std::abs(sum) > 0 ? sum / std::abs(sum) : 1.0;
  std::vector<RunMean> a, q;
  std::vector<double> amplitudes, phases;
  for (int k : members) {
    const FillValue& f = fills[std::size_t(k)];
    a.push_back({std::abs(f.harmonic), f.amplitude_ci, f.dof});
    q.push_back({std::arg(std::conj(along) * f.harmonic), f.phase_ci, f.dof});
    amplitudes.push_back(a.back().mean);
    phases.push_back(q.back().mean);
  }
  double typical = 0;  // the mean amplitude, the scale of the tolerance
  for (double x : amplitudes) typical += x / double(amplitudes.size());
  // Fills that agree to within about the tolerance are one state for the question asked.
  const Combined amplitude = combine_runs(a, 0.5 * tolerance * typical);
  const Combined phase = combine_runs(q, 0.5 * tolerance);
  g.amplitude = amplitude.interval;
  double shift = 0;  // the most the fills still moving at the cap can move the mean
  for (int k : members) shift += moved[std::size_t(k)] / double(members.size());
  g.amplitude.half_width += shift;
  g.phase = {std::arg(along * std::polar(1.0, phase.interval.mean)),
             std::min(kPi, phase.interval.half_width)};
  g.consistent = amplitude.consistent && phase.consistent;
  g.amplitudes_agree = amplitude.consistent;
  const int r = g.fills;
  auto predict = [r](const std::vector<double>& v) {
    return r < 2 ? std::nan("") : student_t975(r - 1) * sample_sd(v) * std::sqrt(1 + 1.0 / r);
  };
  g.amplitude_spread = predict(amplitudes);
  g.phase_spread = std::min(kPi, predict(phases));
  return g;
}

}  // namespace

Ensemble judge_ensemble(const std::vector<FillValue>& given, double tolerance, bool last) {
  // A fill still moving at max_periods (drifting, or too slow a wander for two batches) counts
  // when its fitted change over its retained periods (the drift) is within the spread of the
  // damper's states, the standard deviation of the fills' amplitudes (or the tolerance, where
  // the fills agree closer): it is then a member of the ensemble whose place is known to that
  // change. Its mean lies half the change from where it ended, and the state it was heading for
  // lies beyond by an amount the change bounds while a climb slows, so the whole change is added
  // to its half-width, and to the ensemble mean's half-width the most such fills can move it,
  // the sum of their changes over the number of fills. A larger change is a fill that has not
  // reached any of the states the others show: the point is not a result. (A wander too slow
  // for an interval keeps none: its value counts through the spread.)
  std::vector<FillValue> fills = given;
  const int n = static_cast<int>(fills.size());
  std::vector<double> amplitudes;
  for (const FillValue& f : given) amplitudes.push_back(std::abs(f.harmonic));
  const double allowed =
      n < 2 ? 0 : std::max(sample_sd(amplitudes), tolerance * mean_of(amplitudes));
  std::vector<double> moved(static_cast<std::size_t>(n), 0.0);
  for (int k = 0; k < n; ++k) {
    FillValue& f = fills[std::size_t(k)];
    if (!f.settled && f.drift <= allowed)
      f.settled = true, f.amplitude_ci += f.drift, moved[std::size_t(k)] = f.drift;
  }
  Ensemble e;
  e.fills = fills;
  std::vector<int> all(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) all[std::size_t(k)] = k;
  // Judged on the fills' own half-widths (the changes widen the mean once, in group_mean()).
  e.mean = group_mean(given, all, tolerance, moved);
  // Branches: single linkage over the fills' complex harmonics (a union-find of the links).
  std::vector<int> root(all);
  auto find = [&](int k) {
    while (root[std::size_t(k)] != k)
      k = root[std::size_t(k)] = root[std::size_t(root[std::size_t(k)])];
    return k;
  };
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      const FillValue &a = given[std::size_t(i)], &b = given[std::size_t(j)];
      const double gap = std::fabs(std::abs(a.harmonic) - std::abs(b.harmonic));
      const double larger = std::max(std::abs(a.harmonic), std::abs(b.harmonic));
      // A fill without an interval of its own (too correlated for batch means) links by the
      // tolerance alone, or it would join every state into one.
      const double own = a.amplitude_ci + b.amplitude_ci;
      if (gap <= tolerance * larger || (std::isfinite(own) && gap <= own))
        root[std::size_t(find(i))] = find(j);
    }
  std::vector<std::vector<int>> groups;
  std::vector<int> group_of_root(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < n; ++k) {
    int& g = group_of_root[std::size_t(find(k))];
    if (g < 0) g = static_cast<int>(groups.size()), groups.emplace_back();
    groups[std::size_t(g)].push_back(k);
  }
  for (const auto& members : groups) {
    GroupMean g = group_mean(given, members, tolerance, moved);
    // The share of the fills, with the Wilson score interval (95 %) of a binomial proportion.
    const double p = double(g.fills) / n, z = 1.959963984540054, z2 = z * z;
    const double centre = (p + z2 / (2.0 * n)) / (1 + z2 / n);
    const double half = z / (1 + z2 / n) * std::sqrt(p * (1 - p) / n + z2 / (4.0 * n * n));
    g.share = p;
    g.share_low = std::max(0.0, centre - half);
    g.share_high = std::min(1.0, centre + half);
    e.branch.push_back(g);
  }
  std::vector<int> order(groups.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::sort(order.begin(), order.end(), [&](int x, int y) {
    return e.branch[std::size_t(x)].amplitude.mean > e.branch[std::size_t(y)].amplitude.mean;
  });
  std::vector<GroupMean> sorted;
  e.branch_of.assign(static_cast<std::size_t>(n), 0);
  for (std::size_t rank = 0; rank < order.size(); ++rank) {
    sorted.push_back(e.branch[std::size_t(order[rank])]);
    for (int k : groups[std::size_t(order[rank])])
      e.branch_of[std::size_t(k)] = static_cast<int>(rank);
  }
  e.branch = std::move(sorted);

  int unsettled = 0;
  bool measured = true;  // every fill still moving has a change to judge against the spread
  for (const FillValue& f : fills)
    if (!f.settled) ++unsettled, measured = measured && std::isfinite(f.drift);
  char text[96];
  if (n == 0) {
    e.reason = "no fills";
  } else if (unsettled > 0) {
    std::snprintf(text, sizeof text, "%d of %d fills not settled on their own (drifting)",
                  unsettled, n);
    e.reason = text;
    // More fills measure the spread that such a fill's change is judged against (with two,
    // their standard deviation is known to within a factor of 30 at 95 %).
    e.wants_fills = !last && measured;
  } else if (e.mean.within(tolerance)) {
    e.result = e.branch.size() > 1 ? PointResult::branches : PointResult::one_state;
  } else {
    e.wants_fills = true;
    const bool each =
        e.branch.size() > 1 && std::all_of(e.branch.begin(), e.branch.end(),
                                           [&](const GroupMean& g) { return g.within(tolerance); });
    if (each || (last && !e.mean.amplitudes_agree)) {
      e.result = PointResult::branches;
    } else if (last) {
      std::snprintf(text, sizeof text,
                    "%d fills agree on one state whose mean is not known to the tolerance", n);
      e.reason = text;
    } else {
      std::snprintf(text, sizeof text, "the mean over %d fills is not known to the tolerance", n);
      e.reason = text;
    }
  }
  if (e.result == PointResult::branches) {
    std::snprintf(text, sizeof text, "%zu branches", e.branch.size());
    // Fills that disagree beyond their intervals with no gap wider than the tolerance.
    e.reason = e.branch.size() > 1 ? text : "a continuum of states";
  }
  return e;
}

}  // namespace pdsim

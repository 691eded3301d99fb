#include "src/point_rows.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "src/format.hpp"

namespace pdsim {

bool settled(const Stationary& j) {
  return j.converged || j.stationary;
}

Ensemble judge_fills(const std::vector<FrequencyPoint>& runs, const RunPlan& plan) {
  std::vector<FillValue> fills;
  for (const FrequencyPoint& p : runs)
    fills.push_back({p.judged.mean, p.judged.amplitude_ci, p.judged.phase_ci, p.judged.batches - 1,
                     settled(p.judged), p.judged.drift});
  const bool last = static_cast<int>(runs.size()) >= plan.most_fills;
  Ensemble e = judge_ensemble(fills, plan.settle.tolerance, last);
  if (plan.fixed) {
    const bool all = std::all_of(runs.begin(), runs.end(),
                                 [](const FrequencyPoint& p) { return p.judged.converged; });
    e.result = !all                  ? PointResult::none
               : e.branch.size() > 1 ? PointResult::branches
                                     : PointResult::one_state;
    e.wants_fills = false;
    e.reason = all ? "" : "drifting or too short for an interval";
  }
  return e;
}

std::string point_text(const RunPlan& plan, std::size_t s) {
  bool both = false;
  for (const PlanPoint& p : plan.points) both = both || p.sweep != plan.points[0].sweep;
  const PlanPoint& p = plan.points[s];
  const std::string amplitude =
      plan.amplitude_steps ? ", amplitude " + number(p.amplitude) + (plan.prescribed ? " m" : "")
                           : "";
  return "f = " + number(p.frequency) + " Hz" + amplitude +
         (both ? (p.sweep > 0 ? " (up)" : " (down)") : "");
}

std::string fill_text(const FrequencyPoint& p, std::size_t r, const RunPlan& plan) {
  if (!plan.harmonics)
    return "free decay from " + number(plan.initial_displacement) + " m: " + number(plan.duration) +
           " s";
  std::ostringstream s;
  s.precision(4);
  s << "f = " << p.frequency << " Hz";
  if (plan.most_fills > 1) s << " (fill " << r + 1 << ")";
  s << ": " << amplitude_text(std::abs(p.judged.mean), p.judged.amplitude_ci, plan.prescribed)
    << ", " << p.judged.periods << " periods (" << p.judged.discarded << " warm-up)";
  if (plan.fixed)
    s << ", fixed duration" << (p.judged.converged ? "" : ", " + p.judged.reason);
  else
    s << (p.judged.by_spread   ? ", settled to a third of the fills' spread"
          : p.judged.converged ? ", settled"
          : settled(p.judged)  ? ", held still (" + p.judged.reason + ")"
                               : ", NOT settled: " + p.judged.reason);
  return s.str();
}

std::string ensemble_text(const Ensemble& e, bool prescribed) {
  std::ostringstream s;
  s.precision(4);
  const GroupMean& m = e.mean;
  s << m.fills << (m.fills == 1 ? " fill: " : " fills: ")
    << amplitude_text(m.amplitude.mean, m.amplitude.half_width, prescribed);
  if (m.fills > 1)
    s << " (one fill within +- " << 100 * m.amplitude_spread / std::max(m.amplitude.mean, 1e-300)
      << " %)";
  s << ", phase " << m.phase.mean << " +- " << m.phase.half_width << " rad";
  if (e.branch.size() > 1) {
    s << "; " << e.branch.size() << " branches:";
    for (const GroupMean& b : e.branch)
      s << " " << amplitude_text(b.amplitude.mean, b.amplitude.half_width, prescribed) << " at "
        << b.phase.mean << " rad (" << b.fills << " of " << m.fills << ")";
  }
  s << (e.result == PointResult::one_state  ? "; a result"
        : e.result == PointResult::branches ? "; a result of several branches"
                                            : "; NOT a result: " + e.reason);
  return s.str();
}

void add_row(Results& out, const std::vector<std::pair<int, FrequencyPoint>>& fills, int sweep,
             double amplitude, const RunPlan& plan) {
  const bool prescribed = plan.prescribed;
  std::vector<FrequencyPoint> runs;
  for (const auto& [r, p] : fills) runs.push_back(p);
  const Ensemble e = judge_fills(runs, plan);
  const GroupMean& m = e.mean;
  std::vector<RunMean> energy;
  std::vector<double> rms;
  std::array<std::vector<double>, kMechanisms> dissipated;
  double peak = 0;
  int periods = 0, discarded = 0;
  for (const FrequencyPoint& p : runs) {
    energy.push_back({p.energy_in.mean, p.energy_in.half_width, p.judged.batches - 1});
    rms.push_back(std::sqrt(p.mean.mean_square));
    peak = std::max(peak, p.mean.peak);
    for (int d = 0; d < kMechanisms; ++d) dissipated[d].push_back(p.mean.dissipated[d]);
    periods = std::max(periods, p.judged.periods);
    discarded = std::max(discarded, p.judged.discarded);
  }
  const MeanInterval energy_in = combine_runs(energy, 0).interval;
  auto average = [](const std::vector<double>& values) {
    double s = 0;
    for (double v : values) s += v;
    return s / double(values.size());
  };
  const double frequency = runs[0].frequency;
  const int count = static_cast<int>(runs.size());
  const int interval = count == 1 ? 0 : m.consistent ? 1 : 2;
  const int converged = e.result != PointResult::none ? 1 : 0;
  for (const auto& [r, point] : fills)
    for (std::size_t k = 0; k < point.periods.size(); ++k) {
      const PeriodSummary& p = point.periods[k];
      PeriodTable& t = out.periods;
      t.frequency.push_back(frequency);
      t.realisation.push_back(r);
      t.period.push_back(static_cast<int>(k));
      t.stationary.push_back(static_cast<int>(k) >= point.judged.discarded ? 1 : 0);
      t.amplitude.push_back(std::abs(p.displacement));
      t.phase.push_back(std::arg(p.displacement));
      t.force_amplitude.push_back(std::abs(p.force));
      t.force_phase.push_back(std::arg(p.force));
      t.energy_in.push_back(p.energy_in);
    }
  if (prescribed) {
    PrescribedTable& p = out.prescribed;
    p.frequency.push_back(frequency);
    p.sweep.push_back(sweep);
    p.amplitude.push_back(amplitude);
    p.dissipated_power.push_back(energy_in.mean * frequency);
    p.dissipated_power_ci.push_back(energy_in.half_width * frequency);
    p.force_amplitude.push_back(m.amplitude.mean);
    p.force_amplitude_ci.push_back(m.amplitude.half_width);
    p.force_phase.push_back(m.phase.mean);
    p.force_phase_ci.push_back(m.phase.half_width);
    p.periods.push_back(periods);
    p.periods_discarded.push_back(discarded);
    p.converged.push_back(converged);
    p.realisations.push_back(count);
    p.interval.push_back(interval);
    return;
  }
  FrfTable& f = out.frf;
  f.frequency.push_back(frequency);
  f.sweep.push_back(sweep);
  f.amplitude.push_back(m.amplitude.mean);
  f.amplitude_ci.push_back(m.amplitude.half_width);
  f.amplitude_spread.push_back(m.amplitude_spread);
  f.phase.push_back(m.phase.mean);
  f.phase_ci.push_back(m.phase.half_width);
  f.phase_spread.push_back(m.phase_spread);
  f.result.push_back(static_cast<int>(e.result));
  f.branches.push_back(static_cast<int>(e.branch.size()));
  f.rms.push_back(average(rms));
  f.peak.push_back(peak);
  f.periods.push_back(periods);
  f.periods_discarded.push_back(discarded);
  f.converged.push_back(converged);
  f.realisations.push_back(count);
  f.interval.push_back(interval);
  f.dissipated_energy.push_back(energy_in.mean);
  f.dissipated_energy_ci.push_back(energy_in.half_width);
  for (int d = 0; d < kMechanisms; ++d) f.dissipated[d].push_back(average(dissipated[d]));
  for (std::size_t k = 0; k < fills.size(); ++k) {
    const auto& [r, p] = fills[k];
    FillTable& t = out.fills;
    t.frequency.push_back(frequency);
    t.sweep.push_back(sweep);
    t.realisation.push_back(r);
    t.branch.push_back(e.branch_of[k]);
    t.amplitude.push_back(std::abs(p.judged.mean));
    t.amplitude_ci.push_back(e.fills[k].amplitude_ci);
    t.phase.push_back(std::arg(p.judged.mean));
    t.phase_ci.push_back(p.judged.phase_ci);
    t.periods.push_back(p.judged.periods);
    t.converged.push_back(p.judged.converged ? 1 : 0);
    t.settled.push_back(e.fills[k].settled ? 1 : 0);
  }
  for (std::size_t b = 0; b < e.branch.size(); ++b) {
    const GroupMean& g = e.branch[b];
    BranchTable& t = out.branch_means;
    t.frequency.push_back(frequency);
    t.sweep.push_back(sweep);
    t.branch.push_back(static_cast<int>(b));
    t.fills.push_back(g.fills);
    t.share.push_back(g.share);
    t.share_low.push_back(g.share_low);
    t.share_high.push_back(g.share_high);
    t.amplitude.push_back(g.amplitude.mean);
    t.amplitude_ci.push_back(g.amplitude.half_width);
    t.phase.push_back(g.phase.mean);
    t.phase_ci.push_back(g.phase.half_width);
    t.within_tolerance.push_back(g.within(plan.settle.tolerance) ? 1 : 0);
  }
}

}  // namespace pdsim

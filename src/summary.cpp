#include "src/summary.hpp"

#include <algorithm>
#include <sstream>

#include "src/format.hpp"
#include "src/frequency_run.hpp"

namespace pdsim {

namespace {

// The frequencies whose flag is `value`, comma-separated (with the sweep when both ran).
std::string listed(const std::vector<double>& frequency, const std::vector<int>& sweep,
                   const std::vector<int>& flag, int value) {
  const bool both = std::find(sweep.begin(), sweep.end(), -sweep.front()) != sweep.end();
  std::string list;
  for (std::size_t i = 0; i < frequency.size(); ++i)
    if (flag[i] == value)
      list += (list.empty() ? "" : ", ") + number(frequency[i]) +
              (both ? (sweep[i] > 0 ? " (up)" : " (down)") : "");
  return list;
}

}  // namespace

std::string summary_line(const Results& r, const std::string& path, const RunPlan& plan) {
  std::ostringstream s;
  s.precision(4);
  const bool fixed = plan.fixed;
  if (!r.frf.frequency.empty() && plan.frf) {
    const FrfTable& f = r.frf;
    int results = 0, branched = 0;
    for (int k : f.result) results += k > 0, branched += k == 2;
    s << "FRF: " << f.frequency.size() << " points, " << results << " results";
    if (branched > 0) s << " (" << branched << " of several branches)";
    const FrfPeak peak = frf_peak(f, r.fills);
    if (peak.found)
      s << "; peak amplitude " << 1e3 * peak.amplitude << " +- " << 1e3 * peak.amplitude_ci
        << " mm at " << peak.frequency << " Hz (the mean over its fills; highest single fill "
        << 1e3 * peak.upper << " mm)";
    // The hard part stays in the headline: the largest mean where the point is not a result.
    if (peak.higher)
      s << "; HIGHER where not a result: " << 1e3 * peak.higher_amplitude << " +- "
        << 1e3 * peak.higher_amplitude_ci << " mm at " << peak.higher_frequency << " Hz";
    if (results < static_cast<int>(f.frequency.size()))
      s << "; NOT results at " << listed(f.frequency, f.sweep, f.result, 0)
        << " Hz (a fill still drifting at settle.max_periods, or settle.max_realisations "
           "fills agreeing on one state whose mean is not known to settle.tolerance)";
    if (branched > 0)
      s << "; several branches at " << listed(f.frequency, f.sweep, f.result, 2)
        << " Hz (fills of the same damper in distinct states, the mean's interval their "
           "spread: /frf/fills, /frf/branch_means)";
  } else if (!r.frf.frequency.empty()) {
    s << "sine at " << r.frf.frequency[0] << " Hz: first harmonic " << 1e3 * r.frf.amplitude[0]
      << " +- " << 1e3 * r.frf.amplitude_ci[0] << " mm"
      << (r.frf.converged[0] ? "" : " (not stationary over the duration)");
  } else if (!r.prescribed.frequency.empty()) {
    const PrescribedTable& p = r.prescribed;
    int count = 0;
    for (int c : p.converged) count += c;
    std::size_t k = 0;  // the peak over the result points (fixed runs: over all)
    bool found = false;
    for (std::size_t i = 0; i < p.frequency.size(); ++i)
      if ((fixed || p.converged[i]) && (!found || p.dissipated_power[i] > p.dissipated_power[k]))
        k = i, found = true;
    const std::vector<int> sweep(p.frequency.size(), 1);
    s << "prescribed motion: " << p.frequency.size()
      << (p.frequency.size() == 1 ? " frequency" : " frequencies");
    if (fixed)
      s << ", " << plan.duration << " s each";
    else
      s << ", " << count << " results";
    if (found)
      s << "; " << (p.frequency.size() == 1 ? "" : "peak ") << "power " << p.dissipated_power[k]
        << " +- " << p.dissipated_power_ci[k] << " W at " << p.frequency[k] << " Hz";
    if (count < static_cast<int>(p.frequency.size()))
      s << (fixed ? "; drifting or too short for an interval at " : "; NOT results at ")
        << listed(p.frequency, sweep, p.converged, 0) << " Hz" << (fixed ? " (run longer)" : "");
  } else {
    s << "time history: " << r.timeseries.time.size() << " samples";
  }
  s << "; wall time " << r.meta_numbers.at("wall_time_s") << " s, "
    << r.meta_numbers.at("particle_steps") / std::max(1e-9, r.meta_numbers.at("wall_time_s"))
    << " particle-steps/s -> " << path;
  return s.str();
}

}  // namespace pdsim

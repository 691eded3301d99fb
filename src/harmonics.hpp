// Per-period first harmonics of a driven response (the MBDyn HFelem idea): each period's
// coefficients are summed over exactly one period of samples (the step divides the period, so the
// rectangle rule is the exact DFT of the samples), against the drive's own phase, so that a
// phase-continuous frequency change keeps the reference. The series of periods is then judged by
// src/steady_state.hpp.
#pragma once

#include <complex>
#include <vector>

#include "src/coupled_system.hpp"

namespace pdsim {

// x ~ Re(H) sin(angle) + Im(H) cos(angle), i.e. x = Im(H e^{i angle}).
struct PeriodSummary {
  std::complex<double> displacement;  // m, the response DOF
  std::complex<double> force;         // N, total damper force on the structure
  double mean_square = 0;             // m^2
  double peak = 0;                    // m
  double energy_in = 0;               // J the containers put into the particles this period
  Dissipated dissipated{};            // J, this period, by mechanism
  // Per damper: its container's absolute displacement (m) and its force (N), first harmonic
  // and mean (the force's mean is its constant part: a weight along the direction).
  std::vector<std::complex<double>> container, damper_force;
  std::vector<double> damper_force_mean;
};

class PeriodTracker {
 public:
  PeriodTracker(int samples_per_period, std::size_t dampers) : n_(samples_per_period) {
    clear(acc_, dampers);
  }

  // Adds the sample of one coupling interval of length h (s) starting at phase `angle` (rad);
  // returns true when it completes a period.
  bool add(const StepRecord& r, double h, double angle, const std::vector<double>& container,
           const std::vector<double>& damper_force) {
    const std::complex<double> w =
        (2.0 / n_) * std::complex<double>(std::sin(angle), std::cos(angle));
    acc_.displacement += w * r.displacement;
    acc_.force += w * r.damper_force;
    acc_.mean_square += r.displacement * r.displacement / n_;
    acc_.peak = std::max(acc_.peak, std::fabs(r.displacement));
    acc_.energy_in += r.power_in * h;
    acc_.dissipated += r.dissipated;
    for (std::size_t k = 0; k < container.size(); ++k) {
      acc_.container[k] += w * container[k];
      acc_.damper_force[k] += w * damper_force[k];
      acc_.damper_force_mean[k] += damper_force[k] / n_;
    }
    if (++count_ < n_) return false;
    periods_.push_back(acc_);
    clear(acc_, container.size());
    count_ = 0;
    return true;
  }

  int periods() const { return static_cast<int>(periods_.size()); }
  const std::vector<PeriodSummary>& all() const { return periods_; }

  // One harmonic of every period: series(&PeriodSummary::displacement), or ::force.
  std::vector<std::complex<double>> series(std::complex<double> PeriodSummary::*harmonic) const {
    std::vector<std::complex<double>> out;
    for (const PeriodSummary& p : periods_) out.push_back(p.*harmonic);
    return out;
  }

  // Mean of periods first..n-1 (peak: their largest).
  PeriodSummary mean_from(int first) const {
    PeriodSummary m;
    clear(m, periods_.empty() ? 0 : periods_[0].container.size());
    const int n = periods(), used = n - first;
    for (int k = first; k < n; ++k) {
      const PeriodSummary& p = periods_[static_cast<std::size_t>(k)];
      m.displacement += p.displacement / double(used);
      m.force += p.force / double(used);
      m.mean_square += p.mean_square / used;
      m.peak = std::max(m.peak, p.peak);
      m.energy_in += p.energy_in / used;
      for (int d = 0; d < kMechanisms; ++d) m.dissipated[d] += p.dissipated[d] / used;
      for (std::size_t d = 0; d < m.container.size(); ++d) {
        m.container[d] += p.container[d] / double(used);
        m.damper_force[d] += p.damper_force[d] / double(used);
        m.damper_force_mean[d] += p.damper_force_mean[d] / used;
      }
    }
    return m;
  }

 private:
  static void clear(PeriodSummary& p, std::size_t dampers) {
    p = PeriodSummary{};
    p.container.assign(dampers, 0.0);
    p.damper_force.assign(dampers, 0.0);
    p.damper_force_mean.assign(dampers, 0.0);
  }

  int n_;
  int count_ = 0;
  PeriodSummary acc_;
  std::vector<PeriodSummary> periods_;
};

}  // namespace pdsim

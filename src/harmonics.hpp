// Steady-state detection by a one-period DFT of the response (the MBDyn HFelem idea): each
// period's first-harmonic coefficients are summed over exactly one period of samples (the step
// divides the period, so the rectangle rule is the exact DFT of the samples), and the response
// is converged when they change less than a tolerance between consecutive periods.
#pragma once

#include <complex>
#include <vector>

#include "src/coupled_system.hpp"

namespace pdsim {

struct PeriodSummary {
  std::complex<double> displacement;  // x ~ Re(H) sin(wt) + Im(H) cos(wt), m
  std::complex<double> force;         // same for the damper force, N
  double mean_square = 0;             // m^2
  double peak = 0;                    // m
  double energy_in = 0;               // J the containers put into the particles this period
  double dissipated_normal = 0, dissipated_tangential = 0;  // J this period
};

class PeriodTracker {
 public:
  PeriodTracker(double omega, int samples_per_period) : omega_(omega), n_(samples_per_period) {}

  // Adds the sample of one step of length dt; returns true when it completes a period.
  bool add(const StepRecord& r, double dt) {
    const double s = std::sin(omega_ * r.time), c = std::cos(omega_ * r.time);
    const double w = 2.0 / n_;
    acc_.displacement += w * std::complex<double>(r.displacement * s, r.displacement * c);
    acc_.force += w * std::complex<double>(r.damper_force * s, r.damper_force * c);
    acc_.mean_square += r.displacement * r.displacement / n_;
    acc_.peak = std::max(acc_.peak, std::fabs(r.displacement));
    acc_.energy_in += r.power_in * dt;
    acc_.dissipated_normal += r.dissipated_normal;
    acc_.dissipated_tangential += r.dissipated_tangential;
    if (++count_ < n_) return false;
    periods_.push_back(acc_);
    acc_ = PeriodSummary{};
    count_ = 0;
    return true;
  }

  int periods() const { return static_cast<int>(periods_.size()); }

  // Converged when the estimated distance to the steady state is below `tolerance` of the
  // harmonic, for two consecutive periods. A linear transient makes the harmonic approach its
  // limit geometrically, H_k = H + c rho^k, so the distance left is |dH_k rho / (1 - rho)| with
  // rho = dH_k / dH_{k-1} (Aitken): with light damping this is many times the change per period,
  // which alone would stop early. When rho says no geometric decay (noise of a chaotic damper,
  // |rho| >= 1) the change per period is the estimate.
  bool converged(double tolerance, int min_periods, bool of_force = false) const {
    const int n = periods();
    if (n < std::max(min_periods, 4)) return false;
    auto harmonic = [&](int k) {
      const PeriodSummary& p = periods_[static_cast<std::size_t>(k)];
      return of_force ? p.force : p.displacement;
    };
    for (int k = n - 2; k < n; ++k) {
      const std::complex<double> change = harmonic(k) - harmonic(k - 1);
      const std::complex<double> before = harmonic(k - 1) - harmonic(k - 2);
      double factor = 1.0;
      if (std::abs(before) > 0) {
        const std::complex<double> rho = change / before;
        if (std::abs(rho) < 1.0) factor = std::max(1.0, std::abs(rho / (1.0 - rho)));
      }
      if (factor * std::abs(change) > tolerance * std::max(std::abs(harmonic(k)), 1e-300))
        return false;
    }
    return true;
  }

  // Mean over the last `count` periods (fewer if fewer ran).
  PeriodSummary average(int count) const {
    PeriodSummary m;
    const int n = periods(), k0 = std::max(0, n - count), used = n - k0;
    for (int k = k0; k < n; ++k) {
      const PeriodSummary& p = periods_[static_cast<std::size_t>(k)];
      m.displacement += p.displacement / double(used);
      m.force += p.force / double(used);
      m.mean_square += p.mean_square / used;
      m.peak = std::max(m.peak, p.peak);
      m.energy_in += p.energy_in / used;
      m.dissipated_normal += p.dissipated_normal / used;
      m.dissipated_tangential += p.dissipated_tangential / used;
    }
    return m;
  }

 private:
  double omega_;
  int n_;
  int count_ = 0;
  PeriodSummary acc_;
  std::vector<PeriodSummary> periods_;
};

}  // namespace pdsim

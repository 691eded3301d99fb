#include "src/run_plan.hpp"

#include <algorithm>

#include "io/deck.hpp"
#include "io/excitation.hpp"

namespace pdsim {

double RunPlan::highest_frequency() const {
  double top = 0;
  for (const PlanPoint& p : points) top = std::max(top, p.frequency);
  return top;
}

RunPlan plan_of(const ExcitationSpec& x, const BedSpec& bed, const OutputSpec& output,
                const Scene& scene) {
  RunPlan plan;
  // Every kind runs as points: its frequencies, or a free decay's one point (no frequency).
  const std::vector<double>& frequencies = x.frequencies;
  for (std::size_t k = 0; k < std::max<std::size_t>(1, frequencies.size()); ++k)
    plan.points.push_back({frequencies.empty() ? 0.0 : frequencies[k], point_amplitude(x, k),
                           k < x.sweeps.size() ? x.sweeps[k] : 1});
  plan.input = x.input;
  plan.ensemble = runs_points(x);
  plan.start = plan.ensemble ? x.start : FrequencyStart::carried;
  plan.prescribed = traits(x.kind).moves_containers;
  plan.harmonics = measures_harmonics(x);
  plan.steady = runs_to_steady_state(x);
  plan.fixed = fixed_duration(x);
  plan.frf = sweeps_frf(x);
  plan.amplitude_steps = !x.amplitudes.empty();
  plan.first_fills = first_fills(x);
  plan.most_fills = most_fills(x);
  const SettleSpec& s = x.settle;
  plan.settle = {s.min_periods, s.max_periods, s.tolerance, s.batches, s.average_periods};
  plan.duration = x.duration;
  plan.initial_displacement = x.initial_displacement;
  plan.bed = bed;
  // Rigid contacts approaching slower than the rest speed end at rest, and velocities are met
  // to the solver's tolerance: a bed is settled once no particle moves faster than their sum
  // (measured on the Saeki bed: at the default 1e-3 m/s it jittered above it for 6 s; at the
  // rest speed alone, 7.8e-3 m/s at dt 4e-4 s, its fastest sphere still moved at 9.5e-3 m/s).
  if (!scene.dampers.empty())
    if (const auto& p = scene.dampers[0].engine.nonsmooth)
      plan.bed.speed = std::max(plan.bed.speed, p->rest_speed + p->tolerance);
  plan.output = output;
  return plan;
}

RunPlan plan_of(const Deck& deck, const Scene& scene) {
  return plan_of(deck.excitation, deck.bed, deck.output, scene);
}

}  // namespace pdsim

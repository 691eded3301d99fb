#include "src/check_report.hpp"

#include <cmath>
#include <sstream>

#include "src/bed_file.hpp"
#include "src/format.hpp"
#include "src/frequency_run.hpp"
#include "src/run.hpp"

namespace pdsim {

std::string check_report(const Deck& deck, const Scene& scene) {
  std::ostringstream s;
  s.precision(5);
  s << "deck: " << deck.path << (deck.title.empty() ? "" : " (" + deck.title + ")") << "\n";
  double structure_mass = 0;
  if (deck.structure.kind != StructureKind::none) {
    const std::vector<double>& f = scene.natural_hz;
    structure_mass =
        deck.structure.kind == StructureKind::sdof
            ? deck.structure.mass
            : deck.structure.beam.density * deck.structure.beam.area * deck.structure.beam.length;
    s << "structure: " << (deck.structure.kind == StructureKind::sdof ? "sdof" : "beam")
      << ", mass " << structure_mass << " kg, first natural frequency " << f.front() << " Hz\n";
  } else {
    s << "structure: none (prescribed container motion)\n";
  }
  double steps_per_second = 0;
  long total_particles = 0;
  for (std::size_t k = 0; k < scene.dampers.size(); ++k) {
    const DamperScene& d = scene.dampers[k];
    const auto n = d.engine.particles.size();
    total_particles += static_cast<long>(n);
    s << "damper " << k << ": " << n << " particles, mass " << d.particle_mass << " kg ("
      << d.particle_mass / static_cast<double>(n) << " kg each), fill fraction " << d.fill_fraction;
    if (structure_mass > 0) s << ", mass ratio " << d.particle_mass / structure_mass;
    const ContainerSpec& c = deck.dampers[k].container;
    s << "\n  container: "
      << with_shape(c.shape, [&](auto shape) { return decltype(shape)::describe(c); });
    s << "\n  kernel variant: " << variant_name(d.engine) << "\n";
  }
  if (!scene.dampers.empty()) {
    if (const auto& ns = scene.dampers[0].engine.nonsmooth)
      s << "contacts: rigid (non-smooth), restitution " << ns->restitution << ", friction "
        << ns->friction << "; within " << ns->envelope << " m they enter a step's problem, "
        << "solved to " << ns->tolerance << " m/s in at most " << ns->max_iterations
        << " iterations; approaches slower than " << ns->rest_speed
        << " m/s end at rest, overlaps recover at " << ns->recovery_speed << " m/s at most\n";
    else
      s << "contact time: " << scene.contact_time << " s" << scene.contact_note << "\n";
    if (scene.rayleigh_time > 0) s << "Rayleigh time: " << scene.rayleigh_time << " s\n";
    s << "dt: " << scene.dt << " s (" << scene.dt_basis << "; limit " << scene.dt_limit << " s)\n";
    if (!scene.warning.empty()) s << "WARNING: " << scene.warning << "\n";
    steps_per_second = 1.0 / scene.dt;
  }
  s << "backend: " << backend_name(scene.backend) << " (" << scene.backend_reason << ")\n";
  const RunPlan plan = plan_of(deck, scene);
  if (const double f_top = plan.highest_frequency(); f_top > 0) {
    s << "steps per period: " << static_cast<long>(std::ceil(1.0 / (f_top * scene.dt))) << " at "
      << f_top << " Hz\n";
  }
  const SettleRule& settle = plan.settle;
  if (plan.steady)
    s << "frequencies: " << plan.points.size() << ", start = " << start_name(plan.start)
      << "; steady when the 95 % interval is within " << 100 * settle.tolerance << " % ("
      << settle.min_periods << " to " << settle.max_periods << " periods, " << settle.batches
      << " batches; " << plan.first_fills
      << (plan.most_fills > plan.first_fills
              ? " to " + std::to_string(plan.most_fills) + " fills, added where they disagree"
          : plan.first_fills > 1 ? " fills"
                                 : " fill")
      << ")\n";
  // A bed file the run would refuse is refused here, before any work (a run reads it whether
  // or not the bed settles).
  const std::optional<Results> kept = read_bed_file(scene, plan, deck.where("bed.file"));
  if (const BedSpec& bed = plan.bed; bed.settle) {
    s << "bed: settled under gravity first, until no particle moves faster than " << bed.speed
      << " m/s for " << kBedHold_s << " s (at most " << bed.max_time << " s)"
      << (bed.file.empty() ? ""
          : kept           ? "; read from " + bed.file + ", which holds it"
                           : "; kept in " + bed.file)
      << "\n";
  }
  // Estimated cost: simulated time x steps/s x particles, at an assumed 1e7 particle-steps/s.
  const double simulated = simulated_time_bound(plan);
  s << "simulated time: at most " << simulated << " s";
  if (total_particles > 0) {
    const double particle_steps =
        simulated * steps_per_second * static_cast<double>(total_particles);
    s << ", at most " << number(particle_steps, 3) << " particle-steps (about "
      << number(particle_steps / 1e7, 2) << " s at 1e7 particle-steps/s";
    if (const auto& ns = scene.dampers.front().engine.nonsmooth)
      s << "; a non-smooth step also solves its contacts' impulses, up to " << ns->max_iterations
        << " iterations each costing about a penalty step: 19-23 a step on the shaken Saeki "
           "pile";
    s << ")";
  }
  s << "\n";
  if (!scene.dampers.empty()) {
    const int side_by_side = runs_side_by_side(plan, scene, 0);
    s << "memory: at most about " << number(memory_estimate_mib(plan, scene), 3) << " MiB ("
      << side_by_side << " run" << (side_by_side > 1 ? "s" : "")
      << " side by side, a core each; `pdsim run --threads N` sets how many)\n";
    if (const std::string short_of = memory_shortfall(plan, scene); !short_of.empty())
      s << "warning: " << short_of << "\n";
  }
  return s.str();
}

}  // namespace pdsim

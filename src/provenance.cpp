#include "src/provenance.hpp"

#include "pdsim_version.hpp"
#include "src/format.hpp"

namespace pdsim {

void write_provenance(Results& r, const DeckRecord& deck, const RunFacts& f) {
  auto& t = r.meta_text;
  auto& n = r.meta_numbers;
  const Scene& scene = *f.scene;
  const RunPlan& plan = *f.plan;
  t["deck"] = deck.text;
  t["deck_path"] = deck.path;
  t["identity"] = f.identity;
  if (!deck.sweep_point.empty()) t["sweep_point"] = deck.sweep_point;
  t["title"] = deck.title;
  t["version"] = std::string(PDSIM_VERSION) + " (" + PDSIM_GIT + ")";
  t["backend"] = f.backend.empty() ? "none (no particles)" : f.backend;
  t["kernel_variant"] = f.variant.empty() ? "none" : f.variant;
  const char* schemes[] = {"loose", "interleaved", "tight"};
  t["coupling"] = schemes[static_cast<int>(scene.coupling.scheme)];
  t["dt_basis"] = scene.dt_basis;
  if (!scene.warning.empty()) t["warning"] = scene.warning;
  if (plan.ensemble) t["start"] = start_name(plan.start);
  const BedReport& bed = f.bed;
  t["bed"] = !bed.ran          ? "not settled (bed.settle = false, or no gravity or particles)"
             : f.bed_from_file ? "read from " + plan.bed.file
             : bed.settled
                 ? "settled in " + number(bed.time_s) + " s"
                 : "NOT settled within bed.max_time = " + number(plan.bed.max_time) + " s";
  n["bed_settled"] = bed.settled ? 1 : 0;
  n["bed_settle_time_s"] = bed.time_s;
  n["bed_speed"] = bed.speed;
  n["realisations"] = double(f.fills_min);
  n["max_realisations"] = double(f.fills_max);
  n["fills_used"] = double(f.fills_used);
  n["jobs"] = f.jobs;
  n["threads"] = f.threads;
  n["dt"] = scene.dt;
  n["dt_limit"] = scene.dt_limit;
  n["wall_time_s"] = f.wall_s;
  n["particle_steps"] = double(f.particle_steps);
  int particles = 0;
  for (const DamperScene& d : scene.dampers)
    particles += static_cast<int>(d.engine.particles.size());
  n["particles"] = particles;
  n["simulated_time_s"] = f.simulated_s;
  if (!scene.dampers.empty() && scene.dampers[0].engine.nonsmooth) {
    // This process's solves (a resumed run's earlier ones are not counted).
    const SolverTotals& a = f.solver_start;
    const SolverTotals b = nonsmooth_totals();
    const double steps = static_cast<double>(b.steps - a.steps);
    n["solver_iterations_per_step"] =
        steps > 0 ? static_cast<double>(b.iterations - a.iterations) / steps : 0.0;
    n["solver_most_iterations"] = b.most;
    n["solver_steps_at_cap"] = static_cast<double>(b.capped - a.capped);
    n["solver_worst_residual"] = b.worst_residual;
    if (b.capped > a.capped) {
      const std::string capped =
          number(static_cast<double>(b.capped - a.capped)) + " of " + number(steps) +
          " steps ended at contact.max_iterations with a residual above contact.tolerance "
          "(largest " +
          number(b.worst_residual) + " m/s)";
      t["warning"] = scene.warning.empty() ? capped : scene.warning + "; " + capped;
    }
  }
}

}  // namespace pdsim

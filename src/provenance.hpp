// What a run's /meta says of it (io/output.md): the deck it ran, this build, the backend and
// kernel variant, the step, the bed, the fills, the work and the wall time.
#pragma once

#include <cstddef>
#include <string>

#include "io/results.hpp"
#include "src/frequency_run.hpp"
#include "src/run_plan.hpp"
#include "src/scene.hpp"

namespace pdsim {

// What a run keeps of its deck: its text and names, nothing it runs on (the scene holds that).
struct DeckRecord {
  std::string text, path, title;
  std::string sweep_point;  // "K: key = value, ..." for a point of a [sweep], else ""
};

// What the Driver knows of a run when it writes a file.
struct RunFacts {
  const Scene* scene = nullptr;   // fill 0's
  const RunPlan* plan = nullptr;  // what it ran
  std::string identity;           // its identity_text()
  std::string backend, variant;   // "" without particles
  BedReport bed;                  // fill 0's bed
  bool bed_from_file = false;
  int fills_min = 1, fills_max = 1;
  std::size_t fills_used = 0;
  int jobs = 1, threads = 1;
  double wall_s = 0, simulated_s = 0;
  long long particle_steps = 0;
  SolverTotals solver_start;  // the process's non-smooth solves before this run
};

// Writes the run's /meta (deck, identity, version, backend, step, bed, fills, work, the
// non-smooth solver's counts and warnings) into `r`.
void write_provenance(Results& r, const DeckRecord& deck, const RunFacts& facts);

}  // namespace pdsim

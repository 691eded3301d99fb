// `pdsim bench`: particle-steps per second of the user's flows: the shaken steel-sphere box (the
// scene the LIGGGHTS comparison uses, validation/liggghts/) timed over whole periods after the
// fall from a random fill, and a dense Saeki-size pile; the cost of each optional effect.
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace pdsim {

struct BenchOptions {
  std::vector<int> particles{196, 8000};
  std::vector<int> threads{1, 2};
  long steps = 0;         // > 0: that many steps from the lattice, set-up included (no warm-up)
  double warmup = 0.2;    // s of shaking before the timing (the fall from the fill)
  double periods = 1;     // whole periods timed
  int repeat = 3;         // timings of each flow: median and range
  bool box = true;        // the shaken box at each particle count
  bool pile = true;       // also the dense pile
  bool saeki = true;      // also the Saeki damper on its structure against its DEM alone
  int jobs = 0;           // > 0: also that many copies of each scene at once, one thread each
  bool effects = false;   // also time each optional effect against the full model
  bool coupling = false;  // time one structure <-> particle exchange per scheme and integrator
  bool rigid = false;     // rigid contacts against the penalty engine
  std::string backend = "cpu";
};

void add_bench_options(CLI::App& app, BenchOptions& options);
int run_bench(const BenchOptions& options);

}  // namespace pdsim

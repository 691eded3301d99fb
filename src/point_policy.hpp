// A point's policy over its fills: how many more it gets while its ensemble mean is not known
// to the tolerance, and what the points still planned are expected to cost (the progress line's
// ETA). The Driver asks; it schedules what these decide.
#pragma once

#include <vector>

#include "src/run_plan.hpp"
#include "src/run_record.hpp"
#include "src/scene.hpp"
#include "src/steady_state.hpp"

namespace pdsim {

// How many fills a point with ensemble `e` of `now` fills should have next, `most` at most:
// enough for a Student-t interval of the spread seen to meet `tolerance`, at least two more, at
// most twice as many.
int more_fills(const Ensemble& e, int now, int most, double tolerance);

// The simulated time (s) the points still planned are expected to take: every fill's points
// from `reached` (its last point run, -1: none) up to `target` (the last it is to run), and the
// fills that the points not yet judged are expected to add beyond `want` (the fills each point
// wants now). `scene` is fill 0's; the caller keeps the record from changing meanwhile.
// `beyond`: a point still planned is predicted above every finished point's amplitude (nearer
// resonance than any yet): there the model extrapolates, and it takes the highest finished
// point's periods, which a resonance exceeds.
struct PlannedWork {
  double expected = 0;  // s, simulated
  bool beyond = false;
};
PlannedWork planned_remaining(const RunPlan& plan, const Scene& scene, const RunRecord& record,
                              const std::vector<int>& want, const std::vector<long>& target,
                              const std::vector<long>& reached);

}  // namespace pdsim

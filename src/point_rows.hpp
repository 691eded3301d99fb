// A point's fills together: their ensemble, the log line that says what it is, and the rows
// of /frf (or /prescribed), /periods, /frf/fills and /frf/branch_means it writes.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "io/results.hpp"
#include "src/frequency_run.hpp"
#include "src/steady_state.hpp"

namespace pdsim {

// A fill settled on its own: its mean known to the tolerance, or held still when max_periods
// ended it (a run stops before max_periods only when converged).
bool settled(const Stationary& j);

// The ensemble of a point's fills (judge_ensemble(); with settle.max_realisations fills no
// more will come). A fixed run asked for no tolerance: it is a result when every fill's
// periods are stationary, and adds no fills.
Ensemble judge_fills(const std::vector<FrequencyPoint>& runs, const RunPlan& plan);

// A point's name in the log: "f = 15 Hz", with its amplitude where the points' differ and its
// sweep where both ran.
std::string point_text(const RunPlan& plan, std::size_t s);
// One line for the log: what fill r measured at a point (a free decay: its duration).
std::string fill_text(const FrequencyPoint& p, std::size_t r, const RunPlan& plan);

// One line for the log: a point's ensemble, its branches, and what it is.
std::string ensemble_text(const Ensemble& e, bool prescribed);

// One row of /frf or /prescribed (with its /periods, /frf/fills and /frf/branch_means) from
// the fills of one point: (fill index, what it measured); the point's sweep (+1 up, -1 down)
// and drive amplitude (PlanPoint).
void add_row(Results& out, const std::vector<std::pair<int, FrequencyPoint>>& fills, int sweep,
             double amplitude, const RunPlan& plan);

}  // namespace pdsim

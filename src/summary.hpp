// The one line a finished run prints: what it found (the peak and, beside it, the points that
// are not results), its wall time and rate, and where the file is.
#pragma once

#include <string>

#include "io/results.hpp"
#include "src/run_plan.hpp"

namespace pdsim {

// `plan`: what the run ran.
std::string summary_line(const Results& r, const std::string& path, const RunPlan& plan);

}  // namespace pdsim

// A measured point as checkpoint numbers, so that a resumed run combines it as if just measured.
#pragma once

#include <vector>

#include "src/frequency_run.hpp"

namespace pdsim {

// The point's numbers in the order of kPointFields (point_checkpoint.cpp).
std::vector<double> pack(const FrequencyPoint& p);
// The point back from those numbers; a checkpoint written before a field was added holds fewer
// numbers, and that field takes its stated default.
FrequencyPoint unpack(const std::vector<double>& v);

// The per-period harmonics of a point, five numbers a period.
std::vector<double> pack_periods(const FrequencyPoint& p);
void unpack_periods(const std::vector<double>& v, FrequencyPoint& p);

}  // namespace pdsim

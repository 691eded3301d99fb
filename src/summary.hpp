// The one line a finished run prints: what it found (the peak and, beside it, the points that
// are not results), its wall time and rate, and where the file is.
#pragma once

#include <string>

#include "io/deck.hpp"
#include "io/results.hpp"

namespace pdsim {

std::string summary_line(const Results& r, const std::string& path, const Deck& deck);

}  // namespace pdsim

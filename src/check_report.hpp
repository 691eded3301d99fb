// The text of `pdsim check`: the derived quantities of a deck (masses, fill, contact time, dt,
// kernel variant, steady-state settings and an estimate of the cost).
#pragma once

#include <string>

#include "io/deck.hpp"
#include "src/scene.hpp"

namespace pdsim {

std::string check_report(const Deck& deck, const Scene& scene);

}  // namespace pdsim

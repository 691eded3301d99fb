// A settled bed kept in a file (bed.file), and what decides whether it fits a deck.
#pragma once

#include <string>

#include "src/scene.hpp"

namespace pdsim {

// Everything that decides a settled bed: a bed file made for other particles is refused.
std::string bed_fingerprint(const Scene& scene);
// The dampers' design (containers, laws, constants, particles' sizes and density, gravity),
// without the fill's positions or the step: a damper map is refused for a deck of another.
std::string damper_fingerprint(const Scene& scene);

}  // namespace pdsim

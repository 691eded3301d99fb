// A settled bed kept in a file (bed.file), and what decides whether it fits a deck.
#pragma once

#include <optional>
#include <string>

#include "io/results.hpp"
#include "kernels/errors.hpp"
#include "src/identity.hpp"
#include "src/run_plan.hpp"
#include "src/scene.hpp"

namespace pdsim {

// The settled beds kept in the plan's bed.file, read and checked before any work (by `pdsim
// check` and by a run of `scene`): none when the file does not exist; an InputError at `where` (the
// deck's bed.file) when it is not a pdsim results file, or holds beds settled for another scene
// (naming the fields of its identity that differ) or fewer than the run's first fills
// (settle.realisations).
std::optional<Results> read_bed_file(const Scene& scene, const RunPlan& plan,
                                     const SourcePos& where);

}  // namespace pdsim

// What a compiled scene is, field by field: written into every output, bed file and map, and
// compared where a file made for one scene is used by another (a kept bed, a map behind a
// prediction, a resumed run), so that a refusal names what differs.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "src/scene.hpp"

namespace pdsim {

// Named fields in a fixed order, each value as text with its unit ("damper[0].container" =
// "box size 0.05 x 0.05 x 0.05 m"). Fields named "bed.*" decide a settled bed only (the fill's
// positions, the settling thresholds, a step that follows the motion); the rest decide the
// damper's design and its host: containers, particles, contact law and constants, gravity and a
// penalty law's dt.
using Identity = std::vector<std::pair<std::string, std::string>>;

// Taken from the scene as the engines are made with it (fill 0's particles), not as the deck
// says, so that a derived constant, a mesh file's contents or a default is in it; `bed` says
// how its fills settle (RunPlan::bed).
Identity scene_identity(const Scene& scene, const BedSpec& bed);

// One "name = value" line a field, and back.
std::string identity_text(const Identity& identity);
Identity parse_identity(const std::string& text);

// What comparing a kept record with a scene's covers.
enum class IdentityScope { design, bed };

// The fields within `scope` whose values differ between `kept` (a file's record, called
// `kept_name`: "the map") and `now` (called `now_name`: "the deck"), as
// "damper[0].container: box size 0.05 x 0.05 x 0.05 m in the map, box size 0.06 x 0.05 x 0.05 m in
// the deck; ..."; "" when none does.
std::string identity_difference(const Identity& kept, const Identity& now, IdentityScope scope,
                                const std::string& kept_name, const std::string& now_name);

}  // namespace pdsim

// kind = "free_decay": the structure let go from a static displacement, its time history only.
#include "io/excitation.hpp"
#include "io/excitations/keys.hpp"

namespace pdsim {

void read_free_decay(const deck_keys::Table& t, ExcitationSpec& e) {
  using namespace deck_keys;
  const std::string why = "for kind = \"free_decay\"";
  t.allow_only({"kind", "initial_displacement", "duration"}, " " + why);
  e.initial_displacement = t.need_real("initial_displacement", "a number (m)", any_value, why);
  e.duration = t.need_real("duration", "a positive number (s)", positive, why);
}

}  // namespace pdsim

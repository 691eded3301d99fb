// kind = "sine": one fill driven at one frequency for a fixed duration, from the bed at rest.
#include "io/excitation.hpp"
#include "io/excitations/keys.hpp"

namespace pdsim {

void read_sine(const deck_keys::Table& t, ExcitationSpec& e) {
  using namespace deck_keys;
  const std::string why = "for kind = \"sine\"";
  t.allow_only({"kind", "input", "amplitude", "frequency", "duration"}, " " + why);
  read_drive(t, e, why);
  e.frequencies = {t.need_real("frequency", "a positive number (Hz)", positive, why)};
  e.frequencies_key = "excitation.frequency";
  e.duration = t.need_real("duration", "a positive number (s)", positive, why);
}

}  // namespace pdsim

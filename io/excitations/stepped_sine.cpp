// kind = "stepped_sine": a force or base input at each frequency of a list, each run to its
// steady state by several fills (io/decks.md).
#include "io/excitation.hpp"
#include "io/excitations/keys.hpp"

namespace pdsim {

void read_stepped_sine(const deck_keys::Table& t, ExcitationSpec& e) {
  using namespace deck_keys;
  const std::string why = "for kind = \"stepped_sine\"";
  t.allow_only({"kind", "input", "amplitude", "frequencies", "direction", "settle", "start"},
               " " + why);
  read_drive(t, e, why);
  if (!t.has("frequencies"))
    t.missing("frequencies", "a table { start, stop, step } or an array (Hz)", why);
  e.frequencies = read_frequencies(t);
  e.settle = read_settle(t);
  e.start = read_start(t, false);
  read_direction(t, e);
}

}  // namespace pdsim

// kind = "prescribed": the containers moved X sin(2 pi f t) along an axis, no structure; the
// force the particles put on them measured at each frequency.
#include "io/excitation.hpp"
#include "io/excitations/keys.hpp"

namespace pdsim {

void read_prescribed(const deck_keys::Table& t, ExcitationSpec& e) {
  using namespace deck_keys;
  const std::string why = "for kind = \"prescribed\"";
  t.allow_only({"kind", "motion", "frequencies", "direction", "duration", "settle", "start"},
               " " + why);
  const Table m = t.need_sub("motion", "a table { axis, amplitude, frequency }", why);
  m.allow_only({"axis", "amplitude", "frequency"});
  const std::string vector = "a non-zero vector of 3 numbers [x, y, z]";
  if (!m.has("axis")) m.missing("axis", vector, "for a prescribed motion");
  e.motion.axis = *m.direction("axis");
  e.motion.amplitude =
      m.need_real("amplitude", "a positive number (m)", positive, "for a prescribed motion");
  const auto frequency = m.real("frequency", "a positive number (Hz)", positive);
  if (frequency && t.has("frequencies"))
    t.fail("frequencies", "give either motion.frequency or frequencies, not both");
  if (!frequency && !t.has("frequencies"))
    m.missing("frequency", "a positive number (Hz) (or excitation.frequencies for a sweep)", why);
  e.frequencies = frequency ? std::vector<double>{*frequency} : read_frequencies(t);
  if (frequency) e.frequencies_key = "excitation.motion.frequency";
  e.motion.frequency = e.frequencies.front();
  e.duration = t.real("duration", "a positive number (s)", positive).value_or(0);
  e.settle = read_settle(t);
  e.start = read_start(t, true);
  read_direction(t, e);
}

}  // namespace pdsim

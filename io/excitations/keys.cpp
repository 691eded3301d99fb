#include "io/excitations/keys.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace pdsim::deck_keys {

std::vector<double> read_frequencies(const Table& t) {
  std::vector<double> f;
  const toml::node* given = t.node("frequencies");
  if (given && given->is_table()) {
    const Table sweep = *t.sub("frequencies", "");
    sweep.allow_only({"start", "stop", "step"});
    const std::string why = "for a frequency sweep";
    const double start = sweep.need_real("start", "a positive number (Hz)", positive, why);
    const double stop = sweep.need_real("stop", "a positive number (Hz)", positive, why);
    const double step = sweep.need_real("step", "a positive number (Hz)", positive, why);
    if (stop < start)
      sweep.fail("stop", "expected a number >= start (" + show(start) + " Hz), got " + show(stop));
    // Inclusive of stop within rounding: 0.1..0.7 step 0.1 is 7 values, although
    // (0.7 - 0.1) / 0.1 = 5.999999999999999 in doubles.
    const double intervals = std::floor((stop - start) / step + 1e-6);
    if (intervals >= static_cast<double>(kMaxFrequencies))
      sweep.fail("step", "expected at most " + std::to_string(kMaxFrequencies) +
                             " frequencies, got " + show(intervals + 1));
    for (int i = 0; i <= static_cast<int>(intervals); ++i) f.push_back(start + i * step);
    if (std::abs(f.back() - stop) < 1e-6 * step) f.back() = stop;
  } else if (given) {
    const std::string expected =
        "a table { start, stop, step } or a non-empty array of positive numbers (Hz)";
    f = *t.reals("frequencies", 0, expected, positive);
    if (f.size() > kMaxFrequencies)
      t.fail("frequencies", "expected at most " + std::to_string(kMaxFrequencies) +
                                " frequencies, got " + std::to_string(f.size()));
  }
  return f;
}

void read_direction(const Table& t, ExcitationSpec& e) {
  const std::size_t direction = t.choice("direction", {"up", "down", "both"}).value_or(0);
  std::vector<double>& f = e.frequencies;
  if (direction == 1) std::reverse(f.begin(), f.end());
  e.sweeps.assign(f.size(), direction == 1 ? -1 : 1);
  if (direction == 2) {
    if (e.start == FrequencyStart::independent)
      t.fail("direction",
             "expected \"up\" or \"down\" with start = \"independent\": "
             "\"both\" compares sweeps that carry the state from one frequency "
             "to the next");
    const std::vector<double> up = f;
    f.insert(f.end(), up.rbegin(), up.rend());
    e.sweeps.resize(f.size(), -1);
    if (f.size() > kMaxFrequencies)
      t.fail("direction", "expected at most " + std::to_string(kMaxFrequencies) +
                              " frequencies in both sweeps together, got " +
                              std::to_string(f.size()));
  }
}

SettleSpec read_settle(const Table& t) {
  SettleSpec s;
  s.realisations = 0;
  s.max_realisations = 0;
  const auto settle = t.sub("settle", "a table { min_periods, max_periods, tolerance }");
  if (!settle) return s;
  settle->allow_only({"min_periods", "max_periods", "tolerance", "batches", "average_periods",
                      "realisations", "max_realisations"});
  s.min_periods =
      static_cast<int>(settle->integer("min_periods", 1, kMaxPeriods).value_or(s.min_periods));
  s.max_periods =
      static_cast<int>(settle->integer("max_periods", 1, kMaxPeriods).value_or(s.max_periods));
  if (s.min_periods > s.max_periods) {
    const bool min_given = settle->has("min_periods");
    settle->fail(min_given ? "min_periods" : "max_periods",
                 min_given ? "expected at most max_periods (" + std::to_string(s.max_periods) +
                                 "), got " + std::to_string(s.min_periods)
                           : "expected at least min_periods (" + std::to_string(s.min_periods) +
                                 "), got " + std::to_string(s.max_periods));
  }
  s.tolerance =
      settle->real("tolerance", "a number in (0, 1]", fraction_range).value_or(s.tolerance);
  // Two batches are the fewest that have a spread; four keep Student's t at 3.2 (with three, a
  // ringing start passed as converged 6 % off on the Saeki deck).
  s.batches = static_cast<int>(settle->integer("batches", 2, 1000).value_or(s.batches));
  if (s.batches > s.max_periods) {
    if (settle->has("batches"))
      settle->fail("batches", "expected at most max_periods (" + std::to_string(s.max_periods) +
                                  "), got " + std::to_string(s.batches));
    settle->fail("max_periods", "expected at least settle.batches (" + std::to_string(s.batches) +
                                    ", the default) periods, got " + std::to_string(s.max_periods));
  }
  s.average_periods = static_cast<int>(
      settle->integer("average_periods", 1, kMaxPeriods).value_or(s.average_periods));
  if (s.average_periods > 0 && s.average_periods < s.batches)
    settle->fail("average_periods", "expected at least settle.batches (" +
                                        std::to_string(s.batches) +
                                        ") periods, one per batch of the interval, got " +
                                        std::to_string(s.average_periods));
  s.realisations =
      static_cast<int>(settle->integer("realisations", 1, 1000).value_or(s.realisations));
  s.max_realisations = static_cast<int>(settle->integer("max_realisations", 1, 1000).value_or(0));
  return s;
}

FrequencyStart read_start(const Table& t, bool prescribed) {
  if (prescribed) {
    const auto i = t.choice("start", {"carried", "independent"});
    return i && *i == 1 ? FrequencyStart::independent : FrequencyStart::carried;
  }
  const Names names(std::begin(kStartNames), std::end(kStartNames));
  return static_cast<FrequencyStart>(t.choice("start", names).value_or(0));
}

void read_drive(const Table& t, ExcitationSpec& e, const std::string& why) {
  const ExcitationInput inputs[] = {ExcitationInput::force, ExcitationInput::base_displacement,
                                    ExcitationInput::base_acceleration};
  const char* units[] = {"N", "m", "m/s^2"};
  const std::size_t input =
      t.choice("input", {"force", "base_displacement", "base_acceleration"}).value_or(0);
  e.input = inputs[input];
  e.amplitude = t.need_real("amplitude", std::string("a positive number (") + units[input] + ")",
                            positive, why);
}

}  // namespace pdsim::deck_keys

// The keys excitation kinds share: frequencies (a list or a range, also [map]'s), their
// direction, [excitation.settle], `start` and a sine's drive.
#pragma once

#include <vector>

#include "io/deck_table.hpp"
#include "io/specs.hpp"

namespace pdsim::deck_keys {

// excitation.frequencies: an array of positive numbers (Hz) or a table { start, stop, step }.
std::vector<double> read_frequencies(const Table& t);
// The frequencies in the order they are run, each with its sweep (+1 up, -1 down): "up" (the
// default) runs the list as given, "down" reversed, "both" as given and then back from its end.
void read_direction(const Table& t, ExcitationSpec& e);
// [excitation.settle]; realisations and max_realisations are 0 when not given: read_deck()
// resolves them once the fill is known.
SettleSpec read_settle(const Table& t);
// excitation.start; a prescribed motion knows "carried" and "independent" only.
FrequencyStart read_start(const Table& t, bool prescribed);
// A sine's `input` and `amplitude` (N, m or m/s^2 as the input is); `why` names the kind.
void read_drive(const Table& t, ExcitationSpec& e, const std::string& why);

}  // namespace pdsim::deck_keys

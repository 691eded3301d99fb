// pdsim predict: a host structure's FRF from a damper map (pdsim map) by harmonic balance, in
// milliseconds instead of a coupled run. The damper acts on the host through the first harmonic
// of its force, F1 = (w^2 m_eff(X, f) - i w c_eff(X, f)) X, so an SDOF of mass M, stiffness K and
// damping C under a force F0 sin(w t) moves with amplitude X where
//   X |K - (M + m_eff) w^2 + i w (C + c_eff)| = F0,
// solved at each frequency for every root: where the map's effective mass changes with the
// amplitude, several roots (branches) coexist and the response jumps between them.
#pragma once

#include <string>
#include <vector>

#include "io/deck.hpp"
#include "io/results.hpp"
#include "src/run.hpp"

namespace pdsim {

// The map read for interpolation: at each of its frequencies the force components w^2 m_eff X
// and w c_eff X (and their half-widths) linear in X between its amplitudes (exact for a rigid
// load and for Coulomb friction), and m_eff, c_eff linear in f between its frequencies. Nothing is
// extrapolated: a point outside the map has no value.
class MapInterpolant {
 public:
  // The map's rows of one `sweep` (0: points from the settled bed; +1 amplitudes stepped up,
  // -1 back down: the bed's states on each way). Throws InputError for a map it cannot read.
  MapInterpolant(const MapTable& map, int sweep = 0);
  struct Value {
    double mass = 0, damping = 0, mass_ci = 0, damping_ci = 0;  // kg, N s/m
  };
  // The amplitudes the map covers at `frequency` (m), {0, 0} outside its frequencies.
  std::pair<double, double> amplitudes(double frequency) const;
  Value at(double frequency, double amplitude) const;  // within amplitudes(frequency)
  double lowest_frequency() const { return rows_.front().frequency; }
  double highest_frequency() const { return rows_.back().frequency; }

 private:
  struct Row {  // one map frequency
    double frequency;
    std::vector<double> amplitude, real, imag, real_ci, imag_ci;  // m; N (force components)
  };
  Value at_row(const Row& r, double amplitude) const;
  std::pair<std::size_t, double> bracket(double frequency) const;  // lower row, weight of next
  std::vector<Row> rows_;
};

struct HbRoot {
  double amplitude = 0, amplitude_ci = 0, phase = 0;  // m, m, rad
  bool stable = false;
  MapInterpolant::Value damper;
};
struct SdofHost {
  double mass = 0, stiffness = 0, damping = 0, force = 0;  // kg, N/m, N s/m, N (amplitude)
};

// Every amplitude that balances the force at `frequency`, ascending. Throws InputError naming the
// frequency when the balance's root lies outside the map's amplitudes (below its smallest or
// above its largest) or the frequency outside its frequencies.
std::vector<HbRoot> harmonic_balance(const MapInterpolant& map, const SdofHost& host,
                                     double frequency);

struct PredictOptions {
  std::vector<std::string> maps;  // the map files (one damper's, read as one map)
  std::string output;             // default: the deck's output name with "_hb.h5"
  bool force = false;
};

// The deck's FRF (an SDOF under a force stepped sine) from the maps; writes /frf_hb. With
// amplitudes stepped up and down in the map, the roots of each way are reported (branches a
// slow rise or fall of the amplitude finds).
RunReport run_predict(const Deck& deck, const PredictOptions& options);

}  // namespace pdsim

// pdsim predict: a host structure's FRF from a damper map (pdsim map) by harmonic balance, in
// milliseconds instead of a coupled run. The damper acts on the host through the first harmonic
// of its force, as the impedance Z(X, f) = -m_eff w^2 + i w c_eff of its container's motion X.
// A linear host (an SDOF, a beam) moves the damper's point by U = G / (1 + Z H), with G its
// motion without the damper and H its receptance there, so the damper moves with amplitude X
// where
//   X |1 + Z(X, f) H| = |G|   (an SDOF under F0: X |K - (M + m_eff) w^2 + i w (C + c_eff)| = F0),
// solved at each frequency for every root: where the map's effective mass changes with the
// amplitude, several roots (branches) coexist and the response jumps between them.
#pragma once

#include <string>
#include <vector>

#include "io/deck.hpp"
#include "io/results.hpp"
#include "src/run.hpp"
#include "structure/structure.hpp"

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
    // N/m: how far the map's impedance F1 / X moves between the two amplitudes read between
    // (the larger of the two frequencies'): what straight lines there may miss.
    double step = 0;
    bool converged = true;  // every map point read here converged
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
    std::vector<int> converged;                                   // the map's /map/converged
  };
  Value at_row(const Row& r, double amplitude) const;
  std::pair<std::size_t, double> bracket(double frequency) const;  // lower row, weight of next
  std::vector<Row> rows_;
};

struct HbRoot {
  // The structure's response (the FRF's, see HostAt::response) and the damper's own amplitude.
  double amplitude = 0, amplitude_ci = 0, phase = 0, damper_amplitude = 0;  // m, m, rad, m
  // |step H / (1 + (Z - Z0) H)|: the share of the balance the map's cell spans, about the
  // largest relative change of the amplitude that reading the cell by straight lines may hide.
  double map_change = 0;
  bool stable = false;
  MapInterpolant::Value damper;
};

// A linear host driven at one frequency, as its one damper sees it, phasors against the drive's.
// H and G are taken with the damper point held by a reference impedance Z0 (then the damper's
// motion is U = G / (1 + (Z - Z0) H)), so that an undamped host at its own frequency, whose bare
// receptance is infinite, still has finite ones.
struct HostAt {
  double omega = 0;                 // rad/s
  std::complex<double> shift;       // Z0 = i w^2 t^T M t, N/m: the damper point's mass, as damping
  std::complex<double> receptance;  // H, m/N: the damper point's motion per unit force there
  std::complex<double> bare;        // G, m: the damper point's absolute motion under the drive
  Eigen::VectorXcd load;            // the drive's load on the structure's coordinates
  std::complex<double> base;        // the base's displacement phasor (force input: 0)
};
// `s` (with one damper mounted) under the deck's drive (`input`, `amplitude`) at `frequency` Hz.
HostAt host_at(const LinearStructure& s, ExcitationInput input, double amplitude, double frequency);

// Every amplitude that balances the host at `frequency`, ascending in the damper's amplitude;
// each root's response is `s`'s reported displacement. Throws InputError naming the frequency
// when the balance's root lies outside the map's amplitudes (below its smallest or above its
// largest) or the frequency outside its frequencies.
std::vector<HbRoot> harmonic_balance(const MapInterpolant& map, const LinearStructure& s,
                                     const HostAt& host, double frequency);

struct PredictOptions {
  std::vector<std::string> maps;  // the map files (one damper's, read as one map)
  std::string output;             // default: the deck's output name with "_hb.h5"
  bool force = false;
};

// The deck's FRF (its structure with one damper, a stepped sine or sine) from the maps; writes
// /frf_hb. With
// amplitudes stepped up and down in the map, the roots of each way are reported (branches a
// slow rise or fall of the amplitude finds).
RunReport run_predict(const Deck& deck, const PredictOptions& options);

}  // namespace pdsim

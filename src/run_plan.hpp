// What a run does with its scene (src/scene.hpp: the dampers and their host as the solver sees
// them): the points it runs, the fills each starts with and may grow to, when a point's periods
// end, how the bed settles, what it records. Built once from the deck (plan_of()); the Driver,
// FrequencyRun and the rows read these values, not the deck's excitation.
#pragma once

#include <vector>

#include "io/specs.hpp"
#include "src/scene.hpp"

namespace pdsim {

struct Deck;  // io/deck.hpp: only plan_of() reads it

// One point: a frequency at a drive amplitude, on one sweep.
struct PlanPoint {
  double frequency = 0;  // Hz; 0: a free decay's one point
  double amplitude = 0;  // the drive's: N, m or m/s^2 as RunPlan::input says; m when prescribed
  int sweep = 1;         // +1 sweeping up, -1 down
};

// When a fill's point is steady (src/steady_state.hpp): [excitation.settle] but for its fill
// counts, which are RunPlan::first_fills and most_fills.
struct SettleRule {
  int min_periods = 0;      // never converged before this many periods
  int max_periods = 0;      // a point stops here, converged or not
  double tolerance = 0;     // relative 95 % half-width of the first-harmonic amplitude
  int batches = 0;          // batch means an interval needs
  int average_periods = 0;  // 0: the stationary periods found; N: the last N periods
};

struct RunPlan {
  std::vector<PlanPoint> points;  // in the order they run; never empty
  ExcitationInput input = ExcitationInput::force;
  // How a point of several fills starts (excitation.start); a sine's one point: carried on from
  // the bed at rest.
  FrequencyStart start = FrequencyStart::carried;
  bool ensemble = false;    // points run by several fills side by side (stepped sine, prescribed)
  bool prescribed = false;  // the containers' motion is prescribed: no structure is driven
  bool harmonics = false;   // points measure a first harmonic (a free decay records time only)
  bool steady = false;      // points run to a steady state (the detector judges them)
  bool fixed = false;       // points run the whole periods of `duration` and report their means
  bool frf = false;         // the points are an FRF of the structure, with a peak to report
  bool amplitude_steps = false;     // the points' amplitudes differ (pdsim map): named by them
  int first_fills = 1;              // fills a point starts with (fill seeds seed, seed+1, ...)
  int most_fills = 1;               // fills a point may grow to while its mean is not known
  SettleRule settle;                // when a fill's point is steady, and its ensemble's
  double duration = 0;              // s: a sine's, a free decay's, a fixed prescribed point's
  double initial_displacement = 0;  // m, a free decay's
  BedSpec bed;  // how the bed settles before the first point (its speed as the contacts allow)
  OutputSpec output;

  // Hz, 0 when no point has a frequency (a free decay).
  double highest_frequency() const;
  // Whether each point runs on its own from the fills' settled beds, side by side.
  bool independent() const { return start == FrequencyStart::independent; }
};

// The excitation `x`, how the bed settles and what the run records, as the run of `scene` (built
// for `x`) takes them.
RunPlan plan_of(const ExcitationSpec& x, const BedSpec& bed, const OutputSpec& output,
                const Scene& scene);
// The deck's excitation, [excitation.settle], [bed] and [output], for `scene` built from it.
RunPlan plan_of(const Deck& deck, const Scene& scene);

}  // namespace pdsim

// Replays a carried sweep's point rules on the per-period series a run recorded (/periods):
// each fill judged after every period at the tolerance, every 25 periods the fills' looks at
// each other (spread_floors(), known_at_look(), a pass keeping the last half), a cap of
// `--cap` periods, then judge_ensemble(). It answers "what would these fills have given under
// this rule or cap" without running them again. Two limits: a fill cannot run past the periods
// it recorded (it ends there, marked E), and a fill stopped sooner would have carried another
// state to the next point; the figures behind resonance_statistics.md ("The cap as a lever").
// usage:
//   g++ -O2 -std=c++20 -I. validation/fills_replay.cpp src/steady_state.cpp -o /tmp/fills_replay
//   /usr/bin/python3 validation/fills_series.py saeki_250.h5 | /tmp/fills_replay --cap 300
#include <algorithm>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <vector>

#include "src/steady_state.hpp"

using namespace pdsim;
using Series = std::vector<std::complex<double>>;

int main(int argc, char** argv) {
  int cap = 1 << 30, skip = 3;  // skip: the predicted start's first refinement round
  double tolerance = 0.02, low = 0, high = 1e9;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (!std::strcmp(argv[k], "--cap")) cap = std::atoi(argv[k + 1]);
    if (!std::strcmp(argv[k], "--skip")) skip = std::atoi(argv[k + 1]);
    if (!std::strcmp(argv[k], "--tolerance")) tolerance = std::atof(argv[k + 1]);
    if (!std::strcmp(argv[k], "--from")) low = std::atof(argv[k + 1]);
    if (!std::strcmp(argv[k], "--to")) high = std::atof(argv[k + 1]);
  }
  std::map<double, std::vector<Series>> points;  // frequency: fills in order
  double frequency;
  int fill, n;
  while (std::cin >> frequency >> fill >> n) {
    Series s;
    for (int k = 0; k < n; ++k) {
      double amplitude, phase;
      std::cin >> amplitude >> phase;
      if (k >= skip && static_cast<int>(s.size()) < cap) s.push_back(std::polar(amplitude, phase));
    }
    points[frequency].push_back(s);
  }
  const SteadyStateCriteria criteria{tolerance, 10, 4};
  long total = 0;
  for (const auto& [f, fills] : points) {
    if (f < low || f > high) continue;
    const std::size_t count = fills.size();
    std::vector<int> stop(count, 0);
    std::vector<char> by(count, ' ');
    std::vector<std::complex<double>> now(count);
    std::vector<FillValue> value(count);
    auto head = [&](std::size_t q, int k) {
      return Series(fills[q].begin(), fills[q].begin() + k);
    };
    auto keep = [&](std::size_t q, int k, const Stationary& s, char why) {
      stop[q] = k, by[q] = why, now[q] = s.mean;
      value[q] = {s.mean, s.amplitude_ci, s.phase_ci, s.batches - 1, s.converged || s.stationary,
                  s.drift};
    };
    std::size_t longest = 0;
    for (const Series& s : fills) longest = std::max(longest, s.size());
    for (int k = 1; k <= static_cast<int>(longest); ++k) {
      for (std::size_t q = 0; q < count; ++q) {
        if (stop[q] > 0) continue;
        const Stationary s = analyse_periods(head(q, k), criteria);
        now[q] = s.mean;
        if (s.converged)
          keep(q, k, s, ' ');
        else if (k == static_cast<int>(fills[q].size()))
          keep(q, k, s, k == cap ? 'C' : 'E');
      }
      if (k % 25) continue;
      const std::vector<std::complex<double>> at_look = now;  // the means every look compares
      for (std::size_t q = 0; q < count; ++q) {
        if (stop[q] > 0) continue;
        const std::vector<std::complex<double>> values(
            at_look.begin(), at_look.begin() + static_cast<long>(std::max<std::size_t>(q + 1, 2)));
        const Floors floors = spread_floors(values);
        SteadyStateCriteria relaxed = criteria;
        relaxed.amplitude_floor = floors.amplitude;
        relaxed.phase_floor = floors.phase;
        if (known_at_look(head(q, k), relaxed))
          keep(q, k, analyse_periods(head(q, k), relaxed, k / 2), 'L');
      }
    }
    const Ensemble e = judge_ensemble(value, tolerance, true);
    int periods = 0;
    std::printf("%6.2f Hz:", f);
    for (std::size_t q = 0; q < count; ++q) {
      std::printf(" %d%c", stop[q], by[q]);
      periods += stop[q];
    }
    std::printf("\n          %.4g +- %.1f %%, %s; %d periods\n", e.mean.amplitude.mean * 1e3,
                100 * e.mean.amplitude.half_width / e.mean.amplitude.mean,
                e.result == PointResult::none ? ("NOT a result: " + e.reason).c_str() : "a result",
                periods);
    total += periods;
  }
  std::printf("periods %ld (L: stopped at a look, C: at the cap, E: at the end of the record)\n",
              total);
}

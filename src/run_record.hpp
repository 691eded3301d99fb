// What a run has done, as its checkpoint keeps it: each fill's settled bed, what each fill
// measured at each point (and its means at the looks), which points are finished, the carried
// fills' states between points and the work so far. The Driver fills it as it schedules; a
// resumed run starts from it.
#pragma once

#include <complex>
#include <cstddef>
#include <map>
#include <optional>
#include <vector>

#include "kernels/state_arrays.hpp"
#include "src/frequency_run.hpp"

namespace pdsim {

struct RunRecord {
  RunRecord(std::size_t fills, std::size_t count);  // fills a point may grow to, points

  std::vector<StateArrays> beds;   // per fill: its settled bed (empty: not yet)
  std::vector<BedReport> reports;  // per fill
  std::vector<std::vector<std::optional<FrequencyPoint>>> points;     // [fill][point]
  std::vector<std::vector<std::vector<std::complex<double>>>> looks;  // [fill][point]
  std::vector<char> done;                     // per point: finished (its ensemble judged)
  std::map<std::size_t, StateArrays> states;  // a carried fill's state after its last point
  bool bed_from_file = false;                 // the first fills' beds were read from bed.file
  long long particle_steps = 0;
  double simulated_s = 0;
  double wall_before_s = 0;  // of the sessions before this one (a resumed run's)

  // Fills 0..n-1 have begun (settled their beds).
  std::size_t fills_begun() const;
  // The last point fill r has run, -1 for none.
  long reached(std::size_t r) const;
};

// Fills 0..count-1's beds and their reports ("bed.reports": four numbers a fill), into a
// checkpoint or a bed file; and back, into the fills whose beds are not yet settled.
void put_beds(const RunRecord& record, std::size_t count, StateArrays& out);
void get_beds(const StateArrays& in, std::size_t count, RunRecord& record);

// The whole record into a checkpoint, `wall_s` the run's wall time so far; and back.
void put_checkpoint(const RunRecord& record, double wall_s, StateArrays& out);
void get_checkpoint(const StateArrays& in, RunRecord& record);

}  // namespace pdsim

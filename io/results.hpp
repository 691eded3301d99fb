// Everything a run produces, in SI units, and the HDF5 writer/reader for it (io/output.md).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "kernels/state_arrays.hpp"
#include "kernels/tallies.hpp"

namespace pdsim {

// Each table lists its columns once, with units and meaning, in a *_columns(table, f) function
// that calls f(name, column, units, description) for each: the writer and the reader of
// io/results.cpp both walk that list (T is the table or a const table).

struct TimeSeries {  // structure DOF along the excitation direction, total force on the
                     // container(s)
  std::vector<double> time, displacement, velocity, damper_force, damper_force_mean, frequency;
};
template <class T, class F>
void timeseries_columns(T& t, F&& f) {
  f("time", t.time, "s", "simulated time of the sample");
  f("displacement", t.displacement, "m",
    "structure displacement at the response DOF along the excitation direction (relative to "
    "the base for base input)");
  f("velocity", t.velocity, "m/s", "structure velocity at the response DOF");
  f("damper_force", t.damper_force, "N",
    "force of the particles on the container(s) along the direction: the mean over the coupling "
    "interval that starts at the sample (tight coupling: its value at the sample)");
  f("damper_force_mean", t.damper_force_mean, "N",
    "damper_force averaged over the time since the previous sample (its impulse over that "
    "interval), so that impacts between samples are not lost; NaN at a run's first sample");
  f("frequency", t.frequency, "Hz", "excitation frequency being run when the sample was taken");
}

// What the 95 % intervals of a /frf or /prescribed row are made of.
inline constexpr const char* kIntervalKinds =
    "kind of the 95 % intervals: 0 batch means over one run's stationary periods; 1 several "
    "realisations that agree, their intervals pooled; 2 realisations that disagree (coexisting "
    "regimes of the bed), the Student-t spread of their means";

// /frf: one row per stepped-sine point (frequency and sweep). A point's result is the
// ensemble of its fills (random packings of the same damper): the mean over the fills with
// its 95 % interval, where one fill lies (amplitude_spread), and its branches.
struct FrfTable {
  std::vector<double> frequency, amplitude, amplitude_ci, phase, phase_ci, rms, peak;
  std::vector<int> periods, periods_discarded, converged, realisations, interval;
  std::vector<double> dissipated_energy, dissipated_energy_ci;
  std::array<std::vector<double>, kMechanisms> dissipated;  // J per period, by mechanism
  std::vector<int> sweep, result, branches;
  std::vector<double> amplitude_spread, phase_spread;
};
template <class T, class F>
void frf_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "excitation frequency");
  f("sweep", t.sweep, "1", "+1 sweeping up, -1 sweeping down (excitation.direction)");
  f("amplitude", t.amplitude, "m",
    "first-harmonic displacement amplitude: the mean over the fills of each fill's mean over "
    "its stationary periods");
  f("amplitude_ci", t.amplitude_ci, "m",
    "95 % half-width of amplitude, the ensemble mean (its kind: interval)");
  f("amplitude_spread", t.amplitude_spread, "m",
    "95 % prediction half-width over the fills: where one more fill (one damper of this "
    "design) would lie; NaN with a single fill");
  f("phase", t.phase, "rad",
    "phase of the first harmonic against the input sin(angle): x = amplitude sin(angle + "
    "phase), the mean over the fills");
  f("phase_ci", t.phase_ci, "rad", "95 % half-width of phase (as amplitude_ci)");
  f("phase_spread", t.phase_spread, "rad", "95 % prediction half-width of phase over the fills");
  f("result", t.result, "1",
    "0 not a result (a fill still drifting at settle.max_periods, or fills that agree on one "
    "state whose mean is not known to settle.tolerance with settle.max_realisations fills), 1 "
    "one state (the ensemble mean amplitude known to the tolerance), 2 several branches (each "
    "branch's mean known to the tolerance, or, with settle.max_realisations fills, fills "
    "distinct beyond their own intervals; the ensemble mean carries its wide interval, "
    "/frf/branch_means/within_tolerance says which branches meet the tolerance)");
  f("branches", t.branches, "1",
    "distinct states among the fills (fills linked when their amplitudes agree within "
    "settle.tolerance or their own intervals; /frf/branch_means)");
  f("rms", t.rms, "m", "RMS displacement over the stationary periods");
  f("peak", t.peak, "m", "largest |displacement| over the stationary periods");
  f("periods", t.periods, "1", "periods run at this frequency (per realisation, the largest)");
  f("periods_discarded", t.periods_discarded, "1",
    "warm-up periods left out of the means (MSER truncation; largest over the realisations)");
  f("converged", t.converged, "1", "1 when the point is a result (result > 0), else 0");
  f("realisations", t.realisations, "1", "fills (fill seeds) behind the point");
  f("interval", t.interval, "1", kIntervalKinds);
  f("dissipated_energy", t.dissipated_energy, "J",
    "energy the containers put into the particles per period (= dissipated in them when "
    "stationary)");
  f("dissipated_energy_ci", t.dissipated_energy_ci, "J", "95 % half-width of dissipated_energy");
  for (int m = 0; m < kMechanisms; ++m)
    f(kMechanismColumns[m].name, t.dissipated[m], "J", kMechanismColumns[m].per_period);
}

// /frf/fills: every fill's own value at every point.
struct FillTable {
  std::vector<double> frequency, amplitude, amplitude_ci, phase, phase_ci;
  std::vector<int> sweep, realisation, branch, periods, converged, settled;
};
template <class T, class F>
void fill_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "excitation frequency");
  f("sweep", t.sweep, "1", "+1 sweeping up, -1 down");
  f("realisation", t.realisation, "1", "fill (seed offset), from 0");
  f("branch", t.branch, "1", "the fill's branch at this point, from 0 (highest amplitude)");
  f("amplitude", t.amplitude, "m", "the fill's mean first-harmonic amplitude");
  f("amplitude_ci", t.amplitude_ci, "m", "its 95 % half-width from batch means");
  f("phase", t.phase, "rad", "the fill's mean phase");
  f("phase_ci", t.phase_ci, "rad", "its 95 % half-width");
  f("periods", t.periods, "1", "periods the fill ran at this point");
  f("converged", t.converged, "1", "1 when the fill's own mean is known to settle.tolerance");
  f("settled", t.settled, "1",
    "1 when the fill settled on its own: converged, or held still (no drift) when "
    "settle.max_periods ended it, its interval then as wide as it is; 0 still drifting");
}

// /frf/branch_means: each branch of each point.
struct BranchTable {
  std::vector<double> frequency, share, share_low, share_high, amplitude, amplitude_ci, phase,
      phase_ci;
  std::vector<int> sweep, branch, fills, within_tolerance;
};
template <class T, class F>
void branch_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "excitation frequency");
  f("sweep", t.sweep, "1", "+1 sweeping up, -1 down");
  f("branch", t.branch, "1", "branch, from 0 (highest amplitude)");
  f("fills", t.fills, "1", "fills in the branch");
  f("share", t.share, "1", "fraction of the point's fills in the branch");
  f("share_low", t.share_low, "1", "lower end of the 95 % Wilson score interval of share");
  f("share_high", t.share_high, "1", "upper end of that interval");
  f("amplitude", t.amplitude, "m", "mean amplitude of the branch's fills");
  f("amplitude_ci", t.amplitude_ci, "m", "its 95 % half-width");
  f("phase", t.phase, "rad", "mean phase of the branch's fills");
  f("phase_ci", t.phase_ci, "rad", "its 95 % half-width");
  f("within_tolerance", t.within_tolerance, "1",
    "1 when the branch's mean amplitude is known to settle.tolerance");
}

// The headline of an FRF, over every result point (/frf attributes, the run's summary line and
// a sweep's summary.csv all take it from here): the highest ensemble mean amplitude with its
// interval and frequency, and the highest single fill at a result point. NaN without results.
// So that the headline never hides the hard part, also the highest mean at a point that is not
// a result when it is above that peak (or there are no results).
struct FrfPeak {
  double amplitude = 0, amplitude_ci = 0, frequency = 0, upper = 0;
  int sweep = 0;
  bool found = false;
  double higher_amplitude = 0, higher_amplitude_ci = 0, higher_frequency = 0;
  int higher_sweep = 0;
  bool higher = false;
};
FrfPeak frf_peak(const FrfTable& frf, const FillTable& fills);

struct PrescribedTable {  // one row per prescribed-motion point
  std::vector<int> sweep;
  std::vector<double> frequency, amplitude, dissipated_power, dissipated_power_ci, force_amplitude,
      force_amplitude_ci, force_phase, force_phase_ci;
  std::vector<int> periods, periods_discarded, converged, realisations, interval;
};
template <class T, class F>
void prescribed_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "frequency of the container motion");
  f("sweep", t.sweep, "1", "+1 on the way up (frequency or amplitude), -1 on the way down");
  f("amplitude", t.amplitude, "m", "amplitude X of the container motion");
  f("dissipated_power", t.dissipated_power, "W",
    "mean power the container puts into the particles over the stationary periods");
  f("dissipated_power_ci", t.dissipated_power_ci, "W", "95 % half-width of dissipated_power");
  f("force_amplitude", t.force_amplitude, "N",
    "first harmonic of the particles' force on the container along the motion axis");
  f("force_amplitude_ci", t.force_amplitude_ci, "N", "95 % half-width of force_amplitude");
  f("force_phase", t.force_phase, "rad", "phase of that force against the displacement");
  f("force_phase_ci", t.force_phase_ci, "rad", "95 % half-width of force_phase");
  f("periods", t.periods, "1", "periods run at this frequency");
  f("periods_discarded", t.periods_discarded, "1", "warm-up periods left out of the means");
  f("converged", t.converged, "1",
    "1 when the force harmonic is stationary and known to settle.tolerance (fixed durations "
    "too)");
  f("realisations", t.realisations, "1", "independent runs (fill seeds) behind the point");
  f("interval", t.interval, "1", kIntervalKinds);
}

// A damper map (`pdsim map`): one row per grid point of prescribed motion X sin(w t) along the
// structure's direction. The first harmonic of the particles' force on the container,
// F1 = (w^2 m_eff - i w c_eff) X, gives the effective mass and damping a host feels.
struct MapTable {
  std::vector<double> frequency, amplitude, acceleration, force_amplitude, force_amplitude_ci,
      force_phase, force_phase_ci, effective_mass, effective_mass_ci, effective_damping,
      effective_damping_ci, dissipated_power, dissipated_power_ci;
  std::vector<int> sweep, periods, converged, realisations;
};
template <class T, class F>
void map_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "frequency of the container motion");
  f("amplitude", t.amplitude, "m", "amplitude X of the container motion");
  f("sweep", t.sweep, "1",
    "0: the point ran from the settled bed; +1: amplitudes stepped up to it, -1: back down to it "
    "(the bed carried from the point before)");
  f("acceleration", t.acceleration, "g", "peak acceleration X w^2 of the motion, in 9.80665 m/s^2");
  f("force_amplitude", t.force_amplitude, "N",
    "first harmonic |F1| of the particles' force on the container along the motion");
  f("force_amplitude_ci", t.force_amplitude_ci, "N", "95 % half-width of force_amplitude");
  f("force_phase", t.force_phase, "rad", "phase of F1 against the displacement");
  f("force_phase_ci", t.force_phase_ci, "rad", "95 % half-width of force_phase");
  f("effective_mass", t.effective_mass, "kg",
    "Re(F1 / X) / w^2: the mass a host feels (a rigid load: its mass; may be negative)");
  f("effective_mass_ci", t.effective_mass_ci, "kg", "95 % half-width, from F1's intervals");
  f("effective_damping", t.effective_damping, "N s/m",
    "-Im(F1 / X) / w: the viscous damping a host feels");
  f("effective_damping_ci", t.effective_damping_ci, "N s/m",
    "95 % half-width, from F1's intervals");
  f("dissipated_power", t.dissipated_power, "W",
    "mean power the container puts into the particles (w^2 X^2 effective_damping / 2)");
  f("dissipated_power_ci", t.dissipated_power_ci, "W", "95 % half-width of dissipated_power");
  f("periods", t.periods, "1", "periods run at this point (the longest fill)");
  f("converged", t.converged, "1",
    "1 when the force harmonic is stationary and known to excitation.settle.tolerance");
  f("realisations", t.realisations, "1", "fills behind the point");
}

// Appends `from`'s rows to `to`'s (one map of the points of several).
void append_rows(MapTable& to, const MapTable& from);

// A host's FRF predicted from a damper map by harmonic balance (`pdsim predict`): one row per
// frequency, way of the map and branch (every amplitude that balances the drive there).
struct HbTable {
  std::vector<double> frequency, amplitude, amplitude_ci, phase, damper_amplitude, effective_mass,
      effective_damping, map_change;
  std::vector<int> sweep, branch, stable, map_converged;
};
template <class T, class F>
void hb_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "excitation frequency");
  f("sweep", t.sweep, "1",
    "the map's rows the root is from: 0 its points from the settled bed, +1 its amplitudes "
    "stepped up, -1 stepped down");
  f("branch", t.branch, "1",
    "the balance's roots at this frequency and sweep, from 0 = the lowest damper amplitude");
  f("amplitude", t.amplitude, "m",
    "first-harmonic displacement amplitude of the structure's response point (as /frf)");
  f("amplitude_ci", t.amplitude_ci, "m",
    "95 % half-width from the map's intervals, to first order (large near a turning point)");
  f("phase", t.phase, "rad", "x = amplitude sin(angle + phase) against the drive's sin(angle)");
  f("stable", t.stable, "1",
    "1 when the root is stable to slow changes of amplitude (d(X |1 + (Z(X) - Z0) H|)/dX > 0)");
  f("damper_amplitude", t.damper_amplitude, "m",
    "the damper's container motion X at the root (the map's amplitude)");
  f("effective_mass", t.effective_mass, "kg", "the map's effective mass at this amplitude");
  f("effective_damping", t.effective_damping, "N s/m", "the map's effective damping here");
  f("map_change", t.map_change, "1",
    "how far the map's impedance F1 / X moves across the amplitudes the root lies between, as a "
    "share of the balance there: above 0.5 the map is too coarse there to read by straight "
    "lines");
  f("map_converged", t.map_converged, "1",
    "1 when every map point the root is read from converged (/map/converged)");
}

struct PeriodTable {  // one row per period run, per frequency and realisation
  std::vector<double> frequency, amplitude, phase, force_amplitude, force_phase, energy_in;
  std::vector<int> realisation, period, stationary;
};
template <class T, class F>
void period_columns(T& t, F&& f) {
  f("frequency", t.frequency, "Hz", "excitation frequency");
  f("realisation", t.realisation, "1", "realisation (fill seed offset), from 0");
  f("period", t.period, "1", "period at this frequency, from 0");
  f("stationary", t.stationary, "1", "1 for the periods the means use, 0 for the warm-up");
  f("amplitude", t.amplitude, "m", "this period's first-harmonic displacement amplitude");
  f("phase", t.phase, "rad", "its phase against the input sin(angle)");
  f("force_amplitude", t.force_amplitude, "N",
    "this period's first harmonic of the particles' force on the container(s)");
  f("force_phase", t.force_phase, "rad", "its phase against the input (prescribed: the motion)");
  f("energy_in", t.energy_in, "J", "energy the containers put into the particles this period");
}

// The energy ledger of one continuous run, in the inertial frame of the particles (the
// structure's kinetic energy includes the base's motion), each sample the state at the start
// of a step with the works and losses up to it.
// Particle snapshots (output.particles): every `every` seconds, each damper's particles and its
// container, in the world frame. Arrays are flat, row-major: position[(t * N + i) * 3 + c].
struct DamperSnapshots {
  std::string shape;                       // "box", "cylinder" or "mesh"
  std::vector<double> size;                // m: box edge lengths; cylinder diameter, -, height;
                                           // mesh: twice its extents from the origin
  std::vector<double> radius;              // m, per particle (N)
  std::vector<double> position, velocity;  // m, m/s (T x N x 3)
  std::vector<double> spin;                // rad/s (T x N x 3)
  std::vector<std::int32_t> contacts;      // partners and walls each particle touches (T x N)
  std::vector<double> container_position;  // m, centre (T x 3)
  std::vector<double> container_axes;      // rows: the container's x, y, z axes (T x 3 x 3)
  // The container's outline in its own frame (a mesh's edges where its surfaces meet): points
  // (P x 3, m) and the segments joining them (S x 2 point indices); empty in older files.
  std::vector<double> outline_points;
  std::vector<std::int32_t> outline_segments;
};
struct ParticleSnapshots {
  std::vector<double> time;  // s (T)
  std::vector<DamperSnapshots> dampers;
};

struct EnergySeries {
  std::vector<double> time, work_in, dissipated_structure;
  std::array<std::vector<double>, kMechanisms> dissipated;  // J, cumulative, by mechanism
  std::vector<double> kinetic, potential, imbalance;
};
template <class T, class F>
void energy_columns(T& t, F&& f) {
  f("time", t.time, "s", "simulated time");
  f("work_in", t.work_in, "J",
    "cumulative work of the input in the inertial frame: the external force's; the base's, on "
    "the structure and through it on the dampers; the containers' for prescribed motion; with "
    "the energy a new frequency's drive or predicted start puts in");
  f("dissipated_structure", t.dissipated_structure, "J", "cumulative, structural damping");
  for (int m = 0; m < kMechanisms; ++m)
    f(kMechanismColumns[m].name, t.dissipated[m], "J", kMechanismColumns[m].cumulative);
  f("kinetic", t.kinetic, "J",
    "inertial frame: the structure's (with the base's motion), the particles' translation and "
    "rotation");
  f("potential", t.potential, "J",
    "the structure's elastic energy, the particles' weight (zero at the origin) and the contact "
    "springs' energy");
  f("imbalance", t.imbalance, "J",
    "work_in - dissipated_* - (kinetic + potential), each as its change since the first sample");
}

// Every /meta attribute a file may hold, declared once: write_results() refuses any other (a
// programming error, never a user's), and a test holds io/output.md's table to this list.
// `complete` is the writer's own (1 in a finished file).
struct MetaAttribute {
  const char* name;
  bool text;  // a string, else a number
};
inline constexpr MetaAttribute kMetaAttributes[] = {
    {"deck", true},
    {"deck_path", true},
    {"title", true},
    {"sweep_point", true},
    {"version", true},
    {"backend", true},
    {"kernel_variant", true},
    {"coupling", true},
    {"dt_basis", true},
    {"warning", true},
    {"start", true},
    {"bed", true},
    {"failure", true},
    {"identity", true},
    {"maps", true},
    {"threads", false},
    {"jobs", false},
    {"dt", false},
    {"dt_limit", false},
    {"wall_time_s", false},
    {"particle_steps", false},
    {"solver_iterations_per_step", false},
    {"solver_most_iterations", false},
    {"solver_steps_at_cap", false},
    {"solver_worst_residual", false},
    {"particles", false},
    {"simulated_time_s", false},
    {"realisations", false},
    {"max_realisations", false},
    {"fills_used", false},
    {"bed_settled", false},
    {"bed_settle_time_s", false},
    {"bed_speed", false},
    {"complete", false},
};

struct Results {
  // /meta attributes (kMetaAttributes).
  std::map<std::string, std::string> meta_text;
  std::map<std::string, double> meta_numbers;
  TimeSeries timeseries;
  FrfTable frf;
  FillTable fills;           // /frf/fills
  BranchTable branch_means;  // /frf/branch_means
  PrescribedTable prescribed;
  MapTable map;         // /map, written by pdsim map
  HbTable frf_hb;       // /frf_hb, written by pdsim predict
  PeriodTable periods;  // the per-period harmonics behind /frf or /prescribed
  std::optional<EnergySeries> energy;
  std::optional<ParticleSnapshots> particles;
  // Restart state (named flat arrays), written while a run is in progress so that --resume
  // continues after the last finished frequency. Empty in a finished file.
  StateArrays checkpoint;  // format kCheckpointFormat, each array in its own type
};

// Writes `results` to `path`, or with complete = false to the checkpoint "<path>.partial"
// (which a complete write then removes). Each write replaces the old file whole, through a
// flushed temporary file and a rename: a crash, a kill or a full disk leaves the previous file
// intact, and an interrupted run never leaves a file that looks complete. With replace = false
// a complete write refuses to overwrite a file that appeared at `path` meanwhile (the results
// then go to "<path>.finished"). Throws
// std::runtime_error naming the path on any failure (HDF5 or the disk).
void write_results(const std::string& path, const Results& results, bool complete,
                   bool replace = true);

// Replaces `path` by `text` whole: a flushed temporary file renamed into place.
void replace_file(const std::string& path, const std::string& text);

// Writes `results` to exactly `path` as an unfinished file (/meta/complete = 0), replacing it
// whole (what a failed run had computed). Throws std::runtime_error naming the path.
void write_unfinished(const std::string& path, const Results& results);

// An advisory lock on "<path>.lock", held while a run writes `path`: a second pdsim writing the
// same output is refused at once (std::runtime_error naming the path) instead of overwriting
// the first one's results unnoticed. The lock file is removed when the lock is released.
class OutputLock {
 public:
  explicit OutputLock(const std::string& path);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  std::string file_;
  int fd_ = -1;
};

// Whether a pdsim holds the lock of output `path` now (a run writing it).
bool output_locked(const std::string& path);

// Reads a file written by write_results (finished or ".partial"). Throws on failure.
Results read_results(const std::string& path);

}  // namespace pdsim

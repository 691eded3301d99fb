// Everything a run produces, in SI units, and the HDF5 writer/reader for it (brief section 6).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace pdsim {

struct TimeSeries {  // structure DOF along the excitation direction, total force on the
                     // container(s)
  std::vector<double> time, displacement, velocity, damper_force;  // s, m, m/s, N
};

struct FrfTable {                             // one row per stepped-sine frequency
  std::vector<double> frequency;              // Hz
  std::vector<double> amplitude;              // m, first-harmonic displacement amplitude
  std::vector<double> phase;                  // rad, of the displacement relative to the input
  std::vector<double> rms;                    // m
  std::vector<double> peak;                   // m
  std::vector<int> periods;                   // periods run at this frequency
  std::vector<int> converged;                 // 0/1
  std::vector<double> dissipated_energy;      // J per cycle in the particles
  std::vector<double> dissipated_normal;      // J per cycle, normal damping
  std::vector<double> dissipated_tangential;  // J per cycle, friction / tangential damping
};

struct PrescribedTable {                 // one row per prescribed-motion frequency
  std::vector<double> frequency;         // Hz
  std::vector<double> dissipated_power;  // W, mean over the averaged cycles
  std::vector<double> force_amplitude;   // N, first harmonic of the container force along the axis
  std::vector<double> force_phase;       // rad, relative to the displacement
};

struct EnergySeries {
  std::vector<double> time, kinetic, elastic, dissipated_normal, dissipated_tangential, work_in;
};

struct Results {
  // /meta attributes: deck, version, backend, threads, dt, wall_time_s, particle_steps, ...
  std::map<std::string, std::string> meta_text;
  std::map<std::string, double> meta_numbers;
  TimeSeries timeseries;
  FrfTable frf;
  PrescribedTable prescribed;
  std::optional<EnergySeries> energy;
  // Restart state (named flat arrays), written while a run is in progress so that --resume
  // continues after the last finished frequency. Empty in a finished file.
  std::map<std::string, std::vector<double>> checkpoint;
};

// Writes `results` to `path` atomically: the data go to "<path>.partial" first, which is
// renamed over `path` only when `complete` is true, so an interrupted run never leaves a file
// that looks complete. With complete = false only the ".partial" file is (re)written.
// Throws std::runtime_error naming the path on any HDF5 failure.
void write_results(const std::string& path, const Results& results, bool complete);

// Reads a file written by write_results (finished or ".partial"). Throws on failure.
Results read_results(const std::string& path);

}  // namespace pdsim

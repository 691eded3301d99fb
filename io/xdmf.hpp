// An XDMF index of a result file's particle snapshots, so that ParaView (or VisIt) opens a run
// as a time series: per damper, its particles as points (radius, velocity, spin attributes read
// from the HDF5 file) and its container as a wireframe moving with it.
#pragma once

#include <string>

#include "io/results.hpp"

namespace pdsim {

// The index's path beside a result file: OUT.h5 -> OUT.xdmf (other names: OUT.xdmf appended).
std::string xdmf_path(const std::string& h5_path);

// Writes the index of `snapshots`, stored in `h5_path` (named relative to the index's folder),
// whole or not at all (a temporary file renamed into place).
void write_xdmf(const std::string& h5_path, const ParticleSnapshots& snapshots);

}  // namespace pdsim

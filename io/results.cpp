// HDF5 writer/reader for Results (io/output.md), on the HDF5 1.10 C API.
#include "io/results.hpp"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <variant>

namespace pdsim {
namespace {

static_assert(sizeof(int) == 4, "FrfTable int columns are stored as 32-bit integers");

// The innermost message of the HDF5 error stack ("unable to open file: ... errno = 2, ...")
// is the only place that says why a call failed; read it before the next call clears it.
std::string hdf5_reason() {
  std::string reason;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_DOWNWARD,
      [](unsigned, const H5E_error2_t* error, void* out) -> herr_t {
        if (error->desc != nullptr && error->desc[0] != '\0') {
          *static_cast<std::string*>(out) = error->desc;
        }
        return 0;
      },
      &reason);
  return reason;
}

[[noreturn]] void fail(const std::string& file, const std::string& what) {
  const std::string reason = hdf5_reason();
  throw std::runtime_error(file + ": HDF5: cannot " + what + (reason.empty() ? "" : ": " + reason));
}

template <typename T>
T check(T status, const std::string& file, const std::string& what) {
  if (status < 0) fail(file, what);
  return status;
}

// Owns one HDF5 identifier and closes it with the matching H5*close.
class Handle {
 public:
  Handle(hid_t id, herr_t (*closer)(hid_t), const std::string& file, const std::string& what)
      : id_(check(id, file, what)), close_(closer) {}
  Handle(Handle&& other) noexcept
      : id_(std::exchange(other.id_, H5I_INVALID_HID)), close_(other.close_) {}
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  Handle& operator=(Handle&&) = delete;
  ~Handle() {
    if (id_ >= 0) close_(id_);
  }
  hid_t get() const { return id_; }
  // Closing a file flushes it; that failure must be reported, not swallowed by a destructor.
  void close(const std::string& file) {
    const hid_t id = std::exchange(id_, H5I_INVALID_HID);
    check(close_(id), file, "close");
  }

 private:
  hid_t id_;
  herr_t (*close_)(hid_t);
};

Handle variable_string_type(const std::string& file) {
  Handle type(H5Tcopy(H5T_C_S1), H5Tclose, file, "copy the string type");
  check(H5Tset_size(type.get(), H5T_VARIABLE), file, "make a variable-length string type");
  check(H5Tset_cset(type.get(), H5T_CSET_UTF8), file, "set the UTF-8 character set");
  return type;
}

// ---- writing ----

// A scalar attribute; `value` points to one element of `memory_type`.
void write_attribute(hid_t group, const std::string& name, hid_t file_type, hid_t memory_type,
                     const void* value, const std::string& file,
                     const std::string& where = "/meta") {
  const std::string what = "write attribute " + where + "/" + name;
  Handle space(H5Screate(H5S_SCALAR), H5Sclose, file, what);
  Handle attribute(
      H5Acreate2(group, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
      file, what);
  check(H5Awrite(attribute.get(), memory_type, value), file, what);
}

void write_text_attribute(hid_t object, const std::string& name, const std::string& text,
                          const std::string& file, const std::string& where) {
  const Handle type = variable_string_type(file);
  const char* chars = text.c_str();
  write_attribute(object, name, type.get(), type.get(), &chars, file, where);
}

// A dataset of any rank (`dims`, row-major `data`).
void write_array(hid_t group, const std::string& group_path, const std::string& name,
                 hid_t file_type, hid_t memory_type, const void* data,
                 const std::vector<hsize_t>& dims, const std::string& file, const char* units,
                 const char* description) {
  const std::string what = "write dataset " + group_path + "/" + name;
  hsize_t size = 1;
  for (hsize_t d : dims) size *= d;
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose,
               file, what);
  Handle dataset(H5Dcreate2(group, name.c_str(), file_type, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                            H5P_DEFAULT),
                 H5Dclose, file, what);
  if (size > 0) {
    check(H5Dwrite(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), file, what);
  }
  if (units) write_text_attribute(dataset.get(), "units", units, file, group_path + "/" + name);
  if (description)
    write_text_attribute(dataset.get(), "description", description, file, group_path + "/" + name);
}

void write_column(hid_t group, const std::string& group_path, const std::string& name,
                  hid_t file_type, hid_t memory_type, const void* data, std::size_t size,
                  const std::string& file, const char* units, const char* description) {
  write_array(group, group_path, name, file_type, memory_type, data, {static_cast<hsize_t>(size)},
              file, units, description);
}

class GroupWriter {
 public:
  GroupWriter(hid_t parent, const std::string& path, const std::string& file)
      : path_(path),
        file_(file),
        group_(H5Gcreate2(parent, path.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
               file, "create group " + path) {}
  void column(const std::string& name, const std::vector<double>& values,
              const char* units = nullptr, const char* description = nullptr) {
    write_column(group_.get(), path_, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, values.data(),
                 values.size(), file_, units, description);
  }
  void column(const std::string& name, const std::vector<int>& values, const char* units = nullptr,
              const char* description = nullptr) {
    write_column(group_.get(), path_, name, H5T_STD_I32LE, H5T_NATIVE_INT, values.data(),
                 values.size(), file_, units, description);
  }
  void column(const std::string& name, const std::vector<std::uint64_t>& values,
              const char* units = nullptr, const char* description = nullptr) {
    write_column(group_.get(), path_, name, H5T_STD_U64LE, H5T_NATIVE_UINT64, values.data(),
                 values.size(), file_, units, description);
  }
  void column(const std::string& name, const std::vector<std::uint8_t>& values,
              const char* units = nullptr, const char* description = nullptr) {
    write_column(group_.get(), path_, name, H5T_STD_U8LE, H5T_NATIVE_UINT8, values.data(),
                 values.size(), file_, units, description);
  }
  hid_t id() const { return group_.get(); }
  // Every column of a table, with its units and description.
  template <class Table, class Columns>
  void table(const Table& t, Columns columns) {
    columns(t, [&](const char* name, const auto& values, const char* units, const char* what) {
      column(name, values, units, what);
    });
  }
  hid_t get() const { return group_.get(); }

 private:
  std::string path_, file_;
  Handle group_;
};

void write_meta(hid_t file_id, const Results& results, bool complete, const std::string& file) {
  GroupWriter meta(file_id, "/meta", file);
  // Variable-length strings: the deck text may exceed the 64 KiB limit of a fixed-length
  // attribute stored in the object header.
  const Handle text_type = variable_string_type(file);
  auto declared = [](const std::string& name, bool text) {
    for (const MetaAttribute& a : kMetaAttributes)
      if (name == a.name && text == a.text && name != "complete") return;
    throw std::runtime_error("/meta/" + name + " is not declared in kMetaAttributes as a " +
                             (text ? "text" : "number"));
  };
  for (const auto& [name, text] : results.meta_text) declared(name, true);
  for (const auto& [name, number] : results.meta_numbers) declared(name, false);
  for (const auto& [name, text] : results.meta_text) {
    const char* chars = text.c_str();
    write_attribute(meta.get(), name, text_type.get(), text_type.get(), &chars, file);
  }
  for (const auto& [name, number] : results.meta_numbers) {
    write_attribute(meta.get(), name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &number, file);
  }
  const int complete_flag = complete ? 1 : 0;
  write_attribute(meta.get(), "complete", H5T_STD_I32LE, H5T_NATIVE_INT, &complete_flag, file);
}

// Row `row` of the dataset `source` (dims: rows first) as a dataset `name` of its own: an HDF5
// virtual dataset, which holds no data, only where to read it.
void write_row_view(hid_t group, const std::string& group_path, const std::string& name,
                    const std::string& source, hid_t file_type, std::vector<hsize_t> dims,
                    hsize_t row, const std::string& file, const char* units) {
  const std::string what = "write the view " + group_path + "/" + name + " of " + source;
  std::vector<hsize_t> start(dims.size(), 0), count = dims;
  start[0] = row;
  count[0] = 1;
  Handle whole(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose,
               file, what);
  check(H5Sselect_hyperslab(whole.get(), H5S_SELECT_SET, start.data(), nullptr, count.data(),
                            nullptr),
        file, what);
  Handle view(H5Screate_simple(static_cast<int>(dims.size() - 1), dims.data() + 1, nullptr),
              H5Sclose, file, what);
  Handle layout(H5Pcreate(H5P_DATASET_CREATE), H5Pclose, file, what);
  check(H5Pset_virtual(layout.get(), view.get(), ".", source.c_str(), whole.get()), file, what);
  Handle dataset(H5Dcreate2(group, name.c_str(), file_type, view.get(), H5P_DEFAULT, layout.get(),
                            H5P_DEFAULT),
                 H5Dclose, file, what);
  const std::string path = group_path + "/" + name;
  write_text_attribute(dataset.get(), "units", units, file, path);
  write_text_attribute(
      dataset.get(), "description",
      "row " + std::to_string(row) + " of " + source + " (a view: no data of its own)", file, path);
}

// /particles: the snapshot times, then per damper its particles and container (OUT.xdmf indexes
// them for ParaView, io/xdmf.hpp).
void write_particles(hid_t parent, const ParticleSnapshots& s, const std::string& file) {
  GroupWriter g(parent, "/particles", file);
  g.column("time", s.time, "s", "snapshot times");
  const auto steps = static_cast<hsize_t>(s.time.size());
  for (std::size_t k = 0; k < s.dampers.size(); ++k) {
    const DamperSnapshots& d = s.dampers[k];
    const std::string path = "/particles/damper" + std::to_string(k);
    GroupWriter dg(g.id(), path, file);
    write_text_attribute(dg.id(), "shape", d.shape, file, path);
    dg.column("container_size", d.size, "m",
              "box: edge lengths; cylinder: diameter, diameter, height");
    dg.column("radius", d.radius, "m", "particle radii");
    const auto n = static_cast<hsize_t>(d.radius.size());
    const auto points = static_cast<hsize_t>(d.outline_points.size() / 3);
    write_array(dg.id(), path, "container_outline_points", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                d.outline_points.data(), {points, 3}, file, "m",
                "the container's outline, container frame: its corners (a mesh: its vertices)");
    const auto segments = static_cast<hsize_t>(d.outline_segments.size() / 2);
    write_array(dg.id(), path, "container_outline_segments", H5T_STD_I32LE, H5T_NATIVE_INT32,
                d.outline_segments.data(), {segments, 2}, file, "1",
                "the outline's edges (a mesh: where its surfaces meet), as pairs of point rows");
    auto array = [&](const char* name, const std::vector<double>& v, std::vector<hsize_t> dims,
                     const char* units, const char* what) {
      write_array(dg.id(), path, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, v.data(), dims, file,
                  units, what);
    };
    array("position", d.position, {steps, n, 3}, "m", "particle centres, world frame");
    array("velocity", d.velocity, {steps, n, 3}, "m/s", "particle velocities, world frame");
    array("spin", d.spin, {steps, n, 3}, "rad/s", "particle angular velocities, world frame");
    write_array(dg.id(), path, "contacts", H5T_STD_I32LE, H5T_NATIVE_INT32, d.contacts.data(),
                {steps, n}, file, "1",
                "contacts of each particle: the partners it overlaps and the walls it touches "
                "(-1: not counted, snapshots resumed from an older pdsim)");
    array("container_position", d.container_position, {steps, 3}, "m", "container centre");
    array("container_axes", d.container_axes, {steps, 3, 3}, "-",
          "rows: the container's x, y and z axes in the world frame");
    // For ParaView's Xdmf3 readers, which read no XDMF hyperslab and want a vertex per point:
    // each snapshot's arrays as views (step/T/position ...) and the vertices 0 .. N-1.
    std::vector<std::int32_t> vertex(d.radius.size());
    for (std::size_t i = 0; i < vertex.size(); ++i) vertex[i] = static_cast<std::int32_t>(i);
    write_array(dg.id(), path, "vertex", H5T_STD_I32LE, H5T_NATIVE_INT32, vertex.data(), {n}, file,
                "1", "0 .. N-1: each particle a vertex (OUT.xdmf's topology)");
    GroupWriter views(dg.id(), path + "/step", file);
    for (hsize_t t = 0; t < steps; ++t) {
      const std::string at = path + "/step/" + std::to_string(t);
      GroupWriter step(views.id(), at, file);
      for (const auto& [name, units] :
           {std::pair{"position", "m"}, std::pair{"velocity", "m/s"}, std::pair{"spin", "rad/s"}})
        write_row_view(step.id(), at, name, path + "/" + name, H5T_IEEE_F64LE, {steps, n, 3}, t,
                       file, units);
      write_row_view(step.id(), at, "contacts", path + "/contacts", H5T_STD_I32LE, {steps, n}, t,
                     file, "1");
    }
  }
}

// The whole file built in memory (HDF5's core driver, no backing store) and returned as its
// bytes: the disk is touched only by write_atomically(), so a full disk or a kill can never
// leave HDF5 with a half-written file open (which crashed at exit) or a checkpoint half-written.
std::vector<char> file_image(const std::string& file, const Results& r, bool complete) {
  Handle access(H5Pcreate(H5P_FILE_ACCESS), H5Pclose, file, "create a file access list");
  check(H5Pset_fapl_core(access.get(), 1 << 20, 0), file, "select the in-memory driver");
  Handle h5file(H5Fcreate(file.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, access.get()), H5Fclose, file,
                "create the file");
  write_meta(h5file.get(), r, complete, file);
  if (!r.timeseries.time.empty())
    GroupWriter(h5file.get(), "/timeseries", file).table(r.timeseries, [](auto& t, auto&& f) {
      timeseries_columns(t, f);
    });
  if (!r.frf.frequency.empty()) {
    GroupWriter frf(h5file.get(), "/frf", file);
    frf.table(r.frf, [](auto& t, auto&& f) { frf_columns(t, f); });
    const FrfPeak peak = frf_peak(r.frf, r.fills);
    const double nan = std::nan("");
    const std::pair<const char*, double> attributes[] = {
        {"peak_amplitude", peak.found ? peak.amplitude : nan},
        {"peak_amplitude_ci", peak.found ? peak.amplitude_ci : nan},
        {"peak_frequency", peak.found ? peak.frequency : nan},
        {"peak_upper", peak.found ? peak.upper : nan},
        {"peak_sweep", peak.found ? double(peak.sweep) : nan},
        {"higher_unresolved_amplitude", peak.higher ? peak.higher_amplitude : nan},
        {"higher_unresolved_amplitude_ci", peak.higher ? peak.higher_amplitude_ci : nan},
        {"higher_unresolved_frequency", peak.higher ? peak.higher_frequency : nan}};
    for (const auto& [name, value] : attributes)
      write_attribute(frf.id(), name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value, file, "/frf");
    if (!r.fills.frequency.empty())
      GroupWriter(frf.id(), "/frf/fills", file).table(r.fills, [](auto& t, auto&& f) {
        fill_columns(t, f);
      });
    if (!r.branch_means.frequency.empty())
      GroupWriter(frf.id(), "/frf/branch_means", file).table(r.branch_means, [](auto& t, auto&& f) {
        branch_columns(t, f);
      });
  }
  if (!r.prescribed.frequency.empty())
    GroupWriter(h5file.get(), "/prescribed", file).table(r.prescribed, [](auto& t, auto&& f) {
      prescribed_columns(t, f);
    });
  if (!r.map.frequency.empty())
    GroupWriter(h5file.get(), "/map", file).table(r.map, [](auto& t, auto&& f) {
      map_columns(t, f);
    });
  if (!r.frf_hb.frequency.empty())
    GroupWriter(h5file.get(), "/frf_hb", file).table(r.frf_hb, [](auto& t, auto&& f) {
      hb_columns(t, f);
    });
  if (!r.periods.frequency.empty())
    GroupWriter(h5file.get(), "/periods", file).table(r.periods, [](auto& t, auto&& f) {
      period_columns(t, f);
    });
  if (r.energy)
    GroupWriter(h5file.get(), "/energy", file).table(*r.energy, [](auto& t, auto&& f) {
      energy_columns(t, f);
    });
  if (r.particles) write_particles(h5file.get(), *r.particles, file);
  if (!r.checkpoint.empty()) {
    GroupWriter g(h5file.get(), "/checkpoint", file);
    write_attribute(g.id(), "format", H5T_STD_I32LE, H5T_NATIVE_INT, &kCheckpointFormat, file,
                    "/checkpoint");
    // Restart state in the engines' own units and layouts, read back only by pdsim.
    for (const auto& [name, values] : r.checkpoint)
      std::visit(
          [&g, &name = name](const auto& v) {
            g.column(name, v, "internal",
                     "restart state for --resume (kernels/state_arrays.hpp), not a result");
          },
          values);
  }
  check(H5Fflush(h5file.get(), H5F_SCOPE_LOCAL), file, "flush the file");
  const ssize_t size = check(H5Fget_file_image(h5file.get(), nullptr, 0), file, "size the file");
  std::vector<char> image(static_cast<std::size_t>(size));
  check(H5Fget_file_image(h5file.get(), image.data(), image.size()), file, "copy the file");
  h5file.close(file);
  return image;
}

[[noreturn]] void fail_io(const std::string& path, const std::string& what, int error) {
  throw std::runtime_error(path + ": cannot " + what + ": " + std::strerror(error));
}

// Flushes the folder of `path`, so that a rename in it reaches the disk (an error here leaves
// the files as they were: nothing to report).
void sync_folder(const std::string& path) {
  std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (folder.empty()) folder = ".";
  if (const int dir = open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir >= 0) {
    fsync(dir);
    close(dir);
  }
}

// Writes `bytes` to a temporary file beside `path` and flushes it to the disk; returns its
// name. A SIGKILL here leaves at most that temporary file behind, never a half-written `path`.
std::string write_temporary(const std::string& path, const std::vector<char>& bytes) {
  const std::string temporary = path + ".tmp-" + std::to_string(getpid());
  const int fd = open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int error = errno;
    fail_io(temporary, "create", error);
  }
  auto give_up = [&](const std::string& what, int error) {
    close(fd);
    unlink(temporary.c_str());
    fail_io(path, what, error);
  };
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = write(fd, bytes.data() + done, bytes.size() - done);
    const int error = errno;
    if (n < 0 && error == EINTR) continue;
    if (n <= 0) give_up("write", n < 0 ? error : ENOSPC);
    done += static_cast<std::size_t>(n);
  }
  if (fsync(fd) != 0) give_up("flush to the disk", errno);
  if (close(fd) != 0) {
    const int error = errno;
    unlink(temporary.c_str());
    fail_io(path, "write", error);
  }
  return temporary;
}

// Renames `from` to `to`; with `replace` false only where nothing is at `to` (RENAME_NOREPLACE,
// or a hard link on file systems without it, such as NFS: both refuse atomically). Returns 0
// or the errno (EEXIST: something is at `to`).
int move_into_place(const std::string& from, const std::string& to, bool replace) {
  if (replace) return rename(from.c_str(), to.c_str()) == 0 ? 0 : errno;
  if (renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) return 0;
  const int error = errno;
  if (error != EINVAL && error != ENOSYS && error != EOPNOTSUPP) return error;
  if (link(from.c_str(), to.c_str()) != 0) return errno;
  unlink(from.c_str());
  return 0;
}

}  // namespace

void replace_file(const std::string& path, const std::string& text) {
  const std::string temporary = write_temporary(path, std::vector<char>(text.begin(), text.end()));
  if (const int error = move_into_place(temporary, path, true); error != 0) {
    unlink(temporary.c_str());
    fail_io(path, "rename " + temporary + " to it", error);
  }
  sync_folder(path);
}

void write_results(const std::string& path, const Results& results, bool complete, bool replace) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const std::string partial = path + ".partial";
  const std::string target = complete ? path : partial;
  const std::string temporary = write_temporary(target, file_image(path, results, complete));
  // A complete file goes straight to `path`, so that the checkpoint stays resumable until the
  // finished file is in place; then the checkpoint goes.
  const int error = move_into_place(temporary, target, replace || !complete);
  if (error == EEXIST) {
    // Keep the finished results where the message says: in place of the checkpoint.
    const bool kept = rename(temporary.c_str(), (path + ".finished").c_str()) == 0;
    throw std::runtime_error(path +
                             ": appeared while pdsim ran (another program wrote it) and "
                             "is not overwritten without --force" +
                             (kept ? "; the results are in " + path + ".finished" : ""));
  }
  if (error != 0) {
    unlink(temporary.c_str());
    fail_io(target, "rename " + temporary + " to it", error);
  }
  sync_folder(target);
  if (complete) unlink(partial.c_str());
}

void write_unfinished(const std::string& path, const Results& results) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const std::string temporary = write_temporary(path, file_image(path, results, false));
  if (const int error = move_into_place(temporary, path, true); error != 0) {
    unlink(temporary.c_str());
    fail_io(path, "rename " + temporary + " to it", error);
  }
  sync_folder(path);
}

namespace {

// ---- reading ----

bool has_link(hid_t location, const std::string& name, const std::string& file) {
  return check(H5Lexists(location, name.c_str(), H5P_DEFAULT), file, "look up " + name) > 0;
}

// Reads a 1-D dataset; a missing one stays empty (files from older writers, optional columns).
// With `rank` > 1, a dataset of that rank read flat (row-major).
template <typename T>
void read_column(hid_t group, const std::string& group_path, const std::string& name,
                 hid_t memory_type, std::vector<T>& out, const std::string& file, int rank = 1) {
  if (!has_link(group, name, file)) return;
  const std::string what = "read dataset " + group_path + "/" + name;
  Handle dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT), H5Dclose, file, what);
  Handle space(H5Dget_space(dataset.get()), H5Sclose, file, what);
  if (check(H5Sget_simple_extent_ndims(space.get()), file, what) != rank) {
    throw std::runtime_error(file + ": " + group_path + "/" + name + " is not a " +
                             std::to_string(rank) + "-D dataset");
  }
  out.resize(
      static_cast<std::size_t>(check(H5Sget_simple_extent_npoints(space.get()), file, what)));
  if (!out.empty()) {
    check(H5Dread(dataset.get(), memory_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), file,
          what);
  }
}

class GroupReader {
 public:
  GroupReader(hid_t group, const std::string& path, const std::string& file)
      : path_(path), file_(file), group_(group) {}
  void column(const std::string& name, std::vector<double>& out) const {
    read_column(group_, path_, name, H5T_NATIVE_DOUBLE, out, file_);
  }
  void column(const std::string& name, std::vector<int>& out) const {
    read_column(group_, path_, name, H5T_NATIVE_INT, out, file_);
  }

 private:
  std::string path_, file_;
  hid_t group_;
};

// The format attribute of /checkpoint; checkpoints written before it had one are format 1.
int checkpoint_format(hid_t group, const std::string& file) {
  if (check(H5Aexists(group, "format"), file, "look up /checkpoint/format") <= 0) return 1;
  const std::string what = "read attribute /checkpoint/format";
  Handle attribute(H5Aopen(group, "format", H5P_DEFAULT), H5Aclose, file, what);
  int format = 0;
  check(H5Aread(attribute.get(), H5T_NATIVE_INT, &format), file, what);
  return format;
}

// A checkpoint array in the type it was written with.
StateArray read_state_array(hid_t group, const std::string& name, const std::string& file) {
  const std::string what = "read dataset /checkpoint/" + name;
  H5T_class_t type_class = H5T_NO_CLASS;
  std::size_t size = 0;
  bool is_signed = false;
  {
    Handle dataset(H5Dopen2(group, name.c_str(), H5P_DEFAULT), H5Dclose, file, what);
    Handle type(H5Dget_type(dataset.get()), H5Tclose, file, what);
    type_class = H5Tget_class(type.get());
    size = H5Tget_size(type.get());
    is_signed = type_class == H5T_INTEGER && H5Tget_sign(type.get()) == H5T_SGN_2;
  }
  auto read = [&](auto values, hid_t memory_type) -> StateArray {
    read_column(group, "/checkpoint", name, memory_type, values, file);
    return values;
  };
  if (type_class == H5T_FLOAT) return read(std::vector<double>{}, H5T_NATIVE_DOUBLE);
  if (type_class == H5T_INTEGER && size == 4 && is_signed)
    return read(std::vector<std::int32_t>{}, H5T_NATIVE_INT32);
  if (type_class == H5T_INTEGER && size == 8 && !is_signed)
    return read(std::vector<std::uint64_t>{}, H5T_NATIVE_UINT64);
  if (type_class == H5T_INTEGER && size == 1 && !is_signed)
    return read(std::vector<std::uint8_t>{}, H5T_NATIVE_UINT8);
  throw std::runtime_error(file + ": /checkpoint/" + name + " has a type no checkpoint uses");
}

// Calls `read(group_id, reader)` when the group exists; a missing group leaves the fields empty.
template <typename Read>
bool read_group(hid_t file_id, const std::string& path, const std::string& file, Read read) {
  if (!has_link(file_id, path, file)) return false;
  Handle group(H5Gopen2(file_id, path.c_str(), H5P_DEFAULT), H5Gclose, file, "open " + path);
  read(group.get(), GroupReader(group.get(), path, file));
  return true;
}

std::vector<std::string> member_names(hid_t group, bool attributes, const std::string& file,
                                      const std::string& what) {
  std::vector<std::string> names;
  hsize_t index = 0;
  if (attributes) {
    check(H5Aiterate2(
              group, H5_INDEX_NAME, H5_ITER_INC, &index,
              [](hid_t, const char* name, const H5A_info_t*, void* out) -> herr_t {
                static_cast<std::vector<std::string>*>(out)->emplace_back(name);
                return 0;
              },
              &names),
          file, what);
  } else {
    check(H5Literate(
              group, H5_INDEX_NAME, H5_ITER_INC, &index,
              [](hid_t, const char* name, const H5L_info_t*, void* out) -> herr_t {
                static_cast<std::vector<std::string>*>(out)->emplace_back(name);
                return 0;
              },
              &names),
          file, what);
  }
  return names;
}

// A string attribute (variable or fixed length) of `object`, whose path is `where`.
std::string read_text_attribute(hid_t object, const std::string& name, const std::string& file,
                                const std::string& where) {
  const std::string what = "read attribute " + where + "/" + name;
  Handle attribute(H5Aopen(object, name.c_str(), H5P_DEFAULT), H5Aclose, file, what);
  Handle file_type(H5Aget_type(attribute.get()), H5Tclose, file, what);
  if (H5Tget_class(file_type.get()) != H5T_STRING)
    throw std::runtime_error(file + ": " + where + "/" + name + " is not a string");
  Handle memory_type(H5Tget_native_type(file_type.get(), H5T_DIR_ASCEND), H5Tclose, file, what);
  if (check(H5Tis_variable_str(file_type.get()), file, what) > 0) {
    char* chars = nullptr;
    check(H5Aread(attribute.get(), memory_type.get(), &chars), file, what);
    std::string text = chars != nullptr ? chars : "";
    H5free_memory(chars);
    return text;
  }
  std::string chars(H5Tget_size(file_type.get()), '\0');
  check(H5Aread(attribute.get(), memory_type.get(), chars.data()), file, what);
  return chars.substr(0, std::strlen(chars.c_str()));
}

void read_meta(hid_t meta, Results& results, const std::string& file) {
  for (const std::string& name : member_names(meta, true, file, "list /meta attributes")) {
    if (name == "complete") continue;  // a property of the file, not of Results
    const std::string what = "read attribute /meta/" + name;
    Handle attribute(H5Aopen(meta, name.c_str(), H5P_DEFAULT), H5Aclose, file, what);
    Handle file_type(H5Aget_type(attribute.get()), H5Tclose, file, what);
    const H5T_class_t type_class = H5Tget_class(file_type.get());
    if (type_class == H5T_STRING) {
      results.meta_text[name] = read_text_attribute(meta, name, file, "/meta");
    } else if (type_class == H5T_FLOAT || type_class == H5T_INTEGER) {
      double number = 0;
      check(H5Aread(attribute.get(), H5T_NATIVE_DOUBLE, &number), file, what);
      results.meta_numbers[name] = number;
    } else {
      throw std::runtime_error(file + ": /meta/" + name + " is neither a string nor a number");
    }
  }
}

Results read_file(const std::string& file) {
  Results r;
  Handle h5file(H5Fopen(file.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose, file,
                "open the file");
  const hid_t f = h5file.get();
  read_group(f, "/meta", file, [&](hid_t meta, const GroupReader&) { read_meta(meta, r, file); });
  auto read_all = [](const GroupReader& g) {
    return
        [&g](const char* name, auto& values, const char*, const char*) { g.column(name, values); };
  };
  read_group(f, "/timeseries", file,
             [&](hid_t, const GroupReader& g) { timeseries_columns(r.timeseries, read_all(g)); });
  read_group(f, "/frf", file,
             [&](hid_t, const GroupReader& g) { frf_columns(r.frf, read_all(g)); });
  if (!r.frf.frequency.empty()) {
    read_group(f, "/frf/fills", file,
               [&](hid_t, const GroupReader& g) { fill_columns(r.fills, read_all(g)); });
    read_group(f, "/frf/branch_means", file,
               [&](hid_t, const GroupReader& g) { branch_columns(r.branch_means, read_all(g)); });
  }
  read_group(f, "/prescribed", file,
             [&](hid_t, const GroupReader& g) { prescribed_columns(r.prescribed, read_all(g)); });
  read_group(f, "/map", file,
             [&](hid_t, const GroupReader& g) { map_columns(r.map, read_all(g)); });
  read_group(f, "/frf_hb", file,
             [&](hid_t, const GroupReader& g) { hb_columns(r.frf_hb, read_all(g)); });
  read_group(f, "/periods", file,
             [&](hid_t, const GroupReader& g) { period_columns(r.periods, read_all(g)); });
  read_group(f, "/energy", file,
             [&](hid_t, const GroupReader& g) { energy_columns(r.energy.emplace(), read_all(g)); });
  read_group(f, "/particles", file, [&](hid_t group, const GroupReader& g) {
    ParticleSnapshots& s = r.particles.emplace();
    g.column("time", s.time);
    for (std::size_t k = 0;; ++k) {
      const std::string name = "damper" + std::to_string(k);
      if (!has_link(group, name, file)) break;
      Handle damper(H5Gopen2(group, name.c_str(), H5P_DEFAULT), H5Gclose, file, "open " + name);
      const std::string path = "/particles/" + name;
      DamperSnapshots& d = s.dampers.emplace_back();
      d.shape = read_text_attribute(damper.get(), "shape", file, path);
      auto read = [&](const char* key, std::vector<double>& out, int rank) {
        read_column(damper.get(), path, key, H5T_NATIVE_DOUBLE, out, file, rank);
      };
      read("container_size", d.size, 1);
      if (has_link(damper.get(), "container_outline_points", file)) {
        read("container_outline_points", d.outline_points, 2);
        read_column(damper.get(), path, "container_outline_segments", H5T_NATIVE_INT32,
                    d.outline_segments, file, 2);
      }
      read("radius", d.radius, 1);
      read("position", d.position, 3);
      read("velocity", d.velocity, 3);
      read("spin", d.spin, 3);
      read_column(damper.get(), path, "contacts", H5T_NATIVE_INT32, d.contacts, file, 2);
      // Snapshots from a pdsim that did not count contacts (a resumed run): -1, not known.
      if (d.contacts.empty()) d.contacts.assign(d.position.size() / 3, -1);
      read("container_position", d.container_position, 2);
      read("container_axes", d.container_axes, 3);
    }
  });
  read_group(f, "/checkpoint", file, [&](hid_t group, const GroupReader&) {
    const int format = checkpoint_format(group, file);
    if (format != kCheckpointFormat)
      throw InputError(file + ": its checkpoint has format " + std::to_string(format) +
                       (format < kCheckpointFormat ? " (an older pdsim)" : " (a newer pdsim)") +
                       "; this pdsim reads format " + std::to_string(kCheckpointFormat) +
                       ": run anew without --resume (or delete the bed file)");
    for (const std::string& name : member_names(group, false, file, "list /checkpoint"))
      r.checkpoint[name] = read_state_array(group, name, file);
  });
  h5file.close(file);
  return r;
}

}  // namespace

FrfPeak frf_peak(const FrfTable& frf, const FillTable& fills) {
  FrfPeak peak;
  for (std::size_t i = 0; i < frf.frequency.size(); ++i) {
    const bool result = i < frf.result.size() ? frf.result[i] > 0 : frf.converged[i] != 0;
    if (!result || (peak.found && frf.amplitude[i] <= peak.amplitude)) continue;
    peak.found = true;
    peak.amplitude = frf.amplitude[i];
    peak.amplitude_ci = frf.amplitude_ci[i];
    peak.frequency = frf.frequency[i];
    peak.sweep = i < frf.sweep.size() ? frf.sweep[i] : 1;
  }
  for (std::size_t i = 0; i < frf.frequency.size(); ++i) {
    const bool result = i < frf.result.size() ? frf.result[i] > 0 : frf.converged[i] != 0;
    if (result || (peak.found && frf.amplitude[i] <= peak.amplitude) ||
        (peak.higher && frf.amplitude[i] <= peak.higher_amplitude))
      continue;
    peak.higher = true;
    peak.higher_amplitude = frf.amplitude[i];
    peak.higher_amplitude_ci = frf.amplitude_ci[i];
    peak.higher_frequency = frf.frequency[i];
    peak.higher_sweep = i < frf.sweep.size() ? frf.sweep[i] : 1;
  }
  // The highest single fill at a result point; a file without fills: the highest mean.
  peak.upper = peak.amplitude;
  for (std::size_t k = 0; k < fills.frequency.size(); ++k)
    for (std::size_t i = 0; i < frf.frequency.size(); ++i)
      if (frf.frequency[i] == fills.frequency[k] && frf.sweep[i] == fills.sweep[k] &&
          frf.result[i] > 0)
        peak.upper = std::max(peak.upper, fills.amplitude[k]);
  return peak;
}

bool output_locked(const std::string& path) {
  const std::string file = path + ".lock";
  const int fd = open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool held = flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  close(fd);
  return held;
}

OutputLock::OutputLock(const std::string& path) : file_(path + ".lock") {
  // Locked, and still the file at that name: a lock taken on a file that the previous holder
  // removed meanwhile protects nothing, so try again on the new one.
  for (int attempt = 0; attempt < 100; ++attempt) {
    fd_ = open(file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) fail_io(file_, "create the lock file (is the folder writable?)", errno);
    if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      close(fd_);
      if (error == EWOULDBLOCK)
        throw std::runtime_error(path + ": another pdsim is writing this output (it holds " +
                                 file_ + "); wait for it, or write elsewhere with -o");
      fail_io(file_, "lock", error);
    }
    struct stat held {
    }, named{};
    if (fstat(fd_, &held) == 0 && stat(file_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
        held.st_dev == named.st_dev) {
      // The pid is a courtesy to whoever looks; the lock is what counts.
      const std::string pid = std::to_string(getpid()) + "\n";
      [[maybe_unused]] const bool noted =
          ftruncate(fd_, 0) == 0 && write(fd_, pid.data(), pid.size()) > 0;
      return;
    }
    close(fd_);
  }
  throw std::runtime_error(file_ + ": cannot take the lock (the file keeps changing)");
}

OutputLock::~OutputLock() {
  unlink(file_.c_str());  // before unlocking, so that no one locks a file about to vanish
  close(fd_);
}

Results read_results(const std::string& path) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  return read_file(path);
}

void append_rows(MapTable& to, const MapTable& from) {
  map_columns(to, [&](const char* name, auto& into, const char*, const char*) {
    map_columns(from, [&](const char* other, const auto& rows, const char*, const char*) {
      if constexpr (std::is_same_v<std::decay_t<decltype(into)>, std::decay_t<decltype(rows)>>)
        if (std::string(name) == other) into.insert(into.end(), rows.begin(), rows.end());
    });
  });
}

}  // namespace pdsim

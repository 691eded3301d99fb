#include "io/results.hpp"

#include <doctest/doctest.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace fs = std::filesystem;
using pdsim::Results;

namespace {

// A fresh directory per test case and process, so parallel ctest runs do not collide.
fs::path scratch_dir(const std::string& test_name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("pdsim_results_test_" + test_name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Longer than the 64 KiB an attribute can hold in an object header, multi-line, non-ASCII.
std::string long_deck_text() {
  std::string deck = "# Saeki (2002) damper, 250 particles\n[structure]\nmass = 2.37  # kg\n";
  for (int i = 0; deck.size() < 100000; ++i) {
    deck += "[[note]]\ntext = \"line " + std::to_string(i) + ": \\u03b6 = 0.01, \xce\xbc = 0.3\"\n";
  }
  return deck + "\ttab and \"quotes\" at the end";
}

// Values whose decimal or single-precision storage would not survive bit-exact.
std::vector<double> awkward(double scale) {
  return {scale / 3.0,
          -scale * 0.1,
          scale * 1e-310,
          scale * 1.7976931348623157e308,
          std::numeric_limits<double>::infinity(),
          -0.0};
}

Results full_results() {
  Results r;
  r.meta_text = {{"deck", long_deck_text()},
                 {"version", "0.1.0-g1234567-dirty"},
                 {"backend", "cpu"},
                 {"title", "Saeki 250 particles"},
                 {"warning", ""}};  // an empty text
  r.meta_numbers = {{"threads", 2},
                    {"dt", 2.0 / 3.0 * 1e-6},
                    {"wall_time_s", 12.345678901234567},
                    {"particle_steps", 1.25e9}};
  // Every column of every table, each with its own awkward values (ints: the extremes).
  double seed = 1;
  auto fill = [&](const char*, auto& column, const char*, const char*) {
    using T = typename std::decay_t<decltype(column)>::value_type;
    if constexpr (std::is_same_v<T, int>)
      column = {40, 2147483647, -2147483647 - 1};
    else
      column = awkward(seed++);
  };
  pdsim::timeseries_columns(r.timeseries, fill);
  pdsim::frf_columns(r.frf, fill);
  pdsim::prescribed_columns(r.prescribed, fill);
  pdsim::period_columns(r.periods, fill);
  pdsim::energy_columns(r.energy.emplace(), fill);
  // Two snapshots of a 2-particle box and a 1-particle cylinder.
  pdsim::ParticleSnapshots& s = r.particles.emplace();
  s.time = {0.5, 0.75};
  for (const char* shape : {"box", "cylinder"}) {
    pdsim::DamperSnapshots& d = s.dampers.emplace_back();
    const std::size_t n = s.dampers.size() == 1 ? 2 : 1;
    d.shape = shape;
    d.size = {0.02, 0.03, 0.04};
    d.radius = std::vector<double>(n, 0.002);
    for (auto* v : {&d.position, &d.velocity, &d.spin}) *v = awkward(double(v->size() + 7 * n));
    for (auto* v : {&d.position, &d.velocity, &d.spin}) v->resize(2 * n * 3, 0.25);
    for (std::size_t k = 0; k < 2 * n; ++k) d.contacts.push_back(static_cast<std::int32_t>(k) - 1);
    d.container_position = {0, 0, 0, 1e-3, 0, 0};
    d.container_axes = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 1, 0, 0, 0, 0, 1};
  }
  r.checkpoint = {{"structure_state", std::vector<double>{1e-3, -2e-4, 0.5}},
                  {"particle_positions", awkward(11)},
                  {"rng_state", std::vector<double>{}},
                  {"id", std::vector<std::int32_t>{0, -1, 2147483647}},
                  {"mask", std::vector<std::uint64_t>{0, 1, 0xffffffffffffffffu}},
                  {"wall_mask", std::vector<std::uint8_t>{0, 63, 255}}};
  return r;
}

// Column by column, through the same lists the writer and the reader walk.
template <class Table, class Columns>
void check_columns(const Table& a, const Table& b, Columns columns) {
  std::vector<std::string> names;
  std::vector<std::vector<double>> doubles;
  std::vector<std::vector<int>> ints;
  columns(a, [&](const char* name, const auto& column, const char*, const char*) {
    names.emplace_back(name);
    if constexpr (std::is_same_v<typename std::decay_t<decltype(column)>::value_type, int>)
      ints.push_back(column), doubles.emplace_back();
    else
      doubles.push_back(column), ints.emplace_back();
  });
  std::size_t k = 0;
  columns(b, [&](const char* name, const auto& column, const char*, const char*) {
    CAPTURE(name);
    if constexpr (std::is_same_v<typename std::decay_t<decltype(column)>::value_type, int>)
      CHECK(column == ints[k]);
    else
      CHECK(column == doubles[k]);
    ++k;
  });
  CHECK(k == names.size());
}

void check_equal(const Results& a, const Results& b) {
  CHECK(a.meta_text == b.meta_text);
  CHECK(a.meta_numbers == b.meta_numbers);
  check_columns(a.timeseries, b.timeseries,
                [](auto& t, auto&& f) { pdsim::timeseries_columns(t, f); });
  check_columns(a.frf, b.frf, [](auto& t, auto&& f) { pdsim::frf_columns(t, f); });
  check_columns(a.prescribed, b.prescribed,
                [](auto& t, auto&& f) { pdsim::prescribed_columns(t, f); });
  check_columns(a.periods, b.periods, [](auto& t, auto&& f) { pdsim::period_columns(t, f); });
  REQUIRE(a.energy.has_value() == b.energy.has_value());
  if (a.energy)
    check_columns(*a.energy, *b.energy, [](auto& t, auto&& f) { pdsim::energy_columns(t, f); });
  REQUIRE(a.particles.has_value() == b.particles.has_value());
  if (a.particles) {
    CHECK(a.particles->time == b.particles->time);
    REQUIRE(a.particles->dampers.size() == b.particles->dampers.size());
    for (std::size_t k = 0; k < a.particles->dampers.size(); ++k) {
      const pdsim::DamperSnapshots &x = a.particles->dampers[k], &y = b.particles->dampers[k];
      CHECK(x.shape == y.shape);
      CHECK(x.size == y.size);
      CHECK(x.radius == y.radius);
      CHECK(x.position == y.position);
      CHECK(x.velocity == y.velocity);
      CHECK(x.spin == y.spin);
      CHECK(x.contacts == y.contacts);
      CHECK(x.container_position == y.container_position);
      CHECK(x.container_axes == y.container_axes);
    }
  }
  CHECK(a.checkpoint == b.checkpoint);
}

// Runs h5dump (hdf5-tools) and returns its output, or nothing when it exits non-zero.
std::optional<std::string> h5dump(const std::string& arguments, const fs::path& dir) {
  const fs::path out = dir / "h5dump.txt";
  const std::string command = "h5dump " + arguments + " > '" + out.string() + "' 2>&1";
  if (std::system(command.c_str()) != 0) return std::nullopt;
  std::ifstream in(out);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

TEST_CASE("results: every field round-trips bit-exactly, including checkpoint and a long deck") {
  const fs::path dir = scratch_dir("roundtrip");
  const std::string path = (dir / "run.h5").string();
  const Results written = full_results();
  REQUIRE(written.meta_text.at("deck").size() > 65536);
  pdsim::write_results(path, written, true);
  check_equal(pdsim::read_results(path), written);
  fs::remove_all(dir);
}

TEST_CASE("results: groups with no data are not written and read back empty") {
  const fs::path dir = scratch_dir("empty_groups");
  const std::string path = (dir / "run.h5").string();
  Results written;
  written.meta_text["deck"] = "[run]\n";
  written.timeseries.displacement = {1.0};  // no time: the group is skipped
  pdsim::write_results(path, written, true);
  const Results read = pdsim::read_results(path);
  CHECK(read.meta_text == written.meta_text);
  CHECK(read.meta_numbers.empty());  // `complete` is a file property, not a Results entry
  CHECK(read.timeseries.displacement.empty());
  CHECK(read.frf.frequency.empty());
  CHECK(read.prescribed.frequency.empty());
  CHECK_FALSE(read.energy.has_value());
  CHECK(read.checkpoint.empty());
  fs::remove_all(dir);
}

// Every dataset under `location`, walked through the HDF5 links: those without a units attribute.
std::vector<std::string> datasets_without_units(hid_t location, std::size_t* datasets) {
  struct Walk {
    std::vector<std::string> missing;
    std::size_t datasets = 0;
  } walk;
  auto visit = [](hid_t group, const char* name, const H5L_info_t*, void* data) -> herr_t {
    Walk& w = *static_cast<Walk*>(data);
    const hid_t object = H5Oopen(group, name, H5P_DEFAULT);
    if (object < 0) return -1;
    if (H5Iget_type(object) == H5I_DATASET) {
      ++w.datasets;
      if (H5Aexists(object, "units") <= 0) w.missing.push_back(name);
    }
    H5Oclose(object);
    return 0;
  };
  H5Lvisit(location, H5_INDEX_NAME, H5_ITER_INC, visit, &walk);
  *datasets = walk.datasets;
  return walk.missing;
}

TEST_CASE("results: every dataset of a file, checkpoint included, has a units attribute") {
  const fs::path dir = scratch_dir("units");
  const fs::path path = dir / "run.h5";
  pdsim::write_results(path.string(), full_results(), false);  // the .partial, with checkpoint
  const hid_t file = H5Fopen((dir / "run.h5.partial").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  REQUIRE(file >= 0);
  std::size_t datasets = 0;
  const std::vector<std::string> missing = datasets_without_units(file, &datasets);
  H5Fclose(file);
  CHECK(datasets >= 50);  // the walk saw the tables and the checkpoint
  for (const std::string& name : missing) CHECK_MESSAGE(false, name << " has no units");
  // Negative control: a dataset written without units is found.
  const hid_t bare = H5Fcreate((dir / "bare.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  const hsize_t one = 1;
  const hid_t space = H5Screate_simple(1, &one, nullptr);
  const hid_t group = H5Gcreate2(bare, "g", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const hid_t dataset =
      H5Dcreate2(group, "x", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  H5Dclose(dataset);
  H5Gclose(group);
  H5Sclose(space);
  CHECK(datasets_without_units(bare, &datasets) == std::vector<std::string>{"g/x"});
  H5Fclose(bare);
  fs::remove_all(dir);
}

TEST_CASE("results: a checkpoint of another format is refused, naming the file and the formats") {
  const fs::path dir = scratch_dir("format");
  const fs::path path = dir / "run.h5";
  const fs::path partial = dir / "run.h5.partial";
  pdsim::write_results(path.string(), full_results(), false);
  // What a pdsim before typed checkpoints wrote: no format attribute.
  const hid_t file = H5Fopen(partial.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  REQUIRE(file >= 0);
  const hid_t group = H5Gopen2(file, "/checkpoint", H5P_DEFAULT);
  REQUIRE(group >= 0);
  CHECK(H5Adelete(group, "format") >= 0);
  H5Gclose(group);
  H5Fclose(file);
  const std::string expected = partial.string() +
                               ": its checkpoint has format 1 (an older pdsim); this pdsim reads "
                               "format " +
                               std::to_string(pdsim::kCheckpointFormat) +
                               ": run anew without --resume";
  CHECK_THROWS_WITH_AS(pdsim::read_results(partial.string()), doctest::Contains(expected.c_str()),
                       pdsim::InputError);
  fs::remove_all(dir);
}

TEST_CASE("results: an incomplete write leaves only the .partial file, a complete one only path") {
  const fs::path dir = scratch_dir("atomic");
  const fs::path path = dir / "run.h5";
  const fs::path partial = dir / "run.h5.partial";
  Results results = full_results();

  pdsim::write_results(path.string(), results, false);
  CHECK(fs::exists(partial));
  CHECK_FALSE(fs::exists(path));
  // A resumed run continues from what the .partial file holds.
  check_equal(pdsim::read_results(partial.string()), results);

  // Rewriting the partial truncates it: a checkpoint array dropped since is gone.
  results.checkpoint.erase("particle_positions");
  pdsim::write_results(path.string(), results, false);
  CHECK(pdsim::read_results(partial.string()).checkpoint == results.checkpoint);
  CHECK_FALSE(fs::exists(path));

  results.checkpoint.clear();
  pdsim::write_results(path.string(), results, true);
  CHECK(fs::exists(path));
  CHECK_FALSE(fs::exists(partial));
  check_equal(pdsim::read_results(path.string()), results);
  fs::remove_all(dir);
}

TEST_CASE("results: failures throw with the path in the message") {
  const fs::path dir = scratch_dir("errors");
  const std::string missing_dir = (dir / "no_such_dir" / "run.h5").string();
  CHECK_THROWS_WITH_AS(pdsim::write_results(missing_dir, full_results(), true),
                       doctest::Contains(missing_dir.c_str()), std::runtime_error);
  CHECK_FALSE(fs::exists(missing_dir));

  const std::string missing_file = (dir / "absent.h5").string();
  CHECK_THROWS_WITH_AS(pdsim::read_results(missing_file), doctest::Contains(missing_file.c_str()),
                       std::runtime_error);

  const std::string not_hdf5 = (dir / "text.h5").string();
  std::ofstream(not_hdf5) << "not an HDF5 file\n";
  CHECK_THROWS_WITH_AS(pdsim::read_results(not_hdf5), doctest::Contains(not_hdf5.c_str()),
                       std::runtime_error);

  // Two attributes with one name cannot both exist in /meta.
  Results clash;
  clash.meta_text["dt"] = "1e-6";
  clash.meta_numbers["dt"] = 1e-6;
  const std::string clash_path = (dir / "clash.h5").string();
  CHECK_THROWS_WITH_AS(pdsim::write_results(clash_path, clash, true), doctest::Contains("/meta/dt"),
                       std::runtime_error);
  CHECK_FALSE(fs::exists(clash_path));
  fs::remove_all(dir);
}

TEST_CASE("results: h5dump finds the object names of the output contract (io/output.md)") {
  if (std::system("command -v h5dump > /dev/null 2>&1") != 0) {
    MESSAGE("h5dump (Debian hdf5-tools) is not on PATH: contract check skipped");
    return;
  }
  const fs::path dir = scratch_dir("h5dump");
  const std::string path = (dir / "run.h5").string();
  pdsim::write_results(path, full_results(), true);

  const char* datasets[] = {"/timeseries/time",
                            "/timeseries/displacement",
                            "/timeseries/velocity",
                            "/timeseries/damper_force",
                            "/frf/frequency",
                            "/frf/amplitude",
                            "/frf/amplitude_ci",
                            "/frf/phase",
                            "/frf/phase_ci",
                            "/frf/periods_discarded",
                            "/frf/rms",
                            "/frf/peak",
                            "/frf/periods",
                            "/frf/converged",
                            "/frf/dissipated_energy",
                            "/frf/dissipated_normal",
                            "/frf/dissipated_tangential",
                            "/frf/dissipated_rolling",
                            "/prescribed/frequency",
                            "/prescribed/dissipated_power",
                            "/prescribed/force_amplitude",
                            "/prescribed/force_phase",
                            "/energy/time",
                            "/energy/work_in",
                            "/energy/dissipated_structure",
                            "/energy/dissipated_normal",
                            "/energy/dissipated_tangential",
                            "/energy/dissipated_rolling",
                            "/energy/kinetic",
                            "/energy/potential",
                            "/energy/imbalance",
                            "/checkpoint/structure_state"};
  for (const char* dataset : datasets) {
    CAPTURE(dataset);
    const auto header = h5dump("-H -d " + std::string(dataset) + " '" + path + "'", dir);
    CHECK(header.has_value());
    // Every dataset of the contract carries its units (checkpoint arrays are restart data).
    if (std::string(dataset).rfind("/checkpoint", 0) != 0)
      CHECK(h5dump("-a " + std::string(dataset) + "/units '" + path + "'", dir).has_value());
  }
  const auto units = h5dump("-a /frf/amplitude/units '" + path + "'", dir);
  REQUIRE(units.has_value());
  CHECK(units->find("\"m\"") != std::string::npos);
  for (const char* attribute : {"deck", "version", "backend", "threads", "dt", "wall_time_s",
                                "particle_steps", "complete"}) {
    CAPTURE(attribute);
    CHECK(h5dump("-H -a /meta/" + std::string(attribute) + " '" + path + "'", dir).has_value());
  }
  // Negative control: h5dump must fail on a name that is not there.
  CHECK_FALSE(h5dump("-H -d /frf/no_such_dataset '" + path + "'", dir).has_value());

  const auto periods = h5dump("-H -d /frf/periods '" + path + "'", dir);
  REQUIRE(periods.has_value());
  CHECK(periods->find("H5T_STD_I32LE") != std::string::npos);
  CHECK(periods->find("( 3 )") != std::string::npos);
  const auto amplitude = h5dump("-H -d /frf/amplitude '" + path + "'", dir);
  REQUIRE(amplitude.has_value());
  CHECK(amplitude->find("H5T_IEEE_F64LE") != std::string::npos);
  const auto complete = h5dump("-a /meta/complete '" + path + "'", dir);
  REQUIRE(complete.has_value());
  CHECK(complete->find("(0): 1") != std::string::npos);
  const auto version = h5dump("-a /meta/version '" + path + "'", dir);
  REQUIRE(version.has_value());
  CHECK(version->find("\"0.1.0-g1234567-dirty\"") != std::string::npos);
  fs::remove_all(dir);
}

// The headline over the result points, and beside it the highest mean where a point is not a
// result when it is higher (the hard part must not hide): three points, the middle one the
// highest and not a result.
TEST_CASE("frf_peak: the peak over result points and the higher point that is not a result") {
  pdsim::FrfTable frf;
  frf.frequency = {14.0, 15.0, 16.0};
  frf.amplitude = {1e-3, 3e-3, 2e-3};
  frf.amplitude_ci = {1e-5, 5e-4, 2e-4};
  frf.result = {1, 0, 2};
  frf.converged = {1, 0, 1};
  frf.sweep = {1, 1, 1};
  pdsim::FillTable fills;
  fills.frequency = {16.0, 16.0, 15.0};
  fills.sweep = {1, 1, 1};
  fills.amplitude = {1.5e-3, 2.5e-3, 4e-3};
  const pdsim::FrfPeak peak = pdsim::frf_peak(frf, fills);
  REQUIRE(peak.found);
  CHECK(peak.amplitude == 2e-3);
  CHECK(peak.frequency == 16.0);
  CHECK(peak.upper == 2.5e-3);  // the fill at 15 Hz is at a point that is not a result
  REQUIRE(peak.higher);
  CHECK(peak.higher_amplitude == 3e-3);
  CHECK(peak.higher_amplitude_ci == 5e-4);
  CHECK(peak.higher_frequency == 15.0);
  // Below the peak, a point that is not a result is no headline.
  frf.amplitude[1] = 1.5e-3;
  CHECK_FALSE(pdsim::frf_peak(frf, fills).higher);
  // Without results, the highest mean is still said.
  frf.result = {0, 0, 0};
  const pdsim::FrfPeak none = pdsim::frf_peak(frf, fills);
  CHECK_FALSE(none.found);
  REQUIRE(none.higher);
  CHECK(none.higher_frequency == 16.0);
}

TEST_CASE(
    "results: io/output.md's /meta table names exactly the declared attributes, typed alike") {
  std::ifstream doc(std::string(PDSIM_TEST_DIR) + "/../io/output.md");
  REQUIRE(doc.good());
  std::string line;
  bool in_section = false;
  std::vector<std::pair<std::string, bool>> rows;  // (name, text)
  while (std::getline(doc, line)) {
    if (line.rfind("## ", 0) == 0) in_section = line == "## `/meta` attributes";
    // Table rows: | `name` | text or number | units | meaning |
    if (!in_section || line.rfind("| `", 0) != 0) continue;
    const auto close = line.find('`', 3);
    const std::string name = line.substr(3, close - 3);
    const auto type_at = line.find("| ", close) + 2;
    rows.emplace_back(name, line.compare(type_at, 4, "text") == 0);
  }
  std::vector<std::pair<std::string, bool>> declared;
  for (const pdsim::MetaAttribute& a : pdsim::kMetaAttributes)
    declared.emplace_back(a.name, a.text);
  std::sort(rows.begin(), rows.end());
  std::sort(declared.begin(), declared.end());
  for (const auto& row : rows)
    if (!std::binary_search(declared.begin(), declared.end(), row))
      MESSAGE("in io/output.md, not declared so: " << row.first);
  for (const auto& d : declared)
    if (!std::binary_search(rows.begin(), rows.end(), d))
      MESSAGE("declared, not in io/output.md so: " << d.first);
  CHECK(rows == declared);
}

TEST_CASE("results: a /meta attribute that is not declared is refused, nothing written") {
  const fs::path dir = scratch_dir("undeclared_meta");
  Results r;
  r.meta_numbers["wall_time"] = 1.0;  // declared as wall_time_s
  const std::string path = (dir / "run.h5").string();
  CHECK_THROWS_WITH_AS(pdsim::write_results(path, r, true), doctest::Contains("/meta/wall_time"),
                       std::runtime_error);
  CHECK_FALSE(fs::exists(path));
  fs::remove_all(dir);
}

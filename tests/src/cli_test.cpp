// The pdsim executable as a user meets it: exit codes, nothing written for bad input, no silent
// overwrite, and an interrupted stepped sine resumed to the same numbers.
#include <doctest/doctest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "io/results.hpp"
#include "src/format.hpp"  // number(), as the log writes frequencies
#include "src/run.hpp"
#include "tests/support/stl_files.hpp"

namespace fs = std::filesystem;

namespace {

struct Sandbox {
  fs::path dir;
  Sandbox() {
    dir = fs::temp_directory_path() /
          ("pdsim_cli_" + std::to_string(::getpid()) + "_" + std::to_string(counter()++));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Sandbox() { fs::remove_all(dir); }
  static int& counter() {
    static int n = 0;
    return n;
  }
  // Runs a shell command in the sandbox; returns its exit code (-1 if it did not exit), its
  // output in `log`.
  int shell(const std::string& script, std::string* log = nullptr) const {
    const fs::path out = dir / "log.txt";
    const std::string command =
        "cd '" + dir.string() + "' && (" + script + ") > '" + out.string() + "' 2>&1";
    const int status = std::system(command.c_str());
    if (log) {
      std::ifstream in(out);
      std::stringstream s;
      s << in.rdbuf();
      *log = s.str();
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  // Runs pdsim with `args` in the sandbox.
  int pdsim(const std::string& args, std::string* log = nullptr) const {
    return shell("'" + std::string(PDSIM_BINARY) + "' " + args, log);
  }
  std::size_t files() const {
    std::size_t n = 0;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().filename() != "log.txt") ++n;
    return n;
  }
};

// A bare SDOF at 15 Hz under 1 N, its mass swept over three values (the sweep tests' deck).
const char* kMassSweep =
    "[structure]\nkind = \"sdof\"\nmass = 1.0\nstiffness = 10000.0\n"
    "damping_ratio = 0.2\n[excitation]\nkind = \"stepped_sine\"\n"
    "amplitude = 1.0\nfrequencies = [15.0]\n"
    "settle = { min_periods = 10, max_periods = 400, tolerance = 1e-5 }\n"
    "[output]\nfile = \"m.h5\"\n[sweep]\n\"structure.mass\" = [0.5, 1.0, 2.0]\n";

std::string deck(const std::string& name) {
  return std::string(PDSIM_TEST_DIR) + "/decks/" + name;
}

// A prescribed shake of 20 spheres in the STL cavity `stl`.
std::string mesh_deck(const std::string& stl) {
  return "[[damper]]\ncontainer = { shape = \"mesh\", file = \"" + stl +
         "\", scale = 0.001 }\nparticles = { count = 20, diameter = 0.004, density = 7800.0 }\n"
         "[contact]\nmodel = \"linear\"\nstiffness = 2000.0\nrestitution = 0.5\n"
         "tangential = \"none\"\n[excitation]\nkind = \"prescribed\"\n"
         "motion = { axis = [1.0, 0.0, 0.0], amplitude = 0.002, frequency = 20.0 }\n"
         "duration = 0.05\n[output]\nfile = \"mesh.h5\"\n";
}

}  // namespace

TEST_CASE("mesh containers: check reports the cavity, bad meshes exit 1 naming the key and file") {
  using namespace pdsim::stl_files;
  Sandbox box;
  const std::string deck_path = scratch("mesh.toml");
  auto run_with = [&](const std::string& stl, const char* command, std::string* log) {
    std::ofstream(deck_path) << mesh_deck(stl);
    return box.pdsim(std::string(command) + " '" + deck_path + "'", log);
  };
  // A 30 mm cube in mm: 27 cm^3, 12 triangles, 6 surfaces.
  std::string log;
  REQUIRE(run_with(binary(pdsim::stl_files::box(30, 30, 30), "cube.stl"), "check", &log) == 0);
  CHECK(log.find("12 triangles, 6 surfaces") != std::string::npos);
  CHECK(log.find("volume 2.7e-05 m^3") != std::string::npos);
  CHECK(log.find("fill fraction 0.0248") != std::string::npos);  // 20 x 33.5 mm^3 / 27 cm^3
  CHECK(log.find("deck OK") != std::string::npos);
  std::vector<Triangle> open = pdsim::stl_files::box(30, 30, 30);
  open.pop_back();
  std::vector<Triangle> flipped = pdsim::stl_files::box(30, 30, 30);
  std::swap(flipped[4][1], flipped[4][2]);
  std::vector<Triangle> nan = pdsim::stl_files::box(30, 30, 30);
  nan[0][0].x = std::numeric_limits<double>::quiet_NaN();
  std::vector<Triangle> nested = pdsim::stl_files::box(30, 30, 30);
  for (const Triangle& t : pdsim::stl_files::box(10, 10, 10, {10, 10, 10})) nested.push_back(t);
  std::ofstream(scratch("empty.stl"));
  const std::pair<std::string, std::string> bad[] = {
      {ascii(open, "open.stl"), "not closed"},
      {ascii(nested, "nested.stl"), "2 separate closed surfaces"},
      {ascii(flipped, "flipped.stl"), "not consistently oriented"},
      {binary(nan, "nan.stl"), "not a number"},
      {scratch("empty.stl").string(), "empty (0 bytes)"}};
  for (const auto& [stl, why] : bad) {
    CAPTURE(stl);
    for (const char* command : {"check", "run"}) {
      CHECK(run_with(stl, command, &log) == 1);
      CHECK(log.find("mesh.toml:2:") != std::string::npos);
      CHECK(log.find("container.file") != std::string::npos);
      CHECK(log.find(stl) != std::string::npos);
      CHECK(log.find(why) != std::string::npos);
      CHECK(box.files() == 0);
    }
  }
  fs::remove_all(fs::path(deck_path).parent_path());
}

TEST_CASE("bad decks exit 1 with the position, and write nothing") {
  Sandbox box;
  for (const char* name :
       {"bad_negative_mass.toml", "bad_misspelt_key.toml", "bad_syntax.toml",
        "bad_dt_above_limit.toml", "bad_particles_do_not_fit.toml", "bad_nonsmooth_stiffness.toml",
        "bad_nonsmooth_tolerance.toml", "bad_nonsmooth_iterations.toml", "bad_nonsmooth_dt.toml"}) {
    std::string log;
    CAPTURE(name);
    CHECK(box.pdsim("run '" + deck(name) + "'", &log) == 1);
    CHECK(log.find(std::string(name) + ":") != std::string::npos);
    CHECK(box.files() == 0);
  }
  std::string log;
  CHECK(box.pdsim("run missing.toml", &log) == 1);
  // Command-line mistakes are bad input too: exit 1 with a plain message (CLI11 said 105/106).
  CHECK(box.pdsim("run", &log) == 1);
  CHECK(box.pdsim("", &log) == 1);
  CHECK(log.find("A subcommand is required") != std::string::npos);
  CHECK(box.pdsim("run --threads 0 missing.toml", &log) == 1);
  CHECK(log.find("--threads: Value 0 not in range 1 to 4096") != std::string::npos);
  CHECK(box.pdsim("--version", &log) == 0);
}

TEST_CASE("a run writes its file with provenance and refuses to overwrite it") {
  Sandbox box;
  std::string log;
  REQUIRE(box.pdsim("run --quiet '" + deck("tiny_stepped_sine.toml") + "'", &log) == 0);
  CHECK(log.find("wrote tiny.h5") != std::string::npos);
  CHECK(fs::exists(box.dir / "tiny.h5"));
  CHECK_FALSE(fs::exists(box.dir / "tiny.h5.partial"));
  const pdsim::Results r = pdsim::read_results((box.dir / "tiny.h5").string());
  CHECK(r.meta_text.at("deck").find("tiny stepped sine") != std::string::npos);
  CHECK(r.meta_text.at("backend").find("cpu") == 0);
  CHECK(r.meta_numbers.at("dt") > 0);
  CHECK(r.meta_numbers.at("wall_time_s") > 0);
  CHECK(r.meta_numbers.at("particle_steps") > 0);
  CHECK(r.frf.frequency.size() == 2);
  CHECK(box.pdsim("run --quiet '" + deck("tiny_stepped_sine.toml") + "'", &log) == 1);
  CHECK(log.find("--force") != std::string::npos);
  CHECK(box.pdsim("run --quiet --force '" + deck("tiny_stepped_sine.toml") + "'") == 0);
}

TEST_CASE("run --snapshots writes the particles of one continuous run, or says why it cannot") {
  Sandbox box;
  std::string log;
  // The tiny stepped sine has a random fill and no realisations key: two realisations by
  // default, one with snapshots (they follow one continuous run).
  REQUIRE(box.pdsim("run --quiet --snapshots 0.02 -o s.h5 '" + deck("tiny_stepped_sine.toml") + "'",
                    &log) == 0);
  const pdsim::Results r = pdsim::read_results((box.dir / "s.h5").string());
  REQUIRE(r.particles);
  REQUIRE(r.particles->time.size() >= 2);
  // Each snapshot is taken at the first step at or after its time: within a step (13 us here).
  CHECK(r.particles->time[1] - r.particles->time[0] == doctest::Approx(0.02).epsilon(0.01));
  CHECK(r.particles->dampers.at(0).radius.size() == 20);
  CHECK(fs::exists(box.dir / "s.xdmf"));
  CHECK(r.meta_text.at("deck").find("--snapshots 0.02") != std::string::npos);
  // Two realisations asked for explicitly: refused before any step, naming the key.
  REQUIRE(box.shell("sed 's/batches = 2 }/batches = 2, realisations = 2 }/' '" +
                    deck("tiny_stepped_sine.toml") + "' > two.toml") == 0);
  CHECK(box.pdsim("run --quiet --snapshots 0.02 -o t.h5 two.toml", &log) == 1);
  CHECK(log.find("two.toml") != std::string::npos);
  CHECK(log.find("'output.particles': not with settle.realisations > 1") != std::string::npos);
  CHECK(log.find("set by pdsim run --snapshots") != std::string::npos);
  CHECK_FALSE(fs::exists(box.dir / "t.h5"));
  CHECK(box.pdsim("run --quiet --snapshots 0 two.toml", &log) == 1);
}

TEST_CASE("a fixed-duration run reports its means with an interval and claims no steady state") {
  // A softened shaken box of 60 spheres, 5 periods, the last 4 averaged: too few for the
  // steady-state test's 4 batches of at least 5 periods, which once gave "+- inf" and
  // "NOT converged: not results" for a run that asked for no steady state.
  Sandbox box;
  std::ofstream(box.dir / "box.toml") << R"([[damper]]
container = { shape = "box", size = [0.04, 0.04, 0.04] }
particles = { count = 60, diameter = 0.005, density = 7800.0, fill = "random", seed = 2 }
[contact]
model = "hertz"
young = 2.0e9
poisson = 0.3
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "prescribed"
motion = { axis = [1.0, 0.0, 0.0], amplitude = 0.004, frequency = 20.0 }
duration = 0.25
settle = { average_periods = 4, realisations = 1 }
[output]
file = "box.h5"
)";
  std::string log;
  REQUIRE(box.pdsim("run box.toml", &log) == 0);
  CAPTURE(log);
  CHECK(log.find("1 frequency, 0.25 s each; power ") != std::string::npos);
  CHECK(log.find("fixed duration") != std::string::npos);
  CHECK(log.find("NOT converged") == std::string::npos);
  CHECK(log.find("inf") == std::string::npos);
  const pdsim::Results r = pdsim::read_results((box.dir / "box.h5").string());
  REQUIRE(r.prescribed.frequency.size() == 1);
  CHECK(std::isfinite(r.prescribed.dissipated_power_ci[0]));
  CHECK(r.prescribed.dissipated_power_ci[0] > 0);
  CHECK(r.prescribed.dissipated_power[0] > 0);
}

TEST_CASE("a stepped sine stopped after one frequency and resumed gives the same results") {
  for (const char* name : {"tiny_stepped_sine.toml", "tiny_rigid_stepped_sine.toml"}) {
    CAPTURE(name);
    Sandbox box;
    const std::string tiny = "'" + deck(name) + "'";
    REQUIRE(box.pdsim("run --quiet --threads 1 -o whole.h5 " + tiny) == 0);
    std::string log;
    REQUIRE(box.pdsim("run --quiet --threads 2 -o split.h5 --stop-after 1 " + tiny, &log) == 0);
    CHECK(fs::exists(box.dir / "split.h5.partial"));
    CHECK_FALSE(fs::exists(box.dir / "split.h5"));
    CHECK(box.pdsim("run --quiet -o other.h5 --resume " + tiny, &log) == 1);  // nothing to resume
    REQUIRE(box.pdsim("run --quiet --threads 2 -o split.h5 --resume " + tiny, &log) == 0);
    const pdsim::Results a = pdsim::read_results((box.dir / "whole.h5").string());
    const pdsim::Results b = pdsim::read_results((box.dir / "split.h5").string());
    // Bitwise: the checkpoint restores every array the next steps read, thread count aside.
    CHECK(a.frf.amplitude == b.frf.amplitude);
    CHECK(a.frf.phase == b.frf.phase);
    CHECK(a.frf.dissipated_energy == b.frf.dissipated_energy);
    CHECK(a.timeseries.displacement == b.timeseries.displacement);
    CHECK(a.meta_numbers.at("particle_steps") == b.meta_numbers.at("particle_steps"));
  }
}

// A change to the deck that can alter finished points is refused by name; a new title, thread
// count or layout resumes (io/decks.md).
TEST_CASE("--resume after editing the deck: refused naming the key, unless it cannot matter") {
  Sandbox box;
  std::string text;
  {
    std::ifstream in(deck("tiny_stepped_sine.toml"));
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const fs::path path = box.dir / "edited.toml";
  std::ofstream(path) << text;
  REQUIRE(box.pdsim("run --quiet --threads 1 -o e.h5 --stop-after 1 edited.toml") == 0);
  std::string edited = text;
  edited.replace(edited.find("restitution = 0.5"), 17, "restitution = 0.55");
  edited.replace(edited.find("count = 20"), 10, "count = 21");
  std::ofstream(path) << edited;
  std::string log;
  CHECK(box.pdsim("run --quiet -o e.h5 --resume edited.toml", &log) == 1);
  CHECK(log.find("the deck changed since the interrupted run (contact.restitution: 0.5 then, 0.55 "
                 "now; damper[0].particles.count: 20 then, 21 now)") != std::string::npos);
  edited = "# a comment\n" + text;
  edited.replace(edited.find("tiny stepped sine"), 17, "tiny stepped sine, renamed");
  edited += "[solver]\nthreads = 2\n";
  std::ofstream(path) << edited;
  REQUIRE(box.pdsim("run --quiet -o e.h5 --resume edited.toml", &log) == 0);
  const pdsim::Results r = pdsim::read_results((box.dir / "e.h5").string());
  CHECK(r.frf.frequency == std::vector<double>{15.0, 16.0});
  CHECK(r.meta_text.at("title") == "tiny stepped sine, renamed");
}

TEST_CASE("independent frequencies stopped and resumed keep every point and time series") {
  Sandbox box;
  const fs::path path = box.dir / "independent.toml";
  std::ifstream tiny(deck("tiny_stepped_sine.toml"));
  std::stringstream text;
  text << tiny.rdbuf();
  std::string deck_text = text.str();
  deck_text.replace(deck_text.find("frequencies = [15.0, 16.0]"), 26,
                    "frequencies = [15.0, 16.0, 17.0]\nstart = \"independent\"");
  std::ofstream(path) << deck_text;
  REQUIRE(box.pdsim("run --quiet --jobs 1 -o whole.h5 independent.toml") == 0);
  // Two realisations (the random fill's default) of the first frequency, then a stop.
  REQUIRE(box.pdsim("run --quiet --jobs 1 -o split.h5 --stop-after 1 independent.toml") == 0);
  // The finished frequency is readable in the checkpoint file.
  CHECK(pdsim::read_results((box.dir / "split.h5.partial").string()).frf.frequency.size() == 1);
  REQUIRE(box.pdsim("run --quiet --jobs 2 -o split.h5 --resume independent.toml") == 0);
  const pdsim::Results a = pdsim::read_results((box.dir / "whole.h5").string());
  const pdsim::Results b = pdsim::read_results((box.dir / "split.h5").string());
  CHECK(a.meta_text.at("start") == "independent");
  // Two fills start each point; a fill too short for an interval that moved little counts
  // (the cap rule), so a point may ask for more: the same in both runs.
  CHECK(a.frf.realisations == b.frf.realisations);
  for (int fills : a.frf.realisations) CHECK(fills >= 2);
  CHECK(a.frf.frequency == std::vector<double>{15.0, 16.0, 17.0});
  CHECK(a.frf.amplitude == b.frf.amplitude);
  CHECK(a.timeseries.time == b.timeseries.time);
  CHECK(a.timeseries.frequency == b.timeseries.frequency);
  CHECK(a.timeseries.displacement == b.timeseries.displacement);
}

TEST_CASE("check passes on every example deck and every good test deck") {
  Sandbox box;
  std::vector<fs::path> decks;
  for (const auto& entry : fs::directory_iterator(std::string(PDSIM_TEST_DIR) + "/../examples"))
    if (entry.path().extension() == ".toml") decks.push_back(entry.path());  // not their STLs
  for (const auto& entry : fs::directory_iterator(std::string(PDSIM_TEST_DIR) + "/decks"))
    if (entry.path().filename().string().rfind("good_", 0) == 0) decks.push_back(entry.path());
  for (const fs::path& path : decks) {
    std::string log;
    CAPTURE(path.string());
    CHECK(box.pdsim("check '" + path.string() + "'", &log) == 0);
    CHECK(log.find("deck OK") != std::string::npos);
  }
  CHECK(box.files() == 0);
}

// What a queued run would trip over only when it starts is refused by check already.
TEST_CASE("check refuses an output in a folder that does not exist, and notes an existing one") {
  Sandbox box;
  std::string text;
  {
    std::ifstream in(deck("tiny_stepped_sine.toml"));
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  text.replace(text.find("file = \"tiny.h5\""), 16, "file = \"nowhere/tiny.h5\"");
  std::ofstream(box.dir / "lost.toml") << text;
  std::string log;
  CHECK(box.pdsim("check lost.toml", &log) == 1);
  CHECK(log.find("nowhere/tiny.h5: the folder nowhere does not exist") != std::string::npos);
  CHECK(log.find("deck OK") == std::string::npos);
  fs::create_directories(box.dir / "nowhere");
  std::ofstream(box.dir / "nowhere" / "tiny.h5") << "old";
  CHECK(box.pdsim("check lost.toml", &log) == 0);
  CHECK(log.find("nowhere/tiny.h5 exists: pdsim run needs --force") != std::string::npos);
}

// A sweep's files read without running anything: one point finished, one failed (its log's
// error), one never started; --status says which, --collect tabulates the finished one.
TEST_CASE("sweep --status and --collect say which points are finished, failed or missing") {
  Sandbox box;
  std::ofstream(box.dir / "masses.toml") << kMassSweep;
  fs::create_directories(box.dir / "m_sweep");
  REQUIRE(box.pdsim("run masses.toml --point 1 -o m_sweep/p001.h5 --quiet") == 0);
  std::ofstream(box.dir / "m_sweep" / "p002.log") << "error: the node was lost\n";
  std::string log;
  CHECK(box.pdsim("sweep masses.toml --status", &log) == 2);
  CHECK(log.find("point 1/3 (structure.mass = 0.5): finished") != std::string::npos);
  CHECK(log.find("point 2/3 (structure.mass = 1.0): failed: error: the node was lost") !=
        std::string::npos);
  CHECK(log.find("point 3/3 (structure.mass = 2.0): not run") != std::string::npos);
  CHECK(log.find("1 of 3 points finished") != std::string::npos);
  CHECK(!fs::exists(box.dir / "m_sweep" / "summary.csv"));  // --status writes nothing
  CHECK(box.pdsim("sweep masses.toml --collect", &log) == 2);
  CHECK(log.find("not finished: points 2, 3") != std::string::npos);
  std::ifstream summary(box.dir / "m_sweep" / "summary.csv");
  std::string line, rows;
  while (std::getline(summary, line)) rows += line + "\n";
  CHECK(rows.find("\n1,0.5,finished,p001.h5,") != std::string::npos);
  CHECK(rows.find("\n2,1.0,failed,p002.h5\n") != std::string::npos);
  CHECK(rows.find("\n3,2.0,not run,p003.h5\n") != std::string::npos);
}

// A sweep's points and a map's runs finished earlier are kept only while they are what the deck
// makes now: a new title is taken as it is; a mesh edited since, which the deck's text does not
// show, is refused naming the container.
TEST_CASE("sweep and map --resume: finished files of a mesh edited since are refused by name") {
  using pdsim::stl_files::ascii;
  Sandbox box;
  const std::string stl = ascii(pdsim::stl_files::box(30, 30, 30), "resumed.stl");
  const std::string sweep = mesh_deck(stl) + "[sweep]\n\"excitation.duration\" = [0.05, 0.06]\n";
  const std::string map =
      mesh_deck(stl) + "[map]\namplitudes = [0.001]\nfrequencies = [20.0]\nduration = 0.05\n";
  std::ofstream(box.dir / "s.toml") << sweep;
  std::ofstream(box.dir / "m.toml") << map;
  std::string log;
  REQUIRE(box.pdsim("sweep s.toml --jobs 1", &log) == 0);
  REQUIRE(box.pdsim("map m.toml --jobs 1 --quiet", &log) == 0);
  std::ofstream(box.dir / "s.toml") << "title = \"renamed\"\n" << sweep;
  CHECK(box.pdsim("sweep s.toml --resume --jobs 1", &log) == 0);
  CHECK(log.find("point 2/2 (excitation.duration = 0.06): finished earlier, kept") !=
        std::string::npos);
  ascii(pdsim::stl_files::box(30, 30, 40), "resumed.stl");  // 10 mm taller
  fs::remove(box.dir / "mesh_map.h5");  // as if interrupted: its one run finished
  for (const char* command : {"sweep s.toml --resume --jobs 1", "map m.toml --resume --jobs 1"}) {
    CAPTURE(command);
    CHECK(box.pdsim(command, &log) == 1);
    CAPTURE(log);
    CHECK(log.find("damper[0].container: mesh triangles 144 numbers ") != std::string::npos);
    CHECK(log.find(" then, mesh triangles 144 numbers ") != std::string::npos);
  }
}

// Ranks of a launcher (here its environment alone, as mpirun or srun sets it) share the points:
// each runs its own, the files are those of a local sweep, and the last rank writes the summary.
TEST_CASE("sweep --ranks: two ranks give the points of one local sweep") {
  Sandbox box;
  std::ofstream(box.dir / "masses.toml") << kMassSweep;
  REQUIRE(box.pdsim("sweep masses.toml -o local --jobs 1") == 0);
  const std::string bin = "'" + std::string(PDSIM_BINARY) + "'";
  std::string log;
  REQUIRE(box.shell("for r in 0 1; do OMPI_COMM_WORLD_RANK=$r OMPI_COMM_WORLD_SIZE=2 " + bin +
                        " sweep masses.toml -o ranked --ranks --jobs 1 > rank$r.txt 2>&1 & "
                        "done; wait; cat rank0.txt rank1.txt",
                    &log) == 0);
  CHECK(log.find("rank 0 of 2: 2 of its 2 points finished") != std::string::npos);
  CHECK(log.find("rank 1 of 2: 1 of its 1 points finished") != std::string::npos);
  for (const char* file : {"p001.h5", "p002.h5", "p003.h5"}) {
    CAPTURE(file);
    const pdsim::Results a = pdsim::read_results((box.dir / "local" / file).string());
    const pdsim::Results b = pdsim::read_results((box.dir / "ranked" / file).string());
    CHECK(a.frf.amplitude == b.frf.amplitude);
    CHECK(a.frf.phase == b.frf.phase);
    CHECK(a.timeseries.displacement == b.timeseries.displacement);
  }
  std::ifstream summary(box.dir / "ranked" / "summary.csv");
  std::string line;
  int finished = 0;
  while (std::getline(summary, line)) finished += line.find(",finished,") != std::string::npos;
  CHECK(finished == 3);
  CHECK(box.pdsim("sweep masses.toml --ranks", &log) == 1);  // no launcher: refused by name
  CHECK(log.find("no launcher rank in the environment") != std::string::npos);
}

TEST_CASE("a sweep runs every point side by side and tabulates the analytical SDOF response") {
  Sandbox box;
  // A bare SDOF driven at 15 Hz with 1 N: X = F / sqrt((K - M w^2)^2 + (c w)^2), c = 2 zeta
  // sqrt(K M), for each swept mass.
  std::ofstream(box.dir / "masses.toml") << kMassSweep;
  std::string log;
  REQUIRE(box.pdsim("sweep --jobs 2 masses.toml", &log) == 0);
  CHECK(log.find("3 of 3 points finished") != std::string::npos);
  std::ifstream summary(box.dir / "m_sweep" / "summary.csv");
  std::string line;
  std::getline(summary, line);
  CHECK(line.rfind("point,structure.mass,status,file,", 0) == 0);
  const double masses[] = {0.5, 1.0, 2.0}, w = 2 * M_PI * 15, k = 10000;
  for (double m : masses) {
    CAPTURE(m);
    REQUIRE(std::getline(summary, line));
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    REQUIRE(cells.size() == 11);
    CHECK(cells[8] == "1/1");
    CHECK(cells[9] == "nan");  // every point a result: nothing higher that is not one
    CHECK(std::stod(cells[1]) == m);
    CHECK(cells[2] == "finished");
    CHECK(fs::exists(box.dir / "m_sweep" / cells[3]));
    const double c = 2 * 0.2 * std::sqrt(k * m);
    const double expected = 1.0 / std::hypot(k - m * w * w, c * w);
    CHECK(std::stod(cells[6]) == doctest::Approx(expected).epsilon(2e-3));
  }
  // Finished points are not silently redone or overwritten.
  CHECK(box.pdsim("sweep masses.toml", &log) == 1);
  CHECK(log.find("--resume") != std::string::npos);
  REQUIRE(box.pdsim("sweep --resume masses.toml", &log) == 0);
  CHECK(log.find("point 2/3 (structure.mass = 1.0): finished earlier, kept") != std::string::npos);
  // A sweep deck runs one point at a time only when asked to.
  CHECK(box.pdsim("run masses.toml", &log) == 1);
  CHECK(log.find("pdsim sweep") != std::string::npos);
  REQUIRE(box.pdsim("run --quiet --point 2 -o two.h5 masses.toml", &log) == 0);
  const pdsim::Results two = pdsim::read_results((box.dir / "two.h5").string());
  CHECK(two.meta_text.at("sweep_point") == "2: structure.mass = 1.0");
  CHECK(box.pdsim("run --point 4 masses.toml", &log) == 1);
}

// ---- nothing lost (issue 17): the output checked before computing, locked while written,
// replaced whole; a full disk, a kill or a second writer never costs a finished frequency ----

namespace {

// The tiny deck with `from` replaced by `to`, written into the sandbox as `name`.
std::string tiny_deck(const Sandbox& box, const std::string& name, const std::string& from = "",
                      const std::string& to = "") {
  std::ifstream in(deck("tiny_stepped_sine.toml"));
  std::stringstream s;
  s << in.rdbuf();
  std::string text = s.str();
  if (!from.empty()) text.replace(text.find(from), from.size(), to);
  std::ofstream(box.dir / name) << text;
  return name;
}

// The tiny deck made slow enough to be caught running: five frequencies of `periods` periods
// (about 0.4 s for 10 on one core).
std::string slow_deck(const Sandbox& box, const std::string& name, int periods = 10) {
  const std::string n = std::to_string(periods);
  return tiny_deck(box, name, "frequencies = [15.0, 16.0]\nsettle = { min_periods = 3",
                   "frequencies = [13.0, 14.0, 15.0, 16.0, 17.0]\nsettle = { min_periods = " + n +
                       ", max_periods = " + n + ", batches = 2 }\n# min_periods = 3");
}

// Runs `script` with a fresh tmpfs of `size` mounted at box/M (in a private mount namespace);
// false when this machine does not allow it (no root, no unshare), so the test can skip.
bool with_tmpfs(const Sandbox& box, const std::string& size, const std::string& options,
                const std::string& script, std::string* log) {
  fs::create_directories(box.dir / "M");
  // The probe mounts too: unshare may be allowed where mount is not (AppArmor, no root).
  const std::string probe = "cd '" + box.dir.string() +
                            "' && unshare -m sh -c 'mount -t tmpfs -o size=8k tmpfs M' > "
                            "/dev/null 2>&1";
  if (std::system(probe.c_str()) != 0) return false;
  const std::string mount = "mount -t tmpfs -o size=" + size + options + " tmpfs M";
  return box.shell("unshare -m sh -c '" + mount + " && " + script + "'", log) >= 0;
}

bool sleep_until(const std::function<bool()>& done, double seconds) {
  for (int k = 0; k < int(seconds * 20) && !done(); ++k) usleep(50000);
  return done();
}

}  // namespace

TEST_CASE("a missing folder, a folder as output and a second writer are refused before any step") {
  Sandbox box;
  const std::string tiny = tiny_deck(box, "tiny.toml");
  std::string log;
  CHECK(box.pdsim("run --quiet -o nodir/sub/out.h5 " + tiny, &log) == 1);
  CHECK(log.find("the folder nodir/sub does not exist") != std::string::npos);
  fs::create_directories(box.dir / "adir");
  CHECK(box.pdsim("run --quiet --force -o adir " + tiny, &log) == 1);
  CHECK(log.find("is a folder") != std::string::npos);
  // Two runs on one output: the second is refused at once, the first finishes unharmed.
  const std::string slow = slow_deck(box, "slow.toml");
  REQUIRE(box.shell("'" + std::string(PDSIM_BINARY) + "' run --quiet -o same.h5 " + slow +
                        " > first.txt 2>&1 &",
                    nullptr) == 0);
  REQUIRE(sleep_until([&] { return fs::exists(box.dir / "same.h5.lock"); }, 20));
  CHECK(box.pdsim("run --quiet --force -o same.h5 " + slow, &log) == 1);
  CHECK(log.find("another pdsim is writing this output") != std::string::npos);
  REQUIRE(sleep_until([&] { return fs::exists(box.dir / "same.h5"); }, 120));
  CHECK(sleep_until([&] { return !fs::exists(box.dir / "same.h5.lock"); }, 10));
  CHECK(pdsim::read_results((box.dir / "same.h5").string()).frf.frequency.size() == 5);
  // A read-only folder (a read-only mount: root ignores permission bits).
  if (with_tmpfs(
          box, "1m", ",ro",
          "'" + std::string(PDSIM_BINARY) + "' run --quiet -o M/out.h5 " + tiny + "; echo rc=$?",
          &log)) {
    CHECK(log.find("rc=1") != std::string::npos);
    CHECK(log.find("is not writable") != std::string::npos);
  } else {
    MESSAGE("skipped the read-only mount: this machine does not allow mounts");
  }
}

TEST_CASE("a full disk: exit 2, a clear message, no crash, and the last checkpoint resumes") {
  Sandbox box;
  // Three frequencies: two checkpoints before the results.
  const std::string tiny =
      tiny_deck(box, "tiny.toml", "frequencies = [15.0, 16.0]", "frequencies = [15.0, 16.0, 17.0]");
  REQUIRE(box.pdsim("run --quiet --threads 1 -o whole.h5 " + tiny) == 0);
  // The size of the first checkpoint, to make a disk that holds it but not the next write.
  REQUIRE(box.pdsim("run --quiet -o first.h5 --stop-after 1 " + tiny) == 0);
  const auto first = fs::file_size(box.dir / "first.h5.partial");
  const std::string binary = "'" + std::string(PDSIM_BINARY) + "'";
  for (const std::string& size :
       std::vector<std::string>{"8k", "64k", std::to_string((first * 3 / 2) / 4096 * 4096)}) {
    CAPTURE(size);
    std::string log;
    const std::string script = binary + " run --quiet --threads 1 -o M/out.h5 " + tiny +
                               "; echo rc=$?; cp M/out.h5.partial kept.h5.partial";
    if (!with_tmpfs(box, size, "", script, &log)) {
      MESSAGE("skipped: this machine does not allow tmpfs mounts");
      return;
    }
    CHECK(log.find("rc=2") != std::string::npos);  // not 139 (a crash at exit)
    CHECK(log.find("No space left on device") != std::string::npos);
    if (size.back() != 'k') {
      // The checkpoint the full disk left resumes to the uninterrupted run's numbers.
      REQUIRE(fs::exists(box.dir / "kept.h5.partial"));
      REQUIRE(box.pdsim("run --quiet --threads 1 -o kept.h5 --resume " + tiny, &log) == 0);
      const pdsim::Results a = pdsim::read_results((box.dir / "whole.h5").string());
      const pdsim::Results b = pdsim::read_results((box.dir / "kept.h5").string());
      CHECK(a.frf.amplitude == b.frf.amplitude);
      CHECK(a.timeseries.displacement == b.timeseries.displacement);
    }
  }
}

// Fills where they are needed: two fills start each point; where they disagree (50 spheres,
// fluidised in part near the structure's resonance at 15.9 Hz, move chaotically) more fills are
// added, catching up from their beds through the earlier points; a point is left not a result
// only for a fill that did not settle on its own or with max_realisations fills. What a fill
// computes does not depend on the schedule: one job and two give the same file, bitwise.
TEST_CASE("fills that disagree are joined by more fills, the same on one job and on two") {
  Sandbox box;
  const int max_periods = 40;
  std::string near = tiny_deck(
      box, "near.toml", "frequencies = [15.0, 16.0]\nsettle = { min_periods = 3, max_periods = 4",
      "frequencies = [15.5, 16.5]\nsettle = { min_periods = 3, max_periods = " +
          std::to_string(max_periods));
  REQUIRE(
      box.shell("sed -i -e 's/count = 20/count = 50/' -e 's/^amplitude = 1.0/amplitude = 0.3/' " +
                near) == 0);
  std::string log;
  REQUIRE(box.pdsim("run --threads 1 -o near.h5 " + near, &log) == 0);  // one fill at a time
  CAPTURE(log);
  CHECK(log.find("more fills") != std::string::npos);  // the case this test is for
  const pdsim::Results r = pdsim::read_results((box.dir / "near.h5").string());
  REQUIRE(box.pdsim("run --quiet --threads 2 -o side.h5 " + near) == 0);
  const pdsim::Results side = pdsim::read_results((box.dir / "side.h5").string());
  CHECK(side.meta_numbers.at("jobs") == 2);
  CHECK(side.frf.amplitude == r.frf.amplitude);
  CHECK(side.frf.amplitude_spread == r.frf.amplitude_spread);
  CHECK(side.frf.result == r.frf.result);
  CHECK(side.fills.amplitude == r.fills.amplitude);
  CHECK(side.periods.amplitude == r.periods.amplitude);
  const pdsim::FillTable& f = r.fills;
  for (std::size_t i = 0; i < r.frf.frequency.size(); ++i) {
    CAPTURE(r.frf.frequency[i]);
    int fills = 0, unsettled = 0;
    for (std::size_t k = 0; k < f.frequency.size(); ++k)
      if (f.frequency[k] == r.frf.frequency[i]) ++fills, unsettled += f.settled[k] == 0;
    CHECK(r.frf.realisations[i] == fills);
    CHECK(fills >= 2);
    CHECK(fills <= pdsim::kDefaultMaxFills);
    CHECK(r.frf.sweep[i] == 1);
    // Not a result only with a fill unsettled at max_periods, or at the cap of fills.
    if (r.frf.result[i] == 0) CHECK((unsettled > 0 || fills == pdsim::kDefaultMaxFills));
    if (unsettled > 0) CHECK(r.frf.result[i] == 0);
  }
  for (std::size_t k = 0; k < f.frequency.size(); ++k) {
    if (!f.converged[k]) CHECK(f.periods[k] == max_periods);
    if (f.converged[k]) CHECK(f.settled[k] == 1);
  }
}

// settle.min_periods = max_periods asks for a fixed dwell: the predicted start's refinement
// takes some of those periods, and what is left of them is judged (it used to be refused as
// "fewer than min_periods" at every point, whatever the fills did).
TEST_CASE("a fixed dwell (min_periods = max_periods) with predicted starts is judged at its end") {
  Sandbox box;
  const std::string fixed =
      tiny_deck(box, "fixed.toml", "settle = { min_periods = 3, max_periods = 4",
                "settle = { min_periods = 30, max_periods = 30");
  std::string log;
  REQUIRE(box.pdsim("run --threads 1 -o fixed.h5 " + fixed, &log) == 0);
  CAPTURE(log);
  CHECK(log.find("fewer than min_periods") == std::string::npos);
  const pdsim::Results r = pdsim::read_results((box.dir / "fixed.h5").string());
  for (int periods : r.fills.periods) CHECK(periods == 30);
  for (int settled : r.fills.settled) CHECK(settled == 1);
}

// Three realisations on two jobs: a run done early keeps up with one still going while the third
// waits for a worker; the periods each run makes do not depend on that schedule.
TEST_CASE("three realisations give the same periods on one job and on two") {
  Sandbox box;
  std::string near = tiny_deck(
      box, "three.toml", "frequencies = [15.0, 16.0]\nsettle = { min_periods = 3, max_periods = 4",
      "frequencies = [15.5, 16.5]\nsettle = { realisations = 3, min_periods = 3, max_periods = 40");
  REQUIRE(
      box.shell("sed -i -e 's/count = 20/count = 50/' -e 's/^amplitude = 1.0/amplitude = 0.3/' " +
                near) == 0);
  REQUIRE(box.pdsim("run --quiet --threads 1 -o one.h5 " + near) == 0);
  REQUIRE(box.pdsim("run --quiet --threads 2 -o two.h5 " + near) == 0);
  const pdsim::Results one = pdsim::read_results((box.dir / "one.h5").string());
  const pdsim::Results two = pdsim::read_results((box.dir / "two.h5").string());
  CHECK(one.meta_numbers.at("jobs") == 1);
  CHECK(two.meta_numbers.at("jobs") == 2);
  CHECK(one.frf.realisations == two.frf.realisations);
  for (int fills : one.frf.realisations) CHECK(fills >= 3);
  CHECK(one.periods.realisation == two.periods.realisation);
  CHECK(one.periods.amplitude == two.periods.amplitude);
  CHECK(one.frf.amplitude == two.frf.amplitude);
}

// Fills that stop at a look (their own interval small beside the fills' spread, here where a
// tolerance of 0.5 % would run them to max_periods) wait for the fills before them at each look:
// one job and two, and a run stopped after its first point and resumed, give the same file.
TEST_CASE("fills stopped at looks: the same on one job, on two, and resumed") {
  Sandbox box;
  std::string near = tiny_deck(
      box, "looks.toml", "frequencies = [15.0, 16.0]\nsettle = { min_periods = 3, max_periods = 4",
      "frequencies = [15.5, 16.0]\nsettle = { tolerance = 0.005, max_realisations = 4, "
      "min_periods = 3, max_periods = 100");
  REQUIRE(
      box.shell("sed -i -e 's/count = 20/count = 50/' -e 's/^amplitude = 1.0/amplitude = 0.3/' " +
                near) == 0);
  std::string log;
  REQUIRE(box.pdsim("run --threads 1 -o one.h5 " + near, &log) == 0);
  CAPTURE(log);
  CHECK(log.find("settled to a third of the fills' spread") != std::string::npos);
  REQUIRE(box.pdsim("run --quiet --threads 2 -o two.h5 " + near) == 0);
  REQUIRE(box.pdsim("run --quiet --threads 2 --stop-after 1 -o split.h5 " + near) == 0);
  REQUIRE(box.pdsim("run --quiet --threads 2 --resume -o split.h5 " + near) == 0);
  const pdsim::Results one = pdsim::read_results((box.dir / "one.h5").string());
  for (const char* other : {"two.h5", "split.h5"}) {
    CAPTURE(other);
    const pdsim::Results r = pdsim::read_results((box.dir / other).string());
    CHECK(r.periods.amplitude == one.periods.amplitude);
    CHECK(r.fills.amplitude == one.fills.amplitude);
    CHECK(r.fills.amplitude_ci == one.fills.amplitude_ci);
    CHECK(r.frf.amplitude == one.frf.amplitude);
    CHECK(r.frf.result == one.frf.result);
  }
}

TEST_CASE("SIGKILL at random moments never loses a finished frequency") {
  Sandbox box;
  const std::string slow = slow_deck(box, "slow.toml");
  REQUIRE(box.pdsim("run --quiet --threads 1 -o whole.h5 " + slow) == 0);
  const pdsim::Results whole = pdsim::read_results((box.dir / "whole.h5").string());
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> delay_ms(0, 1500);
  int caught = 0;
  for (int trial = 0; trial < 8; ++trial) {
    CAPTURE(trial);
    fs::remove(box.dir / "k.h5");
    fs::remove(box.dir / "k.h5.partial");
    // Killed at a random moment after its first checkpoint (so on any machine speed), often
    // during a later checkpoint's write.
    const std::string run =
        "'" + std::string(PDSIM_BINARY) + "' run --quiet --threads 1 -o k.h5 " + slow +
        " > /dev/null 2>&1 & for i in $(seq 400); do [ -e k.h5.partial ] && break; sleep 0.05; "
        "done; sleep " +
        std::to_string(delay_ms(rng) / 1000.0) + "; kill -9 $! 2>/dev/null; wait";
    box.shell(run, nullptr);
    if (fs::exists(box.dir / "k.h5")) continue;  // finished before the kill
    REQUIRE(fs::exists(box.dir / "k.h5.partial"));
    ++caught;
    // Whatever the moment, the checkpoint is whole and resumes to the same numbers.
    const pdsim::Results kept = pdsim::read_results((box.dir / "k.h5.partial").string());
    CHECK(kept.frf.frequency.size() <= 5);
    std::ofstream(box.dir / "k.h5.partial.tmp-999999") << "left by a kill mid-write";
    REQUIRE(box.pdsim("run --quiet --threads 1 -o k.h5 --resume " + slow) == 0);
    CHECK(pdsim::read_results((box.dir / "k.h5").string()).frf.amplitude == whole.frf.amplitude);
    // A temporary file a kill left mid-write is cleared by the next run on that output.
    for (const auto& entry : fs::directory_iterator(box.dir))
      CHECK(entry.path().filename().string().find(".tmp-") == std::string::npos);
  }
  CHECK(caught >= 3);
}

// sbatch and squeue stood in for by scripts (a Slurm is in tests/cluster/slurm_test.sh): what
// --slurm submits, and that it checks every point before it removes anything.
TEST_CASE("sweep --slurm submits the points not finished, and removes nothing it then refuses") {
  Sandbox box;
  std::ofstream(box.dir / "masses.toml") << kMassSweep;
  fs::create_directories(box.dir / "bin");
  // sbatch: a warning on its error stream, then the next job id; its arguments kept.
  std::ofstream(box.dir / "bin" / "sbatch")
      << "#!/bin/sh\necho \"$@\" >> sbatch.args\necho 'sbatch: warning: a note' >&2\n"
         "n=$(cat next 2>/dev/null || echo 100); echo $((n + 1)) > next; echo $((n + 1))\n";
  std::ofstream(box.dir / "bin" / "squeue") << "#!/bin/sh\ncat queued 2>/dev/null\n";
  fs::permissions(box.dir / "bin" / "sbatch", fs::perms::owner_all);
  fs::permissions(box.dir / "bin" / "squeue", fs::perms::owner_all);
  const std::string slurm = "PATH=\"$PWD/bin:$PATH\" '" + std::string(PDSIM_BINARY) + "' sweep ";
  std::string log;
  REQUIRE(box.shell(slurm + "masses.toml --slurm --jobs 2 --sbatch '-p short'", &log) == 0);
  CHECK(log.find("3 of 3 points submitted to Slurm as job array 101") != std::string::npos);
  CHECK(log.find("job 102 writes m_sweep/summary.csv") != std::string::npos);
  CHECK(log.find("pdsim sweep 'masses.toml' -o 'm_sweep' --sbatch '-p short' --slurm --resume") !=
        std::string::npos);
  std::string args;
  REQUIRE(box.shell("cat sbatch.args", &args) == 0);
  CHECK(args.find("--array=1-3%2 --cpus-per-task=1 --mem=256M --requeue") != std::string::npos);
  CHECK(args.find("-p short m_sweep/slurm_array.sh") != std::string::npos);
  CHECK(args.find("--dependency=afterany:101") != std::string::npos);
  CHECK(box.shell("bash -n m_sweep/slurm_array.sh") == 0);
  // While that array is queued, nothing more is submitted.
  std::ofstream(box.dir / "queued") << "101_1\n";
  CHECK(box.shell(slurm + "masses.toml --slurm --resume", &log) == 1);
  CHECK(log.find("its job array 101 is still in the queue") != std::string::npos);
  fs::remove(box.dir / "queued");
  // Point 1 finished, point 2 interrupted with a checkpoint, point 3 running (its lock held).
  REQUIRE(box.pdsim("run masses.toml --point 1 -o m_sweep/p001.h5 --quiet") == 0);
  std::ofstream(box.dir / "m_sweep" / "p002.h5.partial") << "a checkpoint";
  REQUIRE(box.shell("flock m_sweep/p003.h5.lock sleep 5 > /dev/null 2>&1 & "
                    "for i in $(seq 100); do [ -e m_sweep/p003.h5.lock ] && break; sleep 0.05; "
                    "done") == 0);
  CHECK(box.shell(slurm + "masses.toml --slurm --force", &log) == 1);
  CHECK(log.find("m_sweep/p003.h5: is being run") != std::string::npos);
  CHECK(fs::exists(box.dir / "m_sweep" / "p002.h5.partial"));  // refused before removing
  CHECK(box.shell(slurm + "masses.toml --slurm", &log) == 1);
  CHECK(log.find("p001.h5: exists; use --resume") != std::string::npos);
  REQUIRE(box.shell(slurm + "masses.toml --slurm --resume", &log) == 0);
  CHECK(log.find("points 3 are running and are not submitted") != std::string::npos);
  CHECK(log.find("1 of 3 points submitted to Slurm as job array 103") != std::string::npos);
  REQUIRE(box.shell("tail -n 2 sbatch.args | head -n 1", &args) == 0);
  CHECK(args.find("--array=2 ") != std::string::npos);
}

// SIGTERM is what Slurm sends at a time limit, preemption or scancel (then SIGKILL KillWait s
// later): a run takes it as an interrupt, exit 130 with its finished frequencies kept.
TEST_CASE("SIGTERM, as a scheduler sends it, keeps the finished frequencies for --resume") {
  Sandbox box;
  const std::string slow = slow_deck(box, "slow.toml");
  REQUIRE(box.pdsim("run --quiet --threads 1 -o whole.h5 " + slow) == 0);
  std::string log;
  const int code =
      box.shell("'" + std::string(PDSIM_BINARY) + "' run --quiet --threads 1 -o t.h5 " + slow +
                    " & for i in $(seq 400); do [ -e t.h5.partial ] && break; sleep 0.05; done; "
                    "kill -TERM $!; wait $!",
                &log);
  REQUIRE_FALSE(fs::exists(box.dir / "t.h5"));  // stopped before its last frequency
  CHECK(code == 130);
  CHECK(log.find("interrupted; finished frequencies are in t.h5.partial") != std::string::npos);
  REQUIRE(box.pdsim("run --quiet --threads 1 -o t.h5 --resume " + slow) == 0);
  const pdsim::Results whole = pdsim::read_results((box.dir / "whole.h5").string());
  const pdsim::Results resumed = pdsim::read_results((box.dir / "t.h5").string());
  CHECK(resumed.frf.amplitude == whole.frf.amplitude);
  CHECK(resumed.timeseries.displacement == whole.timeseries.displacement);
}

// What a queued sweep would trip over is refused before anything is submitted or written.
TEST_CASE("sweep --slurm refuses bad sbatch options and a missing sbatch, naming them") {
  Sandbox box;
  std::ofstream(box.dir / "masses.toml")
      << kMassSweep << "[cluster]\nsbatch = \"--partition=short --array=1-3\"\n";
  std::string log;
  CHECK(box.pdsim("check masses.toml", &log) == 1);
  CHECK(log.find("masses.toml:16:10: 'cluster.sbatch': --array=1-3 is set") != std::string::npos);
  CHECK(log.find("--array=1-3 is set by pdsim sweep --slurm itself") != std::string::npos);
  std::ofstream(box.dir / "masses.toml") << kMassSweep;
  CHECK(box.pdsim("sweep masses.toml --slurm --sbatch \"--time='1:00\"", &log) == 1);
  CHECK(log.find("--sbatch: expected sbatch options as a shell would split them") !=
        std::string::npos);
  CHECK(log.find("unbalanced quotes") != std::string::npos);
  CHECK(box.pdsim("sweep masses.toml --sbatch --time=1:00", &log) == 1);
  CHECK(log.find("--sbatch: only with --slurm") != std::string::npos);
  CHECK(box.pdsim("sweep masses.toml --slurm --ranks", &log) == 1);
  CHECK(log.find("choose one") != std::string::npos);
  CHECK(box.shell("PATH=/nonexistent '" + std::string(PDSIM_BINARY) + "' sweep masses.toml --slurm",
                  &log) == 1);
  CHECK(log.find("cannot start sbatch") != std::string::npos);
  CHECK_FALSE(fs::exists(box.dir / "m_sweep" / "p001.h5"));
}

TEST_CASE("a SIGKILLed sweep leaves no point process behind, each keeping its checkpoint") {
  Sandbox box;
  const std::string name = "sweep_" + std::to_string(getpid()) + ".toml";
  slow_deck(box, name, 100);  // a minute or more a point: it cannot finish by itself meanwhile
  std::ofstream(box.dir / name, std::ios::app) << "[sweep]\n\"structure.mass\" = [0.5, 0.6]\n";
  const std::string binary = "'" + std::string(PDSIM_BINARY) + "'";
  REQUIRE(box.shell(binary + " sweep --jobs 2 " + name + " > sweep.txt 2>&1 & echo $! > sweep.pid",
                    nullptr) == 0);
  // "[s]weep": the pattern must not match the shell that runs pgrep.
  const std::string points = "pgrep -f '[s]" + name.substr(1) + " --point' > /dev/null";
  // Both points running, past their set-up (each holds its output's lock).
  REQUIRE(sleep_until(
      [&] {
        return fs::exists(box.dir / "tiny_sweep" / "p001.h5.lock") &&
               fs::exists(box.dir / "tiny_sweep" / "p002.h5.lock");
      },
      20));
  box.shell("kill -9 $(cat sweep.pid)", nullptr);
  // Each point gets SIGINT, keeps its finished frequencies and stops.
  CHECK(sleep_until([&] { return std::system(points.c_str()) != 0; }, 5));
  std::system(("pkill -f '[s]" + name.substr(1) + " --point'").c_str());  // never leave any
  int interrupted = 0;
  for (const auto& entry : fs::directory_iterator(box.dir / "tiny_sweep"))
    if (entry.path().extension() == ".log") {
      std::ifstream in(entry.path());
      std::stringstream text;
      text << in.rdbuf();
      interrupted += text.str().find("simulation failed: interrupted") != std::string::npos;
    }
  CHECK(interrupted == 2);
}

TEST_CASE("a run that blows up keeps its particle dump and the time series up to the failure") {
  Sandbox box;
  std::ifstream in(deck("bad_dt_above_limit.toml"));
  std::stringstream text;
  text << in.rdbuf();
  std::string unstable = text.str();
  // 92 times the stability limit, accepted against advice: a blow-up within 0.05 s.
  unstable.replace(unstable.find("dt = 1e-5"), 9, "dt = 1e-4\nallow_unstable = true");
  std::ofstream(box.dir / "unstable.toml")
      << unstable << "[gravity]\nvector = [0, 0, -9.81]\n[bed]\nsettle = false\n";
  std::string log;
  CHECK(box.pdsim("run --quiet -o u.h5 unstable.toml", &log) == 2);
  CHECK(log.find("warning: dt = 0.0001 s is 92.52 times the stability limit") != std::string::npos);
  CHECK(log.find("blow-up at t = ") != std::string::npos);
  CHECK(fs::exists(box.dir / "u.h5.blowup.csv"));
  REQUIRE(fs::exists(box.dir / "u.h5.failed.h5"));
  CHECK_FALSE(fs::exists(box.dir / "u.h5"));
  const pdsim::Results kept = pdsim::read_results((box.dir / "u.h5.failed.h5").string());
  CHECK(kept.meta_text.at("failure").find("blow-up at t = ") == 0);
  CHECK(kept.timeseries.time.size() > 5);
  CHECK(kept.timeseries.time.back() < 0.1);
}

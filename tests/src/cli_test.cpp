// The pdsim executable as a user meets it: exit codes, nothing written for bad input, no silent
// overwrite, and an interrupted stepped sine resumed to the same numbers.
#include <doctest/doctest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "io/results.hpp"

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
  // Runs pdsim with `args` in the sandbox; returns the exit code, output in `log`.
  int pdsim(const std::string& args, std::string* log = nullptr) const {
    const fs::path out = dir / "log.txt";
    const std::string command = "cd '" + dir.string() + "' && '" + PDSIM_BINARY + "' " + args +
                                " > '" + out.string() + "' 2>&1";
    const int status = std::system(command.c_str());
    if (log) {
      std::ifstream in(out);
      std::stringstream s;
      s << in.rdbuf();
      *log = s.str();
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::size_t files() const {
    std::size_t n = 0;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().filename() != "log.txt") ++n;
    return n;
  }
};

std::string deck(const std::string& name) {
  return std::string(PDSIM_TEST_DIR) + "/decks/" + name;
}

}  // namespace

TEST_CASE("bad decks exit 1 with the position, and write nothing") {
  Sandbox box;
  for (const char* name : {"bad_negative_mass.toml", "bad_misspelt_key.toml", "bad_syntax.toml",
                           "bad_dt_above_limit.toml", "bad_particles_do_not_fit.toml"}) {
    std::string log;
    CAPTURE(name);
    CHECK(box.pdsim("run '" + deck(name) + "'", &log) == 1);
    CHECK(log.find(std::string(name) + ":") != std::string::npos);
    CHECK(box.files() == 0);
  }
  std::string log;
  CHECK(box.pdsim("run missing.toml", &log) == 1);
  CHECK(box.pdsim("run", &log) != 0);  // CLI11 usage error, not a crash
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

TEST_CASE("a stepped sine stopped after one frequency and resumed gives the same results") {
  Sandbox box;
  const std::string tiny = "'" + deck("tiny_stepped_sine.toml") + "'";
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

TEST_CASE("check passes on every example deck") {
  Sandbox box;
  for (const auto& entry : fs::directory_iterator(std::string(PDSIM_TEST_DIR) + "/../examples")) {
    std::string log;
    CAPTURE(entry.path().string());
    CHECK(box.pdsim("check '" + entry.path().string() + "'", &log) == 0);
    CHECK(log.find("deck OK") != std::string::npos);
  }
  CHECK(box.files() == 0);
}

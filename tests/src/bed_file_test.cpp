// bed.file keeps a settled bed for later runs; it is reused only for the same engines: the
// fingerprint is taken over what the engines are made with, so a change of a contact law's
// constant or of the container's orientation is refused, not silently run on a stale bed.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <tuple>
#include <unistd.h>

#include "src/check_report.hpp"
#include "src/run.hpp"
#include "src/scene.hpp"

using namespace pdsim;
namespace fs = std::filesystem;

namespace {

std::string deck(const std::string& bed_file, double restitution, const std::string& axis) {
  return R"([structure]
kind = "sdof"
mass = 0.5
stiffness = 8000.0
damping_ratio = 0.02
[[damper]]
container = { shape = "cylinder", radius = 0.012, height = 0.03, axis = )" +
         axis + R"( }
particles = { count = 10, diameter = 0.005, density = 7800.0, seed = 4 }
[contact]
model = "linear"
tangential = "history"
stiffness = 4000.0
young = 2.0e8
restitution = )" +
         std::to_string(restitution) + R"(
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[bed]
max_time = 0.3
file = ")" +
         bed_file +
         R"("
[excitation]
kind = "stepped_sine"
amplitude = 1.0
frequencies = [20.0]
settle = { min_periods = 3, max_periods = 3, batches = 2, max_realisations = 2 }
[solver]
threads = 1
)";
}

Results run(const std::string& text) {
  const Deck d = parse_deck(text, "bed.toml");
  return simulate(d, build_scene(d));
}

}  // namespace

TEST_CASE("bed.file: reused for the same engines, refused when a derived constant differs") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_bed_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string file = (dir / "bed.h5").string();
  const Results first = run(deck(file, 0.5, "[0, 0, 1]"));
  CHECK(first.meta_text.at("bed").rfind("read from", 0) != 0);  // settled here, then kept
  REQUIRE(fs::exists(file));
  const Results again = run(deck(file, 0.5, "[0, 0, 1]"));
  CHECK(again.meta_text.at("bed") == "read from " + file);
  CHECK(again.frf.amplitude == first.frf.amplitude);  // the same bed, the same run
  // Restitution changes the derived damping factor (and the step it sets); the axis only the
  // orientation. Each field is named.
  for (const auto& [restitution, axis, field] :
       {std::tuple{0.6, std::string("[0, 0, 1]"), "contact.damping_factor: "},
        std::tuple{0.5, std::string("[1, 0, 0]"),
                   "damper[0].container.axis: absent in the file, "
                   "1 0 0 in the deck"}}) {
    CAPTURE(axis);
    CHECK_THROWS_WITH_AS(run(deck(file, restitution, axis)), doctest::Contains(field), InputError);
  }
  fs::remove_all(dir);
}

TEST_CASE("bed.file: check refuses a file that is no kept bed, or one of another scene, first") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_bed_check_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string file = (dir / "bed.h5").string();
  const Deck good = parse_deck(deck(file, 0.5, "[0, 0, 1]"), "bed.toml");
  std::ofstream(file) << "not an HDF5 file\n";
  // Where the run used to stop with exit 2 and HDF5's signature message, check names the key.
  for (const std::string& text : {std::string("not a bed pdsim kept"), std::string("bed.file")}) {
    CHECK_THROWS_WITH_AS(check_report(good, build_scene(good)), doctest::Contains(text.c_str()),
                         InputError);
    CHECK_THROWS_WITH_AS(run(deck(file, 0.5, "[0, 0, 1]")), doctest::Contains(text.c_str()),
                         InputError);
  }
  fs::remove(file);
  CHECK(check_report(good, build_scene(good)).find("kept in " + file) != std::string::npos);
  run(deck(file, 0.5, "[0, 0, 1]"));
  CHECK(check_report(good, build_scene(good)).find("read from " + file) != std::string::npos);
  const Deck other = parse_deck(deck(file, 0.6, "[0, 0, 1]"), "bed.toml");
  CHECK_THROWS_WITH_AS(check_report(other, build_scene(other)),
                       doctest::Contains("contact.damping_factor: "), InputError);
  fs::remove_all(dir);
}

// A resumed run takes its first fills' beds from its checkpoint: a bed.file settled since for
// another deck is not read, so it cannot refuse the resume.
TEST_CASE("bed.file: a resumed run does not read it, its checkpoint holding the beds") {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_bed_resume_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string file = (dir / "bed.h5").string();
  auto two_points = [&](double restitution) {
    std::string text = deck(file, restitution, "[0, 0, 1]");
    text.replace(text.find("frequencies = [20.0]"), 20, "frequencies = [20.0, 21.0]");
    return parse_deck(text, "bed.toml");
  };
  RunOptions a;
  a.output = (dir / "a.h5").string();
  a.quiet = true;
  a.stop_after = 1;
  run_deck(two_points(0.5), a);
  REQUIRE(fs::exists(a.output + ".partial"));
  fs::remove(file);
  RunOptions b = a;
  b.output = (dir / "b.h5").string();
  b.stop_after = 0;
  run_deck(two_points(0.6), b);  // its own bed, kept in the same file
  a.stop_after = 0;
  a.resume = true;
  run_deck(two_points(0.5), a);
  CHECK(read_results(a.output).frf.frequency == std::vector<double>{20.0, 21.0});
  fs::remove_all(dir);
}

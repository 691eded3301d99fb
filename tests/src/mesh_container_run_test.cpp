// A shaken bed in a mesh container against the analytic container of the same shape: the box as
// 12 triangles and a cylinder as 2,048, each filled at random several times (independent fills,
// a different packing each) and shaken along x; the mean dissipated power and the first harmonic
// of the force on the container agree within the two runs' 95 % intervals.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "src/identity.hpp"
#include "src/run.hpp"
#include "tests/support/stl_files.hpp"
#include "tests/support/validation_row.hpp"

using namespace pdsim;

namespace {

// 60 soft steel spheres d = 5 mm, random fills, shaken 3 mm at 20 Hz (4.8 g) for 0.4 s (after
// the bed settles), the last 6 periods averaged; `fills` fills at once.
std::string deck(const std::string& container, int fills) {
  return R"(title = "mesh against analytic"
[[damper]]
container = )" +
         container +
         R"(
particles = { count = 60, diameter = 0.005, density = 7800.0, seed = 11, fill = "random" }
[contact]
model = "hertz"
tangential = "history"
young = 2.0e9
poisson = 0.3
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "prescribed"
motion = { axis = [1.0, 0.0, 0.0], amplitude = 0.003, frequency = 20.0 }
duration = 0.4
settle = { average_periods = 6, realisations = )" +
         std::to_string(fills) + ", max_realisations = " + std::to_string(fills) + R"( }
[output]
file = "mesh.h5"
[solver]
threads = 1
)";
}

struct Shaken {
  double power, power_ci, force, force_ci;
  int fills;
};
Shaken shake(const std::string& container, int fills) {
  const Deck d = parse_deck(deck(container, fills), "mesh.toml");
  const Results r = simulate(d, build_scene(d));
  REQUIRE(r.prescribed.frequency.size() == 1);
  const PrescribedTable& p = r.prescribed;
  return {p.dissipated_power[0], p.dissipated_power_ci[0], p.force_amplitude[0],
          p.force_amplitude_ci[0], p.realisations[0]};
}

// The mesh run against the analytic one: means within the sum of their half-widths.
void agree(const std::string& name, const Shaken& mesh, const Shaken& analytic) {
  MESSAGE(name << ": power " << mesh.power << " +- " << mesh.power_ci << " W (mesh), "
               << analytic.power << " +- " << analytic.power_ci << " W (analytic); force "
               << mesh.force << " +- " << mesh.force_ci << " N, " << analytic.force << " +- "
               << analytic.force_ci << " N");
  CHECK(mesh.fills == analytic.fills);
  // The intervals are real (several fills, not one run's zero width) and narrow enough to tell
  // a 15 % difference (8 fills: 5 to 10 % of the mean here).
  CHECK(mesh.power_ci > 0);
  CHECK(analytic.power_ci < 0.15 * analytic.power);
  const double power_allowed = mesh.power_ci + analytic.power_ci;
  const double force_allowed = mesh.force_ci + analytic.force_ci;
  CHECK(std::fabs(mesh.power - analytic.power) < power_allowed);
  CHECK(std::fabs(mesh.force - analytic.force) < force_allowed);
  const std::string source =
      "the analytic container, " + std::to_string(analytic.fills) + " fills of the same seeds";
  validation_row(name + ": dissipated power", source, analytic.power, mesh.power,
                 power_allowed / analytic.power, "W");
  validation_row(name + ": force harmonic", source, analytic.force, mesh.force,
                 force_allowed / analytic.force, "N");
}

std::string mesh_table(const std::string& path) {
  return "{ shape = \"mesh\", file = \"" + path + "\" }";
}

}  // namespace

TEST_CASE("a shaken bed in a 12-triangle box dissipates as in the analytic box") {
  const double a = 0.03;  // m, the cube's edge
  const std::string stl =
      stl_files::binary(stl_files::box(a, a, a, {-0.5 * a, -0.5 * a, -0.5 * a}), "box.stl");
  const Shaken mesh = shake(mesh_table(stl), 8);
  std::filesystem::remove(stl);
  const Shaken box = shake("{ shape = \"box\", size = [0.03, 0.03, 0.03] }", 8);
  agree("shaken bed, 12-triangle box against the analytic box", mesh, box);
}

TEST_CASE("a shaken bed in a 2,048-triangle cylinder dissipates as in the analytic cylinder") {
  // 512 facets around: the facets' inscribed radius is r cos(pi / 512), 2e-5 r smaller.
  const double r = 0.017, h = 0.03;
  const std::string stl = stl_files::binary(stl_files::cylinder(r, h, 512), "cylinder.stl");
  const Shaken mesh = shake(mesh_table(stl), 8);
  std::filesystem::remove(stl);
  const Shaken cylinder = shake("{ shape = \"cylinder\", radius = 0.017, height = 0.03 }", 8);
  agree("shaken bed, 2,048-triangle cylinder against the analytic cylinder", mesh, cylinder);
}

// The deck's text does not hold a mesh's triangles: an STL edited after a run is refused on
// resume by the scene's identity, naming the container (a deck edit is named by its key first).
TEST_CASE("a mesh edited since a run: resuming it is refused naming the container") {
  using namespace pdsim::stl_files;
  const std::string stl = ascii(box(0.04, 0.04, 0.04, {-0.02, -0.02, -0.02}), "edited.stl");
  const Deck d = parse_deck(deck(mesh_table(stl), 1), "mesh.toml");
  Results saved;
  saved.meta_text["deck"] = d.text;
  saved.meta_text["identity"] = identity_text(deck_identity(d, build_scene(d)));
  CHECK(changes_since(saved, d).empty());
  ascii(box(0.04, 0.04, 0.05, {-0.02, -0.02, -0.025}), "edited.stl");  // 10 mm taller
  const Deck again = parse_deck(deck(mesh_table(stl), 1), "mesh.toml");
  const Scene scene = build_scene(again);
  const std::string changed = changes_since(saved, again, &scene);
  CAPTURE(changed);
  CHECK(changed.rfind("damper[0].container: mesh triangles 144 numbers ", 0) == 0);
  CHECK(changed.find(" then, mesh triangles 144 numbers ") != std::string::npos);
  CHECK(changes_since(saved, again) == changed);  // the scene built from the deck tells alike
}

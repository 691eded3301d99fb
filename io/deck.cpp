// Deck parsing and validation (io/decks.md). Every value is checked where it is read, so an
// error names the exact key, its position in the file and what was expected.
#include "io/deck.hpp"

#include <wordexp.h>

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string_view>
#include <utility>

#include "io/deck_table.hpp"
#include "io/excitation.hpp"
#include "io/excitations/keys.hpp"
#include "io/stl_mesh.hpp"

namespace pdsim {

using namespace deck_keys;

namespace {

// Beam matrices are dense: 500 elements (1000 DOFs) take about 2 s to set up and solve for
// their modes; 10000 would need gigabytes.
constexpr std::int64_t kMaxElements = 500;
// A deck larger than this is not a deck (and /dev/zero is read until memory runs out).
constexpr std::size_t kMaxDeckBytes = 16u << 20;
void record_positions(const toml::table& table, const std::string& prefix, const std::string& file,
                      std::map<std::string, SourcePos>& positions) {
  for (auto&& [k, node] : table) {
    const std::string name =
        prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
    positions[name] = to_pos(file, node.source());
    if (const toml::table* sub = node.as_table()) record_positions(*sub, name, file, positions);
    const toml::array* array = node.as_array();
    if (!array) continue;
    for (std::size_t i = 0; i < array->size(); ++i) {
      const toml::table* element = (*array)[i].as_table();
      if (!element) continue;
      const std::string indexed = name + "[" + std::to_string(i) + "]";
      positions[indexed] = to_pos(file, element->source());
      record_positions(*element, indexed, file, positions);
    }
  }
}

void read_section(const Table& section, BeamSpec& beam) {
  const std::string why = "for a beam section";
  const auto shape = section.choice("shape", {"rectangle", "circle"});
  if (!shape) {
    section.allow_only({"shape", "area", "inertia", "height", "shear_factor"},
                       " for a section given by area and inertia");
    beam.area = section.need_real("area", "a positive number (m^2)", positive, why);
    beam.inertia = section.need_real("inertia", "a positive number (m^4)", positive, why);
    beam.section_height = section.real("height", "a positive number (m)", positive).value_or(0);
    const auto shear = section.real("shear_factor", "a number in (0, 1]", fraction_range);
    if (beam.timoshenko && !shear)
      section.missing("shear_factor", "a number in (0, 1]", "by timoshenko = true");
    beam.shear_factor = shear.value_or(0);
  } else if (*shape == 0) {
    section.allow_only({"shape", "width", "height"}, " for shape = \"rectangle\"");
    const double width = section.need_real("width", "a positive number (m)", positive, why);
    const double height = section.need_real("height", "a positive number (m)", positive, why);
    beam.area = width * height;
    beam.inertia = width * height * height * height / 12;  // b h^3 / 12, height along direction
    beam.shear_factor = 5.0 / 6.0;                         // the classical rectangle value
    beam.section_height = height;
  } else {
    section.allow_only({"shape", "diameter"}, " for shape = \"circle\"");
    const double d = section.need_real("diameter", "a positive number (m)", positive, why);
    beam.area = kPi * d * d / 4;
    beam.inertia = kPi * d * d * d * d / 64;
    beam.shear_factor = 0.9;  // solid circle; Cowper (1966) gives 6(1+nu)/(7+6nu) = 0.89 at 0.3
    beam.section_height = d;
  }
  // Positive but so small that the area or the second moment underflows (5e-324 m): the beam's
  // matrices would have no modes.
  if (!std::isnormal(beam.area) || !std::isnormal(beam.inertia)) {
    const char* key = !shape        ? (std::isnormal(beam.area) ? "inertia" : "area")
                      : *shape == 0 ? "height"
                                    : "diameter";
    std::ostringstream got;
    got << "expected a section whose area and second moment are normal numbers, got " << beam.area
        << " m^2 and " << beam.inertia << " m^4";
    section.fail(key, got.str());
  }
}

StructureSpec read_structure(const Table& t) {
  StructureSpec s;
  const Names integrators = {"exact", "cvode"};
  const bool beam = t.need_choice("kind", {"sdof", "beam"}, "in every [structure]") == 1;
  if (!beam) {
    s.kind = StructureKind::sdof;
    t.allow_only(
        {"kind", "mass", "stiffness", "damping_ratio", "damping", "direction", "integrator"},
        " for kind = \"sdof\"");
    const std::string why = "for kind = \"sdof\"";
    s.mass = t.need_real("mass", "a positive number (kg)", positive, why);
    s.stiffness = t.need_real("stiffness", "a positive number (N/m)", positive, why);
    const auto ratio = t.real("damping_ratio", "a non-negative number", non_negative);
    const auto damping = t.real("damping", "a non-negative number (N s/m)", non_negative);
    if (ratio && damping) t.fail("damping", "give either damping or damping_ratio, not both");
    const double critical = 2 * std::sqrt(s.stiffness * s.mass);  // c_c = 2 sqrt(K M)
    s.damping_ratio = ratio ? *ratio : damping.value_or(0) / critical;
    s.damping = damping ? *damping : s.damping_ratio * critical;
  } else {
    s.kind = StructureKind::beam;
    t.allow_only(
        {"kind", "length", "elements", "young", "density", "poisson", "section", "supports",
         "damping_ratio", "rayleigh", "timoshenko", "direction", "axis", "modes", "integrator"},
        " for kind = \"beam\"");
    const std::string why = "for kind = \"beam\"";
    BeamSpec& b = s.beam;
    b.length = t.need_real("length", "a positive number (m)", positive, why);
    b.elements = static_cast<int>(t.need_integer("elements", 1, kMaxElements, "", why));
    b.young = t.need_real("young", "a positive number (Pa)", positive, why);
    b.density = t.need_real("density", "a positive number (kg/m^3)", positive, why);
    b.poisson = t.real("poisson", "a number in (-1, 0.5)", poisson_range).value_or(b.poisson);
    b.timoshenko = t.boolean("timoshenko").value_or(false);
    const std::string section_kinds =
        "a table { shape = \"rectangle\", width, height }, { shape = \"circle\", diameter } or "
        "{ area, inertia }";
    read_section(t.need_sub("section", section_kinds, why), b);
    if (const auto supports = t.sub("supports", "a table { start, end }")) {
      supports->allow_only({"start", "end"});
      const Names kinds = {"clamped", "pinned", "free"};
      const Support all[] = {Support::clamped, Support::pinned, Support::free};
      if (const auto i = supports->choice("start", kinds)) b.start = all[*i];
      if (const auto i = supports->choice("end", kinds)) b.end = all[*i];
    }
    const auto ratio = t.real("damping_ratio", "a non-negative number", non_negative);
    const auto rayleigh =
        t.reals("rayleigh", 2, "two non-negative numbers [alpha (1/s), beta (s)]", non_negative);
    if (ratio && rayleigh) t.fail("rayleigh", "give either rayleigh or damping_ratio, not both");
    s.damping_ratio = ratio.value_or(0);
    if (rayleigh) s.rayleigh = std::array<double, 2>{(*rayleigh)[0], (*rayleigh)[1]};
    // two DOF (deflection, slope) per node
    s.modes = static_cast<int>(t.integer("modes", 0, 2 * (kMaxElements + 1)).value_or(0));
  }
  // A beam lies along x and bends along z unless told otherwise.
  const Vec3 default_direction = s.kind == StructureKind::beam ? Vec3{0, 0, 1} : s.direction;
  s.direction = t.direction("direction").value_or(default_direction);
  if (s.kind == StructureKind::beam) {
    s.beam.axis = t.direction("axis").value_or(s.beam.axis);
    if (std::fabs(dot(s.beam.axis, s.direction)) > 1e-9)
      t.fail(t.has("axis") ? "axis" : "direction",
             "the beam axis and the bending direction must be perpendicular (axis defaults to "
             "[1, 0, 0])");
  }
  if (const auto i = t.choice("integrator", integrators))
    s.integrator = *i == 0 ? IntegratorKind::exact : IntegratorKind::cvode;
  return s;
}

DamperSpec read_damper(const Table& t, const StructureSpec& structure) {
  DamperSpec d;
  t.allow_only({"container", "particles", "attach"});
  const std::string why = "in every [[damper]]";

  const Table c = t.need_sub("container",
                             "a table { shape = \"box\", size }, { shape = \"cylinder\", radius, "
                             "height[, axis] } or { shape = \"mesh\", file[, scale, curvature] }",
                             why);
  // The shapes as kernels/shapes.hpp lists them; each reads its own keys (a switch the build
  // holds complete).
  d.container.shape =
      static_cast<WallShape>(c.need_choice("shape", names_of<Shapes>(), "for a container"));
  switch (d.container.shape) {
    case WallShape::mesh: {
      c.allow_only({"shape", "file", "scale", "curvature"}, " for shape = \"mesh\"");
      const std::string mesh = "for shape = \"mesh\"";
      if (!c.has("file")) c.missing("file", "an STL file (ASCII or binary)", mesh);
      std::string file = *c.text("file");
      if (file.empty()) c.fail("file", "expected an STL file name, got \"\"");
      const double scale =
          c.real("scale", "a positive number (metres per file unit)", positive).value_or(1.0);
      const double curvature =
          c.real("curvature", "an angle in degrees, above 0 and below 90", [](double v) {
             return v > 0 && v < 90;
           }).value_or(kDefaultCurvature);
      // A relative file is the deck's neighbour.
      if (std::filesystem::path(file).is_relative())
        file =
            (std::filesystem::path(c.pos().file).parent_path() / file).lexically_normal().string();
      try {
        d.container.mesh = load_mesh(file, scale, curvature);
      } catch (const InputError& e) {
        c.fail("file", e.what());
      }
      break;
    }
    case WallShape::box: {
      c.allow_only({"shape", "size"}, " for shape = \"box\"");
      const std::string expected = "3 positive edge lengths [a, b, c] (m)";
      if (!c.has("size")) c.missing("size", expected, "for shape = \"box\"");
      d.container.size = *c.vec3("size", expected, positive);
      break;
    }
    case WallShape::cylinder: {
      c.allow_only({"shape", "radius", "height", "axis"}, " for shape = \"cylinder\"");
      const std::string cylinder = "for shape = \"cylinder\"";
      d.container.radius = c.need_real("radius", "a positive number (m)", positive, cylinder);
      d.container.height = c.need_real("height", "a positive number (m)", positive, cylinder);
      d.container.axis = c.direction("axis").value_or(d.container.axis);
      break;
    }
  }

  const Table p = t.need_sub("particles", "a table { count, diameter, density }", why);
  p.allow_only({"count", "diameter", "diameters", "diameter_range", "density", "seed", "fill"});
  ParticleSpec& ps = d.particles;
  ps.count = static_cast<int>(p.need_integer("count", 1, kMaxParticles, "", "for particles"));
  const int sizes = int(p.has("diameter")) + int(p.has("diameters")) + int(p.has("diameter_range"));
  if (sizes == 0)
    p.missing("diameter", "a positive number (m) (or diameters or diameter_range)",
              "for particles");
  if (sizes > 1)
    p.fail(p.has("diameter_range") ? "diameter_range" : "diameters",
           "give only one of diameter, diameters and diameter_range");
  ps.diameter = p.real("diameter", "a positive number (m)", positive).value_or(0);
  ps.diameters = p.reals("diameters", 0, "a non-empty array of positive numbers (m)", positive)
                     .value_or(std::vector<double>{});
  const std::string range = "two positive numbers [min, max] with min <= max (m)";
  if (const auto minmax = p.reals("diameter_range", 2, range, positive)) {
    if ((*minmax)[0] > (*minmax)[1])
      p.fail("diameter_range", "expected " + range + ", got [" + show((*minmax)[0]) + ", " +
                                   show((*minmax)[1]) + "]");
    ps.diameter_min = (*minmax)[0];
    ps.diameter_max = (*minmax)[1];
  }
  ps.density = p.need_real("density", "a positive number (kg/m^3)", positive, "for particles");
  ps.seed = static_cast<std::uint64_t>(
      p.integer("seed", 0, std::numeric_limits<std::int64_t>::max()).value_or(1));
  if (const auto fill = p.choice("fill", {"random", "lattice"}))
    ps.fill = *fill == 0 ? Fill::random : Fill::lattice;

  const std::string attach_kinds = "a table { node = K } or { x = position along the beam (m) }";
  const auto attach = t.sub("attach", attach_kinds);
  if (structure.kind != StructureKind::beam) {
    if (attach)
      t.fail("attach",
             "only a beam structure takes attach (an sdof carries its dampers on its "
             "mass; a prescribed motion moves them directly)");
    return d;
  }
  if (!attach) t.missing("attach", attach_kinds, "for a beam structure");
  attach->allow_only({"node", "x"});
  if (attach->has("node") == attach->has("x"))
    t.fail("attach", "expected " + attach_kinds + " (exactly one of node and x)");
  d.attach_node = static_cast<int>(
      attach->integer("node", 0, structure.beam.elements, "(node index)").value_or(-1));
  if (attach->has("x")) {
    const std::string expected =
        "a position along the beam from 0 to " + show(structure.beam.length) + " (m)";
    const double x = *attach->real("x", expected, any_value);
    if (x < 0 || x > structure.beam.length) attach->wrong(*attach->node("x"), "x", expected);
    d.attach_x = x;
  }
  return d;
}

ContactSpec read_contact(const std::optional<Table>& t, const Table& top, bool has_particles) {
  ContactSpec c;
  if (t) {
    t->allow_only({"model", "tangential", "young", "poisson", "restitution", "friction",
                   "stiffness", "rolling_friction", "tolerance", "max_iterations", "rest_speed",
                   "recovery_speed"});
    std::vector<std::string_view> models = names_of<NormalLaws>();
    models.push_back("nonsmooth");
    if (const auto i = t->choice("model", models)) {
      c.nonsmooth = *i + 1 == models.size();
      if (!c.nonsmooth) c.model = static_cast<NormalModel>(*i);
    }
    // Each model's own keys: a rigid contact has no stiffness, moduli or tangential spring, and
    // a penalty law no impulse solver.
    const std::vector<const char*> penalty_keys = {"tangential", "young", "poisson", "stiffness",
                                                   "rolling_friction"};
    const std::vector<const char*> nonsmooth_keys = {"tolerance", "max_iterations", "rest_speed",
                                                     "recovery_speed"};
    for (const char* key : c.nonsmooth ? penalty_keys : nonsmooth_keys)
      if (t->has(key))
        t->fail(key, c.nonsmooth ? "not used by model = \"nonsmooth\" (rigid spheres: no "
                                   "stiffness, moduli, tangential spring or rolling resistance); "
                                   "remove it"
                                 : "used only by model = \"nonsmooth\"; remove it");
    c.tolerance = t->real("tolerance", "a positive number (m/s)", positive).value_or(0);
    c.max_iterations = static_cast<int>(
        t->integer("max_iterations", 1, 1000000, "(iterations a step)").value_or(0));
    c.rest_speed = t->real("rest_speed", "a positive number (m/s)", positive).value_or(0);
    c.recovery_speed = t->real("recovery_speed", "a positive number (m/s)", positive).value_or(0);
    if (const auto i = t->choice("tangential", names_of<TangentialLaws>()))
      c.tangential = static_cast<TangentialModel>(*i);
    c.young = t->real("young", "a positive number (Pa)", positive).value_or(c.young);
    c.poisson = t->real("poisson", "a number in (-1, 0.5)", poisson_range).value_or(c.poisson);
    c.restitution =
        t->real("restitution", "a number in (0, 1]", fraction_range).value_or(c.restitution);
    c.friction = t->real("friction", "a non-negative number", non_negative).value_or(c.friction);
    c.stiffness = t->real("stiffness", "a positive number (N/m)", positive).value_or(c.stiffness);
    c.rolling_friction = t->real("rolling_friction", "a non-negative number", non_negative)
                             .value_or(c.rolling_friction);
  }
  if (!has_particles) return c;
  const Table& where = t ? *t : top;
  const std::string prefix = t ? "" : "contact.";
  // Each law names the keys it cannot run without.
  auto require = [&](const MissingKey& m, const char* law_key, const char* law) {
    if (m.key)
      where.missing(prefix + m.key, m.expected,
                    std::string("for ") + law_key + " = \"" + law + "\"");
  };
  if (c.nonsmooth) return c;  // restitution and friction have defaults
  with_normal_law(
      c.model, [&](auto law) { require(decltype(law)::missing(c), "model", decltype(law)::name); });
  with_tangential_law(c.tangential, [&](auto law) {
    require(decltype(law)::missing(c), "tangential", decltype(law)::name);
  });
  return c;
}

ExcitationSpec read_excitation(const Table& t) {
  ExcitationSpec e;
  Names kinds;
  for (const ExcitationTraits& k : kExcitations) kinds.push_back(k.name);
  const ExcitationTraits& kind = kExcitations[t.need_choice("kind", kinds, "in [excitation]")];
  e.kind = kind.kind;
  kind.read(t, e);
  return e;
}

CouplingSpec read_coupling(const Table& t) {
  CouplingSpec c;
  t.allow_only({"scheme", "every", "tolerance", "max_iterations"});
  const CouplingScheme schemes[] = {CouplingScheme::loose, CouplingScheme::interleaved,
                                    CouplingScheme::tight};
  if (const auto i = t.choice("scheme", {"loose", "interleaved", "tight"})) c.scheme = schemes[*i];
  c.every = static_cast<int>(t.integer("every", 1, 1'000'000, "(DEM steps)").value_or(c.every));
  c.tolerance = t.real("tolerance", "a positive number", positive).value_or(c.tolerance);
  c.max_iterations =
      static_cast<int>(t.integer("max_iterations", 1, 10'000).value_or(c.max_iterations));
  return c;
}

SolverSpec read_solver(const Table& t) {
  SolverSpec s;
  t.allow_only({"dt", "dt_safety", "backend", "allow_unstable", "threads"});
  const std::string dt_expected = "\"auto\" or a positive number (s)";
  const toml::node* dt = t.node("dt");
  if (dt && dt->is_string()) {
    if (*t.text("dt") != "auto") t.wrong(*dt, "dt", dt_expected);
  } else {
    s.dt = t.real("dt", dt_expected, positive).value_or(0);  // 0 = auto
  }
  s.dt_safety = t.real("dt_safety", "a number in (0, 1]", fraction_range).value_or(s.dt_safety);
  const Backend backends[] = {Backend::automatic, Backend::cpu, Backend::cuda};
  if (const auto i = t.choice("backend", {"auto", "cpu", "cuda"})) s.backend = backends[*i];
  s.allow_unstable = t.boolean("allow_unstable").value_or(s.allow_unstable);
  s.threads = static_cast<int>(t.integer("threads", 0, 4096).value_or(s.threads));
  return s;
}

BedSpec read_bed(const std::optional<Table>& t, bool gravity_on_particles) {
  BedSpec b;
  b.settle = gravity_on_particles;
  if (!t) return b;
  t->allow_only({"settle", "speed", "max_time", "file"});
  b.settle = t->boolean("settle").value_or(b.settle);
  b.speed = t->real("speed", "a positive number (m/s)", positive).value_or(b.speed);
  b.max_time = t->real("max_time", "a positive number (s)", positive).value_or(b.max_time);
  b.file = t->text("file").value_or("");
  if (t->has("file") && b.file.empty()) t->fail("file", "expected a file name, got \"\"");
  return b;
}

MapSpec read_map(const Table& t) {
  MapSpec m;
  t.allow_only({"amplitudes", "accelerations", "frequencies", "duration", "steps"});
  const std::string why = "in [map]";
  if (t.has("amplitudes") == t.has("accelerations"))
    t.fail(t.has("amplitudes") ? "accelerations" : "amplitudes",
           "give either amplitudes (m) or accelerations (g), one of them");
  if (t.has("amplitudes"))
    m.amplitudes = *t.reals("amplitudes", 0, "a non-empty array of positive numbers (m)", positive);
  else
    m.accelerations =
        *t.reals("accelerations", 0, "a non-empty array of positive numbers (g)", positive);
  if (!t.has("frequencies"))
    t.missing("frequencies", "a table { start, stop, step } or an array (Hz)", why);
  m.frequencies = read_frequencies(t);
  m.duration = t.real("duration", "a positive number (s)", positive).value_or(0);
  m.steps = static_cast<MapSteps>(t.choice("steps", {"independent", "up", "both"}).value_or(0));
  for (const auto& [key, values] :
       {std::pair{"amplitudes", m.amplitudes}, std::pair{"accelerations", m.accelerations},
        std::pair{"frequencies", m.frequencies}}) {
    std::vector<double> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
      t.fail(key, "expected each value once (a grid point runs once)");
  }
  const std::size_t points = (m.amplitudes.size() + m.accelerations.size()) * m.frequencies.size();
  if (points > kMaxFrequencies)
    t.fail("frequencies", "expected at most " + std::to_string(kMaxFrequencies) +
                              " grid points (amplitudes x frequencies), got " +
                              std::to_string(points));
  return m;
}

ClusterSpec read_cluster(const Table& t) {
  ClusterSpec c;
  t.allow_only({"sbatch"});
  c.sbatch = t.text("sbatch").value_or("");
  try {
    // Checked here, split where a job is submitted: a compute node that reads the deck again
    // may lack the login node's variables.
    sbatch_options(c.sbatch, "", false);
  } catch (const InputError& e) {
    t.fail("sbatch", e.what());
  }
  return c;
}

OutputSpec read_output(const Table& t) {
  OutputSpec o;
  t.allow_only({"file", "every", "energy", "particles"});
  o.file = t.text("file").value_or("");
  if (t.has("file") && o.file.empty()) t.fail("file", "expected a file name, got \"\"");
  if (o.file.find('\0') != std::string::npos)
    t.fail("file", "expected a file name, got one with a NUL character (it would cut the path)");
  o.every = t.real("every", "a non-negative number (s)", non_negative).value_or(o.every);
  o.energy = t.boolean("energy").value_or(o.energy);
  if (t.has("particles")) {
    const Table p = t.need_sub("particles", "a table { every = <s> }", "for particle snapshots");
    p.allow_only({"every"});
    if (!p.has("every")) p.missing("every", "a positive number (s)", "for particle snapshots");
    o.particles_every = *p.real("every", "a positive number (s)", positive);
  }
  return o;
}

// ---- Parameter sweeps ----

constexpr int kMaxSweepPoints = 10'000;

// One part of a sweep key: a table's name, with an index when it names one of [[name]] tables.
struct KeyPart {
  std::string name;
  std::optional<std::size_t> index;
};

std::optional<std::vector<KeyPart>> split_key(const std::string& key) {
  std::vector<KeyPart> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t dot = key.find('.', start);
    std::string part = key.substr(start, dot == std::string::npos ? dot : dot - start);
    KeyPart p;
    if (const std::size_t open = part.find('['); open != std::string::npos) {
      const std::string digits = part.substr(open + 1, part.size() - open - 2);
      if (part.back() != ']' || digits.empty() || digits.size() > 6 ||
          digits.find_first_not_of("0123456789") != std::string::npos)
        return std::nullopt;
      p.index = std::stoul(digits);
      part.erase(open);
    }
    if (part.empty() || part.find_first_of("[] \"") != std::string::npos) return std::nullopt;
    p.name = part;
    parts.push_back(p);
    if (dot == std::string::npos) return parts;
    start = dot + 1;
  }
}

std::string sweep_name(const std::string& key) {
  return "sweep.\"" + key + "\"";
}

// A node as TOML writes it (values of a sweep, for names and tables).
// A value as a reader would write it: floats by show_real (0.8, not toml++'s
// 0.80000000000000004), arrays element by element.
std::string written(const toml::node& node) {
  if (const auto* f = node.as_floating_point()) return show_real(f->get());
  if (const auto* a = node.as_array()) {
    std::string text = "[";
    for (std::size_t i = 0; i < a->size(); ++i) text += (i ? ", " : "") + written((*a)[i]);
    return text + "]";
  }
  std::ostringstream s;
  node.visit([&](const auto& n) { s << n; });
  return s.str();
}

// Every value of a parsed deck by its dotted name ("damper[0].container.size"), as written().
void flatten(const toml::node& node, const std::string& key,
             std::map<std::string, std::string>& out) {
  if (const auto* t = node.as_table()) {
    for (auto&& [name, value] : *t)
      flatten(value, key.empty() ? std::string(name.str()) : key + "." + std::string(name.str()),
              out);
  } else if (const auto* a = node.as_array(); a && !a->empty() && a->is_array_of_tables()) {
    for (std::size_t i = 0; i < a->size(); ++i)
      flatten((*a)[i], key + "[" + std::to_string(i) + "]", out);
  } else {
    out[key] = written(node);
  }
}

SweepSpec read_sweep(const toml::table& table, const std::string& path) {
  // Deck order, not the table's (alphabetical) order.
  std::vector<std::pair<const toml::key*, const toml::node*>> entries;
  for (auto&& [k, node] : table) entries.emplace_back(&k, &node);
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    const auto& p = a.first->source().begin;
    const auto& q = b.first->source().begin;
    return p.line != q.line ? p.line < q.line : p.column < q.column;
  });
  SweepSpec sweep;
  double points = 1;
  for (const auto& [k, node] : entries) {
    const std::string key(k->str());
    const SourcePos pos = to_pos(path, k->source());
    const auto parts = split_key(key);
    if (!parts)
      throw InputError(pos, sweep_name(key),
                       "expected a deck key such as \"damper.particles.count\" or "
                       "\"damper[1].container.size\"");
    if (parts->front().name == "sweep" || parts->size() < 2)
      throw InputError(pos, sweep_name(key),
                       "expected a key inside a deck table, such as \"excitation.amplitude\"");
    // Two keys overlap when one names a place the other also sets ("damper.x" and
    // "damper[1].x", or "damper.particles" and "damper.particles.count").
    for (const std::string& other : sweep.keys) {
      const auto theirs = *split_key(other);
      bool overlap = true;
      for (std::size_t i = 0; overlap && i < std::min(parts->size(), theirs.size()); ++i)
        overlap = (*parts)[i].name == theirs[i].name &&
                  (!(*parts)[i].index || !theirs[i].index || (*parts)[i].index == theirs[i].index);
      if (overlap)
        throw InputError(pos, sweep_name(key),
                         "overlaps the sweep key \"" + other + "\"; sweep one or the other");
    }
    const toml::array* values = node->as_array();
    if (!values || values->empty())
      throw InputError(to_pos(path, node->source()), sweep_name(key),
                       "expected an array of the values to sweep, e.g. [150, 200, 250], got " +
                           (values ? std::string("[]") : describe(*node)));
    sweep.keys.push_back(key);
    sweep.values.emplace_back();
    for (const toml::node& value : *values) {
      std::string text = written(value);  // on one line, for labels and deck comments
      std::replace(text.begin(), text.end(), '\n', ' ');
      sweep.values.back().push_back(text);
    }
    points *= static_cast<double>(values->size());
    if (points > kMaxSweepPoints)
      throw InputError(pos, sweep_name(key),
                       "the sweep has more than " + std::to_string(kMaxSweepPoints) + " points");
  }
  return sweep;
}

// Puts value(key) at the place a sweep key names, below `table`: every [[name]] table when the
// key gives no index. Missing tables are created; the value's node keeps its position in the
// deck's [sweep] table, so that errors about it point there.
using MakeValue = std::function<void(toml::table&, const KeyPart&)>;
void assign(toml::table& table, const std::vector<KeyPart>& parts, std::size_t depth,
            const toml::key& sweep_key, const std::string& path, const MakeValue& put) {
  const KeyPart& part = parts[depth];
  std::string name;
  for (std::size_t i = 0; i <= depth; ++i) name += (i ? "." : "") + parts[i].name;
  auto fail = [&](const std::string& what) {
    throw InputError(to_pos(path, sweep_key.source()), sweep_name(std::string(sweep_key.str())),
                     "'" + name + "' " + what);
  };
  const bool last = depth + 1 == parts.size();
  if (last && !part.index) return put(table, part);
  if (last) fail("is a table of the deck; name a key inside it");
  toml::node* node = table.get(part.name);
  if (!node) {
    if (part.index) fail("does not exist: the deck has no [[" + part.name + "]] tables");
    node = &table.insert(toml::key(part.name, sweep_key.source()), toml::table{}).first->second;
  }
  if (toml::array* array = node->as_array(); array && array->is_array_of_tables()) {
    if (part.index && *part.index >= array->size())
      fail("does not exist: the deck has " + std::to_string(array->size()) + " [[" + part.name +
           "]] tables, numbered from 0");
    for (std::size_t i = 0; i < array->size(); ++i)
      if (!part.index || *part.index == i)
        assign(*(*array)[i].as_table(), parts, depth + 1, sweep_key, path, put);
    return;
  }
  if (part.index) fail("is not an array of [[" + part.name + "]] tables");
  toml::table* sub = node->as_table();
  if (!sub) fail("is a value, not a table");
  assign(*sub, parts, depth + 1, sweep_key, path, put);
}

}  // namespace

int SweepSpec::points() const {
  if (keys.empty()) return 0;
  int n = 1;
  for (const auto& v : values) n *= static_cast<int>(v.size());
  return n;
}

std::vector<std::size_t> SweepSpec::choice(int point) const {
  std::vector<std::size_t> index(keys.size());
  std::size_t rest = static_cast<std::size_t>(point - 1);
  for (std::size_t k = keys.size(); k-- > 0;) {
    index[k] = rest % values[k].size();
    rest /= values[k].size();
  }
  return index;
}

std::string SweepSpec::describe(int point) const {
  const auto index = choice(point);
  std::string text;
  for (std::size_t k = 0; k < keys.size(); ++k)
    text += (k ? ", " : "") + keys[k] + " = " + values[k][index[k]];
  return text;
}

SourcePos Deck::where(const std::string& key) const {
  std::string name = key;
  while (!name.empty()) {
    if (const auto found = positions.find(name); found != positions.end()) return found->second;
    const std::size_t cut = name.find_last_of(".[");
    if (cut == std::string::npos) break;
    name.erase(cut);
  }
  return SourcePos{path, 0, 0};
}

namespace {

toml::table parse_root(const std::string& text, const std::string& path) {
  try {
    return toml::parse(std::string_view(text), std::string_view(path));
  } catch (const toml::parse_error& error) {
    std::string what(error.description());
    // toml++ quotes a redefined dotted key garbled ('"ststructure.mass" '); say it plainly.
    if (what.find("cannot redefine existing") != std::string::npos)
      what = "a key or table given twice: expected each key once";
    throw InputError(to_pos(path, error.source()), "", what.substr(0, 300));
  }
}

// How many realisations a frequency runs, resolved once the fill and the outputs are known
// (settle.realisations is 0 when not given). A random fill's response is chaotic and near
// resonance may lock into one of several regimes for hundreds of periods: two realisations are
// the fewest that show it (README). The energy ledger and the particle snapshots follow one
// continuous run: one realisation by default, several or independent starts refused.
void settle_realisations(Deck& deck) {
  ExcitationSpec& x = deck.excitation;
  const bool random_fill =
      std::any_of(deck.dampers.begin(), deck.dampers.end(),
                  [](const DamperSpec& d) { return d.particles.fill == Fill::random; });
  const char* one_run = deck.output.energy                ? "output.energy"
                        : deck.output.particles_every > 0 ? "output.particles"
                                                          : nullptr;
  const bool min_given = x.settle.realisations > 0;
  if (x.settle.realisations == 0) x.settle.realisations = random_fill && !one_run ? 2 : 1;
  // Fills are added where they disagree (near resonance) up to max_realisations.
  if (x.settle.max_realisations == 0)
    x.settle.max_realisations = random_fill && !one_run
                                    ? std::max(x.settle.realisations, kDefaultMaxFills)
                                    : x.settle.realisations;
  if (x.settle.max_realisations < x.settle.realisations) {
    const char* key = min_given && !deck.positions.count("excitation.settle.max_realisations")
                          ? "excitation.settle.realisations"
                          : "excitation.settle.max_realisations";
    throw InputError(
        deck.where(key), key,
        "expected settle.max_realisations (" + std::to_string(x.settle.max_realisations) +
            ") at least settle.realisations (" + std::to_string(x.settle.realisations) + ")");
  }
  if (x.settle.max_realisations > 1 && x.settle.realisations == 1 && !random_fill)
    throw InputError(deck.where("excitation.settle.max_realisations"),
                     "excitation.settle.max_realisations",
                     "expected 1: a lattice fill is the same for every seed, so added fills "
                     "need particles with fill = \"random\"");
  if (x.settle.realisations > 1 && !random_fill)
    throw InputError(deck.where("excitation.settle.realisations"), "excitation.settle.realisations",
                     "expected 1: a lattice fill is the same for every seed, so realisations "
                     "need particles with fill = \"random\"");
  if (one_run && (x.settle.max_realisations > 1 || x.start == FrequencyStart::independent))
    throw InputError(deck.where(one_run), one_run,
                     "not with settle.realisations > 1, settle.max_realisations > 1 or start = "
                     "\"independent\": it follows one continuous run");
}

Deck read_deck(const toml::table& root, const std::string& text, const std::string& path) {
  Deck deck;
  deck.path = path;
  deck.text = text;
  record_positions(root, "", path, deck.positions);

  const Table top(root, "", SourcePos{path, 0, 0});
  top.allow_only({"title", "structure", "damper", "contact", "gravity", "excitation", "bed",
                  "coupling", "solver", "output", "sweep", "map", "cluster"});
  deck.title = top.text("title").value_or("");
  const std::string table = "a table";

  // The excitation decides whether a structure may exist, so it is read first.
  deck.excitation = read_excitation(top.need_sub("excitation", table, "in every deck"));
  const bool prescribed = traits(deck.excitation.kind).moves_containers;
  const auto structure = top.sub("structure", table);
  if (prescribed && structure)
    top.fail("structure",
             "not allowed with excitation.kind = \"prescribed\" (the container "
             "moves as prescribed; remove [structure])");
  if (!prescribed && !structure)
    top.missing("structure", table,
                "unless excitation.kind = \"prescribed\" (the only kind without a structure)");
  if (structure) deck.structure = read_structure(*structure);

  if (const toml::node* node = root.get("damper")) {
    const toml::array* array = node->as_array();
    if (!array || !array->is_array_of_tables())
      top.wrong(*node, "damper", "[[damper]] tables (an array of tables)");
    std::int64_t total = 0;
    for (std::size_t i = 0; i < array->size(); ++i) {
      const std::string name = "damper[" + std::to_string(i) + "]";
      const Table damper(*(*array)[i].as_table(), name, deck.where(name));
      deck.dampers.push_back(read_damper(damper, deck.structure));
      total += deck.dampers.back().particles.count;
      if (total > kMaxParticles)
        throw InputError(deck.where(name + ".particles.count"), name + ".particles.count",
                         "expected at most " + std::to_string(kMaxParticles) +
                             " particles in all dampers together, got " + std::to_string(total));
    }
  }
  if (prescribed && deck.dampers.empty())
    top.missing("damper", "a [[damper]] table", "for excitation.kind = \"prescribed\"");

  deck.contact = read_contact(top.sub("contact", table), top, !deck.dampers.empty());
  if (const auto gravity = top.sub("gravity", table)) {
    gravity->allow_only({"vector"});
    const std::string expected = "a vector of 3 numbers [x, y, z] (m/s^2)";
    if (!gravity->has("vector")) gravity->missing("vector", expected, "in [gravity]");
    const Vec3 g = *gravity->vec3("vector", expected, any_value);
    if (norm(g) > 0) deck.gravity = g;  // a zero vector means no gravity
  }
  deck.bed = read_bed(top.sub("bed", table), deck.gravity.has_value() && !deck.dampers.empty());
  if (const auto coupling = top.sub("coupling", table)) deck.coupling = read_coupling(*coupling);
  if (const auto solver = top.sub("solver", table)) deck.solver = read_solver(*solver);
  if (const auto output = top.sub("output", table)) deck.output = read_output(*output);
  if (const auto map = top.sub("map", table)) deck.map = read_map(*map);
  if (const auto cluster = top.sub("cluster", table)) deck.cluster = read_cluster(*cluster);
  settle_realisations(deck);
  if (const toml::node* sweep = root.get("sweep")) {
    if (!sweep->as_table()) top.wrong(*sweep, "sweep", table);
    deck.sweep = read_sweep(*sweep->as_table(), path);
    if (deck.map.given())
      top.fail("map", "not with a [sweep] table: a map is of one damper (remove one of them)");
  }
  return deck;
}

}  // namespace

Deck parse_deck(const std::string& text, const std::string& path) {
  return read_deck(parse_root(text, path), text, path);
}

std::vector<std::string> sbatch_options(const std::string& text, const std::string& what,
                                        bool defined) {
  const std::string named = what.empty() ? "" : what + ": ";
  wordexp_t words;
  const int rc = wordexp(text.c_str(), &words, WRDE_NOCMD | (defined ? WRDE_UNDEF : 0));
  if (rc != 0) {
    if (rc == WRDE_NOSPACE) wordfree(&words);
    throw InputError(named + "expected sbatch options as a shell would split them, got '" + text +
                     "' (" +
                     (rc == WRDE_BADCHAR  ? "a | & ; < > ( ) { } or newline outside quotes"
                      : rc == WRDE_CMDSUB ? "a command substitution"
                      : rc == WRDE_BADVAL ? "an undefined variable"
                      : rc == WRDE_SYNTAX ? "unbalanced quotes"
                                          : "cannot be split") +
                     ")");
  }
  std::vector<std::string> options(words.we_wordv, words.we_wordv + words.we_wordc);
  wordfree(&words);
  for (const std::string& o : options) {
    for (const char* own : {"--array", "-a", "--wrap", "--parsable", "--dependency", "-d"}) {
      const std::string name = own;
      if (o == name || o.rfind(name + "=", 0) == 0 || (name.size() == 2 && o.rfind(name, 0) == 0))
        throw InputError(named + o +
                         " is set by pdsim sweep --slurm itself (the array of points, the "
                         "collect job after it); leave it out");
    }
  }
  if (!options.empty() && options.front().rfind('-', 0) != 0)  // later words may be values
    throw InputError(named + "expected options starting with -, got '" + options.front() + "'");
  return options;
}

std::vector<DeckChange> deck_changes(const std::string& before, const std::string& after) {
  std::map<std::string, std::string> was, now;
  flatten(parse_root(before, "(before)"), "", was);
  flatten(parse_root(after, "(after)"), "", now);
  std::vector<DeckChange> changes;
  for (const auto& [key, value] : now)
    if (const auto it = was.find(key); it == was.end() || it->second != value)
      changes.push_back({key, it == was.end() ? "absent" : it->second, value});
  for (const auto& [key, value] : was)
    if (!now.count(key)) changes.push_back({key, value, "absent"});
  std::sort(changes.begin(), changes.end(),
            [](const DeckChange& a, const DeckChange& b) { return a.key < b.key; });
  // pdsim's own notes, which carry a sweep point's values, a map run's motion or --snapshots
  // (sweep_point(), damper_map.cpp's run_text(), with_snapshots()); a user's comment is
  // layout, whatever it says.
  const auto notes = [](const std::string& text) {
    std::string found;
    std::istringstream lines(text);
    for (std::string line; std::getline(lines, line);)
      for (const char* note : {"# sweep point ", "# pdsim map: ", "# pdsim run --snapshots "})
        if (line.rfind(note, 0) == 0)
          found += (found.empty() ? "\"" : "; \"") + line.substr(2) + "\"";
    return found.empty() ? std::string("none") : found;
  };
  if (notes(before) != notes(after))
    changes.push_back({"pdsim's note", notes(before), notes(after)});
  return changes;
}

Deck sweep_point(const Deck& deck, int point) {
  const int points = deck.sweep.points();
  if (points == 0) throw InputError(deck.path + ": the deck has no [sweep] table, so no points");
  if (point < 1 || point > points)
    throw InputError(deck.path + ": sweep point " + std::to_string(point) +
                     " does not exist; the [sweep] table has points 1 to " +
                     std::to_string(points));
  toml::table root = parse_root(deck.text, deck.path);
  const toml::table& sweep = *root.get("sweep")->as_table();
  const auto index = deck.sweep.choice(point);
  for (std::size_t k = 0; k < deck.sweep.keys.size(); ++k) {
    const std::string& key = deck.sweep.keys[k];
    const toml::key& written_key = sweep.find(key)->first;
    // Each place gets the value's node moved out of a fresh parse: a move keeps the node's
    // position in the file (a copy would not), and a key may name several places.
    auto put = [&](toml::table& table, const KeyPart& part) {
      toml::table fresh = parse_root(deck.text, deck.path);
      toml::node& value = (*fresh.get("sweep")->as_table()->get(key)->as_array())[index[k]];
      table.erase(part.name);
      value.visit(
          [&](auto& v) { table.insert(toml::key(part.name, written_key.source()), std::move(v)); });
    };
    assign(root, *split_key(key), 0, written_key, deck.path, put);
  }
  root.erase("sweep");
  const std::string label = "sweep point " + std::to_string(point) + " of " +
                            std::to_string(points) + ": " + deck.sweep.describe(point);
  try {
    // The point's values join the deck text, its provenance in the output.
    Deck d = read_deck(root, deck.text + "\n# " + label + "\n", deck.path);
    d.sweep = deck.sweep;
    d.point = point;
    return d;
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (" + label + ")");
  }
}

Deck with_snapshots(Deck deck, double every) {
  deck.output.particles_every = every;
  // Resolved again with the snapshots on, as if the deck had asked for them.
  if (!deck.positions.count("excitation.settle.realisations"))
    deck.excitation.settle.realisations = 0;
  if (!deck.positions.count("excitation.settle.max_realisations"))
    deck.excitation.settle.max_realisations = 0;
  try {
    settle_realisations(deck);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (output.particles set by pdsim run --snapshots)");
  }
  std::ostringstream note;
  note.precision(17);
  note << "\n# pdsim run --snapshots " << every << "\n";
  deck.text += note.str();
  return deck;
}

Deck load_deck(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError(SourcePos{path, 0, 0}, "", "cannot open the deck file");
  std::string text(kMaxDeckBytes + 1, '\0');
  file.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(file.gcount()));
  if (text.size() > kMaxDeckBytes)
    throw InputError(SourcePos{path, 0, 0}, "",
                     "the deck file is larger than " + std::to_string(kMaxDeckBytes >> 20) +
                         " MiB; expected a TOML deck");
  return parse_deck(text, path);
}

}  // namespace pdsim

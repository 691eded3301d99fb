#include "src/identity.hpp"

#include <charconv>
#include <cstdint>
#include <cstring>
#include <algorithm>
#include <cstdio>
#include <map>
#include <type_traits>

namespace pdsim {

namespace {

// The shortest text that reads back as exactly v: two records agree only if their values do.
std::string exact(double v) {
  char text[32];
  const auto end = std::to_chars(text, text + sizeof text, v).ptr;
  return std::string(text, end);
}

std::string exact3(Vec3 v, const char* between = " ") {
  return exact(v.x) + between + exact(v.y) + between + exact(v.z);
}

// FNV-1a of the values' bytes, for what is too long to show (a mesh, a fill's positions).
class Hash {
 public:
  void add(double v) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char b : bytes) value_ = (value_ ^ b) * 1099511628211ull;
  }
  void add(Vec3 v) { add(v.x), add(v.y), add(v.z); }
  std::string text() const {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(value_));
    return hex;
  }

 private:
  std::uint64_t value_ = 1469598103934665603ull;
};

// "box size 0.05 x 0.05 x 0.05 m": the shape's name and what it says decides it.
std::string container_text(const EngineConfig& e) {
  std::string text = shape_name(e.shape);
  const auto add = [&](const char* name, const auto& value, const char* unit) {
    using T = std::decay_t<decltype(value)>;
    text += std::string(" ") + name + " ";
    if constexpr (std::is_same_v<T, Vec3>) {
      text += exact3(value, " x ");
    } else if constexpr (std::is_same_v<T, double>) {
      text += exact(value);
    } else {  // a list: its length and hash
      Hash h;
      for (double v : value) h.add(v);
      text += std::to_string(value.size()) + " numbers " + h.text();
    }
    if (*unit) text += std::string(" ") + unit;
  };
  with_shape(e.shape, [&](auto shape) { decltype(shape)::identity(e.geometry, add); });
  return text;
}

std::string diameters_text(const std::vector<double>& radius) {
  if (radius.empty()) return "none";
  double low = radius[0], high = radius[0];
  Hash h;
  for (double r : radius) low = std::min(low, r), high = std::max(high, r), h.add(r);
  if (low == high) return exact(2 * low) + " m";
  return exact(2 * low) + " to " + exact(2 * high) + " m, sizes " + h.text();
}

}  // namespace

// The contact constants by name: a field added to ContactParams stops the build here until it
// is named (or said to be derived).
static_assert(sizeof(ContactParams) == 13 * sizeof(double),
              "ContactParams changed: name its new field in scene_identity()");

Identity scene_identity(const Scene& scene, const BedSpec& bed) {
  Identity id;
  auto add = [&](std::string name, std::string value) {
    id.emplace_back(std::move(name), std::move(value));
  };
  add("gravity", scene.gravity ? exact3(*scene.gravity) + " m/s^2" : "none");
  const EngineConfig* first = scene.dampers.empty() ? nullptr : &scene.dampers.front().engine;
  const bool rigid = first && first->nonsmooth;
  // A penalty law's step follows its stiffness, the same for any motion; a rigid contact's
  // follows the motion, so it differs between a map's points by design and decides beds only.
  add(rigid ? "bed.dt" : "solver.dt", exact(scene.dt) + " s");
  if (first) {
    const auto name = [](auto law) { return std::string(decltype(law)::name); };
    if (rigid) {
      const NonsmoothParams& n = *first->nonsmooth;
      add("contact.model", "nonsmooth");
      add("contact.restitution", exact(n.restitution));
      add("contact.friction", exact(n.friction));
      add("contact.max_iterations", std::to_string(n.max_iterations));
      // How the walls move through a step (src/coupled_system.cpp): a run or map made before
      // prescribed walls moved at the chord's velocity is another model.
      add("contact.walls", "the chord's velocity under a prescribed motion, else the start's");
      // The thresholds the deck sets decide the model; derived ones follow each run's motion.
      const auto given = [](double v) { return v > 0 ? exact(v) + " m/s" : "derived"; };
      add("contact.rest_speed", given(scene.rest_speed_given));
      add("contact.recovery_speed", given(scene.recovery_speed_given));
      add("contact.tolerance", given(scene.tolerance_given));
      add("bed.contact.rest_speed", exact(n.rest_speed) + " m/s");
      add("bed.contact.recovery_speed", exact(n.recovery_speed) + " m/s");
      add("bed.contact.envelope", exact(n.envelope) + " m");
      add("bed.contact.tolerance", exact(n.tolerance) + " m/s");
    } else {
      const ContactParams& c = first->contact;
      add("contact.model", with_normal_law(first->normal, name));
      add("contact.tangential", with_tangential_law(first->tangential, name));
      add("contact.rolling", first->rolling ? "true" : "false");
      // The constants the laws read, derived from the deck's keys (src/scene.cpp); the damping
      // roots are derived from these when an engine is made.
      add("contact.linear_stiffness", exact(c.linear_stiffness) + " N/m");
      add("contact.damping_factor", exact(c.damping_factor));
      add("contact.hertz_modulus_pp", exact(c.hertz_modulus_pp) + " Pa");
      add("contact.hertz_modulus_pw", exact(c.hertz_modulus_pw) + " Pa");
      add("contact.shear_modulus_pp", exact(c.shear_modulus_pp) + " Pa");
      add("contact.shear_modulus_pw", exact(c.shear_modulus_pw) + " Pa");
      add("contact.tangential_ratio", exact(c.tangential_ratio));
      add("contact.friction", exact(c.friction));
      add("contact.rolling_friction", exact(c.rolling_friction));
    }
  }
  for (std::size_t k = 0; k < scene.dampers.size(); ++k) {
    const DamperScene& d = scene.dampers[k];
    const EngineConfig& e = d.engine;
    const std::string at = "damper[" + std::to_string(k) + "].";
    add(at + "container", container_text(e));
    if (!e.orientation.identity()) add(at + "container.axis", exact3(e.orientation.z));
    add(at + "particles.count", std::to_string(e.radius.size()));
    add(at + "particles.diameter", diameters_text(e.radius));
    add(at + "particles.density", exact(e.density) + " kg/m^3");
  }
  add("bed.settle", bed.settle ? "true" : "false");
  add("bed.speed", exact(bed.speed) + " m/s");
  add("bed.max_time", exact(bed.max_time) + " s");
  for (std::size_t k = 0; k < scene.dampers.size(); ++k) {
    const DamperScene& d = scene.dampers[k];
    Hash h;
    for (const ParticleState& p : d.engine.particles) h.add(p.position);
    add("bed.damper[" + std::to_string(k) + "].fill",
        "seed " + std::to_string(d.particles.seed) + ", positions " + h.text());
  }
  return id;
}

std::string identity_text(const Identity& identity) {
  std::string text;
  for (const auto& [name, value] : identity) text += name + " = " + value + "\n";
  return text;
}

Identity parse_identity(const std::string& text) {
  Identity id;
  std::size_t at = 0;
  while (at < text.size()) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(at, end - at);
    if (const std::size_t eq = line.find(" = "); eq != std::string::npos)
      id.emplace_back(line.substr(0, eq), line.substr(eq + 3));
    at = end + 1;
  }
  return id;
}

std::string identity_difference(const Identity& kept, const Identity& now, IdentityScope scope,
                                const std::string& kept_name, const std::string& now_name) {
  const auto in_scope = [&](const std::string& name) {
    return scope == IdentityScope::bed || name.rfind("bed.", 0) != 0;
  };
  const std::map<std::string, std::string> was(kept.begin(), kept.end());
  std::map<std::string, bool> seen;
  std::string out;
  auto differs = [&](const std::string& name, const std::string& a, const std::string& b) {
    out +=
        (out.empty() ? "" : "; ") + name + ": " + a + " " + kept_name + ", " + b + " " + now_name;
  };
  for (const auto& [name, value] : now) {
    if (!in_scope(name)) continue;
    seen[name] = true;
    const auto it = was.find(name);
    if (it == was.end())
      differs(name, "absent", value);
    else if (it->second != value)
      differs(name, it->second, value);
  }
  for (const auto& [name, value] : kept)
    if (in_scope(name) && !seen.count(name)) differs(name, value, "absent");
  return out;
}

}  // namespace pdsim

#include "src/bed_file.hpp"

#include "io/excitation.hpp"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <sstream>

namespace pdsim {

namespace {

// Damper d as the engines are made with it (not as the deck says), so that whatever decides it
// (a law's derived constant, the container's orientation) is in it without a line here; the
// numbers as an FNV-1a hash of their bytes, the fill's positions included when `fill`.
std::string damper_text(const DamperScene& d, bool fill) {
  const EngineConfig& e = d.engine;
  std::ostringstream s;
  s.precision(17);
  s << shape_name(e.shape) << " "
    << with_normal_law(e.normal, [](auto law) { return decltype(law)::name; }) << " "
    << with_tangential_law(e.tangential, [](auto law) { return decltype(law)::name; })
    << " rolling " << e.rolling << " particles " << e.radius.size();
  std::uint64_t hash = 1469598103934665603ull;
  auto mix = [&](double v) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char b : bytes) hash = (hash ^ b) * 1099511628211ull;
  };
  auto mix3 = [&](Vec3 v) { mix(v.x), mix(v.y), mix(v.z); };
  mix3(e.geometry.half_size), mix(e.geometry.radius);
  if (e.geometry.surface) {  // a mesh: its triangles and how they join
    for (double v : e.geometry.surface->triangle) mix(v);
    mix(e.geometry.surface->curvature);
  }
  mix3(e.orientation.x), mix3(e.orientation.y), mix3(e.orientation.z);
  mix3(e.gravity.value_or(Vec3{})), mix(e.density);
  // Every constant the kernels read, a field a law adds included.
  static_assert(sizeof(ContactParams) % sizeof(double) == 0, "ContactParams holds doubles");
  double constants[sizeof(ContactParams) / sizeof(double)];
  std::memcpy(constants, &e.contact, sizeof constants);
  for (double v : constants) mix(v);
  if (e.nonsmooth) {  // rigid contacts: the model's constants instead of the laws'
    const NonsmoothParams& n = *e.nonsmooth;
    s << " nonsmooth";
    for (double v : {n.restitution, n.friction, n.rest_speed, n.recovery_speed, n.envelope,
                     n.tolerance, double(n.max_iterations)})
      mix(v);
  }
  for (double r : e.radius) mix(r);
  if (fill)
    for (const ParticleState& p : e.particles) mix3(p.position);
  s << " " << hash;
  return s.str();
}

}  // namespace

std::string bed_fingerprint(const Scene& scene) {
  std::ostringstream s;
  s.precision(17);
  s << "dt " << scene.dt << " speed " << scene.bed.speed << " max_time " << scene.bed.max_time;
  for (const DamperScene& d : scene.dampers) s << " | " << damper_text(d, true);
  return s.str();
}

std::string damper_fingerprint(const Scene& scene) {
  std::string s;
  for (const DamperScene& d : scene.dampers) s += (s.empty() ? "" : " | ") + damper_text(d, false);
  return s;
}

std::optional<Results> read_bed_file(const Scene& scene, const SourcePos& where) {
  const std::string& file = scene.bed.file;
  if (file.empty() || !std::filesystem::exists(file)) return std::nullopt;
  Results saved;
  try {
    saved = read_results(file);
  } catch (const std::exception& e) {
    throw InputError(where, "bed.file",
                     "'" + file + "' is not a bed pdsim kept (" + e.what() +
                         "); delete it or name another file");
  }
  const double held =
      saved.meta_numbers.count("realisations") != 0 ? saved.meta_numbers.at("realisations") : 0.0;
  const int first = runs_points(scene.excitation) ? scene.excitation.settle.realisations : 1;
  const auto kept = saved.meta_text.find("bed_fingerprint");
  if (kept == saved.meta_text.end() || kept->second != bed_fingerprint(scene) || held < first)
    throw InputError(where, "bed.file",
                     "'" + file +
                         "' holds a bed settled for other particles, container, contact, "
                         "gravity, dt or realisations; delete it or name another file");
  return saved;
}

}  // namespace pdsim

#include "src/bed_file.hpp"

#include <cstdint>
#include <cstring>
#include <sstream>

namespace pdsim {

std::string bed_fingerprint(const Deck& deck, const Scene& scene) {
  std::ostringstream s;
  s.precision(17);
  s << "dt " << scene.dt << " speed " << deck.bed.speed << " max_time " << deck.bed.max_time;
  if (deck.gravity)
    s << " g " << deck.gravity->x << " " << deck.gravity->y << " " << deck.gravity->z;
  const ContactSpec& c = deck.contact;
  s << " contact " << int(c.model) << " " << int(c.tangential) << " " << c.young << " " << c.poisson
    << " " << c.restitution << " " << c.friction << " " << c.stiffness << " " << c.rolling_friction;
  for (const DamperScene& d : scene.dampers) {
    const EngineConfig& e = d.engine;
    s << " | " << int(e.shape) << " " << e.geometry.half_size.x << " " << e.geometry.half_size.y
      << " " << e.geometry.half_size.z << " " << e.density << " " << e.radius.size();
    if (!e.orientation.identity())  // (absent for the identity: older bed files still fit)
      s << " axis " << e.orientation.z.x << " " << e.orientation.z.y << " " << e.orientation.z.z;
    // The fill itself, as an FNV-1a hash of its radii and positions.
    std::uint64_t hash = 1469598103934665603ull;
    auto mix = [&](double v) {
      unsigned char bytes[sizeof v];
      std::memcpy(bytes, &v, sizeof v);
      for (unsigned char b : bytes) hash = (hash ^ b) * 1099511628211ull;
    };
    for (double r : e.radius) mix(r);
    for (const ParticleState& p : e.particles)
      mix(p.position.x), mix(p.position.y), mix(p.position.z);
    s << " " << hash;
  }
  return s.str();
}

}  // namespace pdsim

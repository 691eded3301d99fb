// Picks the Variant<...> instantiation a scene needs at start, so that the hot loop holds no
// branch on disabled physics. `make.template operator()<V>()` is called with the chosen type.
#pragma once

#include "kernels/engine.hpp"
#include "kernels/particle_step.hpp"

namespace pdsim {

// The step arguments fixed by the scene, the same for both backends; each engine keeps a copy
// and adds its own array views, the container and dt every step.
inline ParticleStepArgs scene_step_args(const EngineConfig& c) {
  ParticleStepArgs a{};
  a.count = static_cast<int>(c.particles.size());
  a.mono_radius = c.radius.at(0);  // read only by monodisperse variants
  a.mono = sphere_mass(a.mono_radius, c.density);
  a.contact = with_damping_roots(c.contact);
  a.geometry = c.geometry;
  a.gravity = c.gravity.value_or(Vec3{});
  return a;
}
inline bool is_polydisperse(const EngineConfig& c) {
  for (double r : c.radius)
    if (r != c.radius.front()) return true;
  return false;
}

namespace dispatch_detail {

template <class N, class T, bool R, bool G, bool P, WallShape S, class Make>
auto by_rotation(const EngineConfig& c, Make&& make) {
  if (c.rotating) return make.template operator()<Variant<N, T, R, G, P, S, true>>();
  return make.template operator()<Variant<N, T, R, G, P, S, false>>();
}

template <class N, class T, bool R, bool G, bool P, class Make>
auto by_shape(const EngineConfig& c, Make&& make) {
  return with_shape(c.shape, [&](auto shape) {
    return by_rotation<N, T, R, G, P, kind_of<decltype(shape)>>(c, make);
  });
}

template <class N, class T, bool R, bool G, class Make>
auto by_radii(const EngineConfig& c, Make&& make) {
  if (is_polydisperse(c)) return by_shape<N, T, R, G, true>(c, make);
  return by_shape<N, T, R, G, false>(c, make);
}

template <class N, class T, bool R, class Make>
auto by_gravity(const EngineConfig& c, Make&& make) {
  if (c.gravity) return by_radii<N, T, R, true>(c, make);
  return by_radii<N, T, R, false>(c, make);
}

// The laws and the rolling choice, then next.template operator()<N, T, R>().
template <class N, class T, class Next>
auto by_rolling(const EngineConfig& c, Next&& next) {
  if (c.rolling) return next.template operator()<N, T, true>();
  return next.template operator()<N, T, false>();
}

template <class N, class Next>
auto by_tangential(const EngineConfig& c, Next&& next) {
  return with_tangential_law(c.tangential,
                             [&](auto law) { return by_rolling<N, decltype(law)>(c, next); });
}

// Carries a choice of the laws and rolling on to the remaining choices.
template <class Make>
struct ByGravity {
  const EngineConfig& c;
  Make& make;
  template <class N, class T, bool R>
  auto operator()() const {
    return by_gravity<N, T, R>(c, make);
  }
};

}  // namespace dispatch_detail

// The first choices only: `next.template operator()<N, T, R>()` with the normal and tangential
// laws and the rolling flag (the CPU engines are compiled in one translation unit per choice).
template <class Next>
auto dispatch_laws(const EngineConfig& c, Next&& next) {
  return with_normal_law(
      c.normal, [&](auto law) { return dispatch_detail::by_tangential<decltype(law)>(c, next); });
}

template <class Make>
auto dispatch_variant(const EngineConfig& c, Make&& make) {
  return dispatch_laws(c, dispatch_detail::ByGravity<Make>{c, make});
}

template <class V>
std::string variant_string() {
  std::string s = std::string(V::Normal::name) + "/" + V::Tangential::name;
  if (V::kRolling) s += "/rolling";
  if (V::kGravity) s += "/gravity";
  s += V::kPolydisperse ? "/poly" : "/mono";
  s += std::string("/") + ShapeOf<V::kShape>::name;
  if (V::kRotating) s += "/rotating";
  return s;
}

// What an engine needs to know of its kernel variant outside the passes.
struct VariantInfo {
  std::string name;  // variant_string<V>()
  bool history = false, polydisperse = false;
  int pair_doubles = 0;
};

template <class V>
VariantInfo variant_info() {
  return {variant_string<V>(), V::Tangential::kHistory, V::kPolydisperse, pair_doubles<V>()};
}

}  // namespace pdsim

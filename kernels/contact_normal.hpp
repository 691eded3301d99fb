// The normal contact laws, each in its header (normal_linear.hpp, normal_hertz.hpp: response,
// constants, time step, deck keys). A new law is its header, an include, a name in NormalModel
// and a line in NormalLaws here; the CPU engine's translation units and the dispatch follow.
#pragma once

#include <cmath>
#include <tuple>

#include "kernels/normal_hertz.hpp"
#include "kernels/normal_linear.hpp"
#include "kernels/type_list.hpp"

namespace pdsim {

enum class NormalModel { linear, hertz };
using NormalLaws = std::tuple<LinearNormal, HertzNormal>;  // in the order of NormalModel

// f(Law{}) with the law of m (host code).
template <class F>
auto with_normal_law(NormalModel m, F&& f) {
  return with_type<NormalLaws>(m, f);
}

// `p` with the Hertz damping constants derived from its moduli and damping factor.
inline ContactParams with_damping_roots(ContactParams p) {
  p.normal_root_pp = p.damping_factor * std::sqrt(2.0 * p.hertz_modulus_pp);
  p.normal_root_pw = p.damping_factor * std::sqrt(2.0 * p.hertz_modulus_pw);
  p.tangent_root_pp = p.damping_factor * std::sqrt(8.0 * p.shear_modulus_pp);
  p.tangent_root_pw = p.damping_factor * std::sqrt(8.0 * p.shear_modulus_pw);
  return p;
}

}  // namespace pdsim

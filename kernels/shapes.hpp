// Every container shape: its name, the deck's words for it and its header. A new shape is its
// header (geometry, walls, near-wall test, fill test, volume, size limit and wireframe, as
// shape_box.hpp), a name in WallShape and a line in Shapes (the same place), its keys'
// fields in ContainerSpec, and the reading of those keys in io/deck.cpp.
#pragma once

#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>

#include "kernels/shape_box.hpp"
#include "kernels/shape_cylinder.hpp"

namespace pdsim {

enum class WallShape : int { box, cylinder };
using Shapes = std::tuple<BoxShape, CylinderShape>;  // in the order of WallShape

// A container as the deck gives it, SI units.
struct ContainerSpec {
  WallShape shape = WallShape::box;
  Vec3 size;           // box: full edge lengths, m
  double radius = 0;   // cylinder, m
  double height = 0;   // cylinder, m
  Vec3 axis{0, 0, 1};  // cylinder: its axis in the world at rest (unit)
};

template <WallShape S>
using ShapeOf = std::tuple_element_t<static_cast<std::size_t>(S), Shapes>;

namespace shape_detail {
template <class S, std::size_t K = 0>
constexpr WallShape kind_of() {
  if constexpr (std::is_same_v<S, std::tuple_element_t<K, Shapes>>)
    return static_cast<WallShape>(K);
  else
    return kind_of<S, K + 1>();
}
template <class F, std::size_t... K>
auto with_shape(WallShape s, F& f, std::index_sequence<K...>) {
  using Result = decltype(f(std::tuple_element_t<0, Shapes>{}));
  if constexpr (std::is_void_v<Result>) {
    ((static_cast<std::size_t>(s) == K ? f(std::tuple_element_t<K, Shapes>{}) : void()), ...);
  } else {
    Result out{};
    ((static_cast<std::size_t>(s) == K ? void(out = f(std::tuple_element_t<K, Shapes>{})) : void()),
     ...);
    return out;
  }
}
}  // namespace shape_detail

// The WallShape of a shape type.
template <class S>
constexpr WallShape kind_of = shape_detail::kind_of<S>();

// f(Shape{}) with the shape type of s (host code): [](auto shape) { decltype(shape)::volume(g); }
template <class F>
auto with_shape(WallShape s, F&& f) {
  return shape_detail::with_shape(s, f, std::make_index_sequence<std::tuple_size_v<Shapes>>());
}

inline const char* shape_name(WallShape s) {
  return with_shape(s, [](auto shape) { return decltype(shape)::name; });
}
// The shape named `name`, as decks and result files name them; throws std::invalid_argument.
inline WallShape shape_named(const std::string& name) {
  for (std::size_t k = 0; k < std::tuple_size_v<Shapes>; ++k)
    if (name == shape_name(static_cast<WallShape>(k))) return static_cast<WallShape>(k);
  throw std::invalid_argument("no container shape named '" + name + "'");
}

}  // namespace pdsim

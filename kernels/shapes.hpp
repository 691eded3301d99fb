// Every container shape: its name, the deck's words for it and its header. A new shape is its
// header (geometry, walls, near-wall test, fill test, volume, size limit, wireframe and what
// identifies it, as shape_box.hpp), a name in WallShape and a line in Shapes (the same place),
// its keys' fields in ContainerSpec, and the reading of those keys in io/deck.cpp (the shape
// names there come from Shapes).
#pragma once

#include <memory>
#include <string>
#include <tuple>

#include "kernels/shape_box.hpp"
#include "kernels/shape_cylinder.hpp"
#include "kernels/shape_mesh.hpp"
#include "kernels/type_list.hpp"

namespace pdsim {

enum class WallShape : int { box, cylinder, mesh };
using Shapes = std::tuple<BoxShape, CylinderShape, MeshShape>;  // in the order of WallShape

// A container as the deck gives it, SI units.
struct ContainerSpec {
  WallShape shape = WallShape::box;
  Vec3 size;                                // box: full edge lengths, m
  double radius = 0;                        // cylinder, m
  double height = 0;                        // cylinder, m
  Vec3 axis{0, 0, 1};                       // cylinder: its axis in the world at rest (unit)
  std::shared_ptr<const MeshSurface> mesh;  // mesh: the surface read from its file
};

template <WallShape S>
using ShapeOf = std::tuple_element_t<static_cast<std::size_t>(S), Shapes>;

// f(Shape{}) with the shape type of s (host code): [](auto shape) { decltype(shape)::volume(g); }
template <class F>
auto with_shape(WallShape s, F&& f) {
  return with_type<Shapes>(s, f);
}
// The WallShape of a shape type.
template <class S>
constexpr WallShape kind_of = place_of<Shapes, WallShape, S>;

inline const char* shape_name(WallShape s) {
  return name_of<Shapes>(s);
}
// The shape named `name`, as decks and result files name them; throws std::invalid_argument.
inline WallShape shape_named(const std::string& name) {
  return named<Shapes, WallShape>(name);
}

}  // namespace pdsim

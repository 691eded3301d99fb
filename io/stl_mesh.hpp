// A container cavity given as a triangle mesh in an STL file (ASCII or binary): read, checked
// closed, consistently oriented and free of self-intersections, and turned outward. CGAL
// (Debian's libcgal-dev) reads the file and answers the geometric questions a hand-written test
// gets wrong at the edges: self-intersection, orientation, inside or outside.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "kernels/shape_mesh.hpp"

namespace pdsim {

// Surfaces of a mesh container meet at edges that bend by at least this much, degrees
// (`curvature` in a deck): the triangles of a flat face, split any way, are one surface.
constexpr double kDefaultCurvature = 1.0;

// Reads `path` (coordinates times `scale`, to metres). Throws InputError naming the file and
// what is wrong: unreadable or empty, a coordinate that is not a number, an edge of one
// triangle only (not closed: the first such edge, by its end points), an edge that two
// triangles run the same way (a flipped triangle: the first), an edge of more than two
// triangles, triangles that cross each other, more than one closed surface (a shell inside
// another, or beside it), or no volume.
TriangleMesh read_stl(const std::string& path, double scale);

// A mesh container from `path`: read_stl(), its surfaces (mesh_surface()), the widest sphere
// that fits, and the fill's inside test. Throws InputError as read_stl() does.
std::shared_ptr<const MeshSurface> load_mesh(const std::string& path, double scale,
                                             double curvature_degrees);

// Whether `p` lies strictly inside the closed mesh (points on its surface count as outside),
// and how far it is from the surface.
class MeshInside {
 public:
  explicit MeshInside(const TriangleMesh& mesh);
  ~MeshInside();
  MeshInside(const MeshInside&) = delete;
  MeshInside& operator=(const MeshInside&) = delete;
  bool operator()(const Vec3& p) const;
  double distance(const Vec3& p) const;  // to the surface, m

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

}  // namespace pdsim

// A container cavity given as a triangle mesh in an STL file (ASCII or binary): read, checked
// closed, consistently oriented and free of self-intersections, and turned outward. CGAL
// (Debian's libcgal-dev) reads the file and answers the geometric questions a hand-written test
// gets wrong at the edges: self-intersection, orientation, inside or outside.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "kernels/vec3.hpp"

namespace pdsim {

struct TriangleMesh {
  std::vector<Vec3> vertices;                 // m (the file's units times the scale)
  std::vector<std::array<int, 3>> triangles;  // counter-clockwise seen from outside
  double volume = 0;                          // m^3
  Vec3 low, high;                             // bounding box, m
};

// Reads `path` (coordinates times `scale`, to metres). Throws InputError naming the file and
// what is wrong: unreadable or empty, a coordinate that is not a number, an edge of one
// triangle only (not closed: the first such edge, by its end points), an edge that two
// triangles run the same way (a flipped triangle: the first), an edge of more than two
// triangles, triangles that cross each other, or no volume.
TriangleMesh read_stl(const std::string& path, double scale);

// Whether `p` lies strictly inside the closed mesh; points on its surface count as outside.
class MeshInside {
 public:
  explicit MeshInside(const TriangleMesh& mesh);
  ~MeshInside();
  MeshInside(const MeshInside&) = delete;
  MeshInside& operator=(const MeshInside&) = delete;
  bool operator()(const Vec3& p) const;

 private:
  struct Tree;
  std::unique_ptr<Tree> tree_;
};

}  // namespace pdsim

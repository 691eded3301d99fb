#include "io/stl_mesh.hpp"

#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/IO/STL.h>
#include <CGAL/Polygon_mesh_processing/connected_components.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Side_of_triangle_mesh.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "kernels/errors.hpp"

namespace pdsim {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
namespace pmp = CGAL::Polygon_mesh_processing;

std::string where(const Point& p) {
  std::ostringstream s;
  s.precision(9);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

Mesh surface(const TriangleMesh& m) {
  std::vector<Point> points;
  for (const Vec3& v : m.vertices) points.emplace_back(v.x, v.y, v.z);
  std::vector<std::array<std::size_t, 3>> faces;
  for (const auto& t : m.triangles)
    faces.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  Mesh mesh;
  pmp::polygon_soup_to_polygon_mesh(points, faces, mesh);
  return mesh;
}

}  // namespace

TriangleMesh read_stl(const std::string& path, double scale) {
  std::error_code ignored;
  if (!std::filesystem::is_regular_file(path, ignored))
    throw InputError(path + ": no such STL file");
  if (std::filesystem::file_size(path, ignored) == 0)
    throw InputError(path + ": the STL file is empty (0 bytes)");
  std::vector<Point> points;
  std::vector<std::array<std::size_t, 3>> faces;
  if (!CGAL::IO::read_STL(path, points, faces, CGAL::parameters::verbose(false)))
    throw InputError(path + ": cannot be read as an STL file (ASCII or binary)");
  if (faces.empty()) throw InputError(path + ": the STL file holds no triangles");
  for (const Point& p : points)
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z()))
      throw InputError(path + ": a vertex " + where(p) + " is not a number");
  // Each edge of a closed, consistently oriented surface is run once each way, by two
  // triangles; the first triangle that breaks this is named (1-based, in the file's order).
  std::map<std::pair<std::size_t, std::size_t>, int> runs;
  for (const auto& f : faces)
    for (int e = 0; e < 3; ++e) ++runs[{f[e], f[(e + 1) % 3]}];
  for (std::size_t k = 0; k < faces.size(); ++k) {
    const auto& f = faces[k];
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
      throw InputError(path + ": triangle " + std::to_string(k + 1) +
                       " has two corners at the same point " +
                       where(points[f[0] == f[1] ? f[0] : f[2]]));
    for (int e = 0; e < 3; ++e) {
      const std::size_t a = f[e], b = f[(e + 1) % 3];
      const std::string edge = "the edge from " + where(points[a]) + " to " + where(points[b]);
      const int same = runs[{a, b}], opposite = runs.count({b, a}) ? runs[{b, a}] : 0;
      const std::string triangle = "triangle " + std::to_string(k + 1);
      if (opposite == 0 && same == 1)
        throw InputError(path + ": not closed: " + edge + " belongs to " + triangle + " only");
      if (same + opposite > 2)
        throw InputError(path + ": " + edge + " of " + triangle + " belongs to " +
                         std::to_string(same + opposite) + " triangles (expected 2)");
      if (same > 1)
        throw InputError(path + ": not consistently oriented: " + triangle + " runs " + edge +
                         " the same way as its neighbour (one of them is flipped)");
    }
  }
  TriangleMesh m;
  for (const Point& p : points) m.vertices.push_back({scale * p.x(), scale * p.y(), scale * p.z()});
  for (const auto& f : faces) m.triangles.push_back({int(f[0]), int(f[1]), int(f[2])});
  Mesh mesh = surface(m);
  if (pmp::does_self_intersect(mesh))
    throw InputError(path + ": its triangles cross each other (a self-intersecting surface)");
  // A second shell, inside the first (an obstacle) or beside it (a second cavity), would be
  // taken as more cavity: its volume added, its walls facing the wrong way for an obstacle.
  auto shell = mesh.add_property_map<Mesh::Face_index, std::size_t>("f:shell").first;
  if (const std::size_t shells = pmp::connected_components(mesh, shell); shells > 1) {
    std::vector<std::size_t> sizes(shells);
    for (Mesh::Face_index f : mesh.faces()) ++sizes[shell[f]];
    std::string counts;
    for (std::size_t s : sizes) counts += (counts.empty() ? "" : ", ") + std::to_string(s);
    throw InputError(path + ": its triangles form " + std::to_string(shells) +
                     " separate closed surfaces (of " + counts +
                     " triangles); expected one: a container is one cavity, without obstacles "
                     "inside it");
  }
  if (!pmp::is_outward_oriented(mesh))
    for (auto& t : m.triangles) std::swap(t[1], t[2]);  // inward throughout: turned
  m.volume = std::abs(pmp::volume(mesh));
  if (!(m.volume > 0)) throw InputError(path + ": the closed surface encloses no volume");
  m.low = m.high = m.vertices.front();
  for (const Vec3& v : m.vertices) {
    m.low = {std::min(m.low.x, v.x), std::min(m.low.y, v.y), std::min(m.low.z, v.z)};
    m.high = {std::max(m.high.x, v.x), std::max(m.high.y, v.y), std::max(m.high.z, v.z)};
  }
  return m;
}

struct MeshInside::Tree {
  using Primitive = CGAL::AABB_face_graph_triangle_primitive<Mesh>;
  using Boxes = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  Mesh mesh;
  Boxes boxes;
  CGAL::Side_of_triangle_mesh<Mesh, Kernel> side;
  explicit Tree(Mesh m)
      : mesh(std::move(m)), boxes(faces(mesh).first, faces(mesh).second, mesh), side(mesh) {
    boxes.accelerate_distance_queries();
  }
};

MeshInside::MeshInside(const TriangleMesh& mesh) : tree_(std::make_unique<Tree>(surface(mesh))) {}
MeshInside::~MeshInside() = default;
bool MeshInside::operator()(const Vec3& p) const {
  return tree_->side(Point(p.x, p.y, p.z)) == CGAL::ON_BOUNDED_SIDE;
}
double MeshInside::distance(const Vec3& p) const {
  return std::sqrt(tree_->boxes.squared_distance(Point(p.x, p.y, p.z)));
}

namespace {

// The widest sphere inside: the best of a 24^3 grid over the box and of probes along the
// triangles' inward normals (thin cavities a grid misses), climbed to the nearest summit.
double inscribed_diameter(const TriangleMesh& m, const MeshInside& inside) {
  Vec3 best;
  double widest = 0;
  auto try_point = [&](const Vec3& p) {
    if (!inside(p)) return;
    const double d = inside.distance(p);
    if (d > widest) widest = d, best = p;
  };
  constexpr int kGrid = 24;
  const Vec3 span = m.high - m.low;
  for (int k = 0; k < kGrid; ++k)
    for (int j = 0; j < kGrid; ++j)
      for (int i = 0; i < kGrid; ++i)
        try_point(m.low + Vec3{(i + 0.5) / kGrid * span.x, (j + 0.5) / kGrid * span.y,
                               (k + 0.5) / kGrid * span.z});
  const std::size_t every = std::max<std::size_t>(1, m.triangles.size() / 500);
  const double longest = norm(span);
  for (std::size_t t = 0; t < m.triangles.size(); t += every) {
    const auto& v = m.triangles[t];
    const Vec3 a = m.vertices[std::size_t(v[0])], b = m.vertices[std::size_t(v[1])],
               c = m.vertices[std::size_t(v[2])];
    const Vec3 out = cross(b - a, c - a);
    const Vec3 in = (-1.0 / norm(out)) * out, centre = (1.0 / 3) * (a + b + c);
    for (double depth = 1e-6 * longest; depth < longest; depth *= 1.5)
      try_point(centre + depth * in);
  }
  for (double step = 0.5 * longest / kGrid; step > 1e-6 * longest; step *= 0.5)
    for (bool moved = true; moved;) {
      moved = false;
      for (const Vec3 d : {Vec3{1, 0, 0}, Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, -1, 0},
                           Vec3{0, 0, 1}, Vec3{0, 0, -1}}) {
        const double before = widest;
        try_point(best + step * d);
        moved = moved || widest > before;
      }
    }
  return 2 * widest;
}

}  // namespace

std::shared_ptr<const MeshSurface> load_mesh(const std::string& path, double scale,
                                             double curvature_degrees) {
  auto s = std::make_shared<MeshSurface>(mesh_surface(read_stl(path, scale), curvature_degrees));
  s->file = path;
  s->scale = scale;
  auto inside = std::make_shared<const MeshInside>(s->mesh);
  s->inscribed_diameter = inscribed_diameter(s->mesh, *inside);
  s->holds = [inside](Vec3 p, double r) { return (*inside)(p) && inside->distance(p) >= r; };
  return s;
}

}  // namespace pdsim

// The mesh container: a closed triangle surface (an STL cavity), its frame the container's.
// A sphere touches the closest feature of each triangle near it: the face, an edge or a
// corner. Triangles joined across edges that bend less than the surface's `curvature` form one
// surface, which touches a sphere once (at its deepest point, along its touched facets' normals
// weighted by overlap, so that the normal turns smoothly over a curved surface) and keeps one
// tangential history as the sphere slides across its triangles; edges and corners where surfaces
// meet are features of their own, touched only where no face next to them is (a sphere in a concave
// corner touches the faces, one over a convex edge the edge), so that a sphere crossing from
// one face to the next feels one continuous wall.
#pragma once

#include <algorithm>
#include <array>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "kernels/dem_types.hpp"

namespace pdsim {

constexpr int kTriangleDoubles = 12;  // a, b - a, c - a, the inward unit normal
// Per triangle: [0] its surface's key, [1..3] the keys of edges ab, bc, ca, [4..6] of corners
// a, b, c (a surface's key where the edge or corner lies inside one surface), [7..9] the
// surface across edges ab, bc, ca, [10..12] the vertex numbers of a, b, c.
constexpr int kTriangleInts = 13;

// A triangle mesh as read (io/stl_mesh.hpp), m.
struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> triangles;  // counter-clockwise seen from outside
  double volume = 0;                          // m^3
  Vec3 low, high;                             // bounding box, m
};

// The bins of `s` for spheres up to radius `reach`: each bin lists the triangles within reach
// of any point in it; the arrays a MeshView points into.
struct MeshBins {
  Vec3 origin;
  double cell = 0;
  int nx = 0, ny = 0, nz = 0;
  std::vector<std::int32_t> start, triangle;
};
struct MeshBinCache {
  std::mutex mutex;
  std::map<double, std::shared_ptr<const MeshBins>> by_reach;
};

// The host's mesh container: the mesh, its triangles as the kernels read them (without bins:
// those depend on the particles, mesh_bins()), and what the fill and the checks ask of it.
struct MeshSurface {
  std::string file;
  double scale = 1, curvature = 0;  // curvature: degrees
  TriangleMesh mesh;
  std::vector<double> triangle;   // kTriangleDoubles each
  std::vector<std::int32_t> key;  // kTriangleInts each
  std::int32_t regions = 0, vertex_base = 0;
  std::vector<std::array<int, 2>> feature_edges;  // where surfaces meet (vertex numbers)
  double inscribed_diameter = 0;                  // m: the widest sphere that fits
  // Whether a sphere of radius r centred at p lies inside, clear of the surface (io: CGAL).
  std::function<bool(Vec3 p, double r)> holds;
  std::shared_ptr<MeshBinCache> bins = std::make_shared<MeshBinCache>();  // mesh_bins()
};

// A surface's triangles and the keys of their features (regions joined below `curvature`).
MeshSurface mesh_surface(TriangleMesh mesh, double curvature_degrees);

// The kernels' view of `s` in bins `b`, host arrays (an engine on a device points it at its
// copies).
MeshView mesh_view(const MeshSurface& s, const MeshBins& b);
// Built once per surface and reach (each fill's engine, the bed's and the contact counts share
// them): a 10,000-triangle cavity's bins take about a second.
std::shared_ptr<const MeshBins> mesh_bins(const MeshSurface& s, double reach);

// The closest point of a triangle (corner a, edges ab, ac) to the point a + ap, relative to a,
// and its feature: 0 the face, 1..3 the edges ab, bc, ca, 4..6 the corners a, b, c (Ericson,
// Real-Time Collision Detection, 5.1.5).
struct ClosestFeature {
  Vec3 point;
  int feature;
};
PDSIM_HD ClosestFeature closest_feature(Vec3 ap, Vec3 ab, Vec3 ac) {
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {{}, 4};
  const Vec3 bp = ap - ab;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {ab, 5};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return {(d1 / (d1 - d3)) * ab, 1};
  const Vec3 cp = ap - ac;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {ac, 6};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return {(d2 / (d2 - d6)) * ac, 3};
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return {ab + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (ac - ab), 2};
  const double inv = 1 / (va + vb + vc);
  return {(vb * inv) * ab + (vc * inv) * ac, 0};
}

// The memo (MeshView::memo): the entries it holds, and how far a particle may move, in radii,
// before it is remade. A particle touching a wall of slivers 0.03 radii wide (a 10,240-triangle
// cylinder) holds about 6 entries of its bin's 144; 0.005 radii and 32 entries were the fastest
// of 0.005-0.1 and 32-128 there and on 2,048 triangles (validation/results/validation.md).
constexpr int kMemoEntries = 32;
constexpr int kMemoInts = 2 + kMemoEntries;
constexpr double kMemoSlack = 0.005;

struct MeshShape {
  static constexpr const char* name = "mesh";
  static constexpr bool kKeyed = true;  // walls() names features by key, not fixed slots
  static constexpr int kCandidates = 16;

  template <class Spec>
  static ContainerGeometry geometry(const Spec& c) {
    ContainerGeometry g;
    const TriangleMesh& m = c.mesh->mesh;
    auto far = [](double low, double high) { return std::max(-low, high); };
    g.half_size = {far(m.low.x, m.high.x), far(m.low.y, m.high.y), far(m.low.z, m.high.z)};
    g.surface = c.mesh.get();
    return g;
  }

  // The bin of `local`, or -1 outside the bins (NaN too).
  PDSIM_HD static int bin_of(Vec3 local, const MeshView& m) {
    const double fx = (local.x - m.origin.x) * m.inv_cell, fy = (local.y - m.origin.y) * m.inv_cell,
                 fz = (local.z - m.origin.z) * m.inv_cell;
    if (!(fx >= 0 && fy >= 0 && fz >= 0 && fx < m.nx && fy < m.ny && fz < m.nz)) return -1;
    return (static_cast<int>(fz) * m.ny + static_cast<int>(fy)) * m.nx + static_cast<int>(fx);
  }

  // wall(key, gap, normal) for each feature a sphere at `local` of radius r touches (gap < r),
  // the deepest per key; escaped(beyond) for a centre behind the surface. Returns false when
  // more features were near than it holds (kCandidates): the caller stops the run.
  // `particle` (>= 0 where the view has a memo) names the particle whose memo serves the call.
  template <class Wall, class Escaped>
  PDSIM_HD static bool walls(Vec3 local, double r, const ContainerGeometry& g, Wall&& wall,
                             Escaped&& escaped, int particle = -1) {
    const MeshView& m = g.mesh;
    const int bin = bin_of(local, m);
    if (bin < 0) {  // beyond the bins: further than the largest particle from the surface
      escaped(1e300);
      return true;
    }
    const int first = m.bin_start[bin], end = m.bin_start[bin + 1];
    if (end - first == 1 && m.bin_triangle[first] < 0) {  // inside a flat face: its plane alone
      const int t = ~m.bin_triangle[first];
      const double* T = m.triangle + kTriangleDoubles * t;
      const Vec3 inward{T[9], T[10], T[11]};
      const double plane = dot(local - Vec3{T[0], T[1], T[2]}, inward);
      if (fabs(plane) < r) {
        wall(m.key[kTriangleInts * t], plane, inward);
        escaped(-plane);
      }
      return true;
    }
    enum Kind { kFace, kEdge, kCorner };
    int key[kCandidates], kind[kCandidates], triangle[kCandidates], feature[kCandidates];
    double gap[kCandidates];
    Vec3 normal[kCandidates], blended[kCandidates];
    double weight[kCandidates];
    bool mixed[kCandidates];
    int n = 0;
    bool complete = true;
    // The entries to test: the particle's memo where it holds, else the bin's, remaking the
    // memo from them (kept: those within `keep`, a margin over the slack for rounding).
    const std::int32_t* entries = m.bin_triangle + first;
    int count = end - first;
    std::int32_t* memo = particle >= 0 && m.memo ? m.memo + kMemoInts * particle : nullptr;
    double keep = r;
    if (memo) {
      double* at = m.memo_at + 4 * particle;
      const Vec3 moved = local - Vec3{at[0], at[1], at[2]};
      const double slack = kMemoSlack * r;
      if (memo[0] == bin && at[3] == r && dot(moved, moved) < slack * slack) {
        if (memo[1] >= 0) entries = memo + 2, count = memo[1];
        memo = nullptr;
      } else {
        memo[0] = bin, memo[1] = 0;
        at[0] = local.x, at[1] = local.y, at[2] = local.z, at[3] = r;
        keep = (r + slack) * (1 + 1e-12);
      }
    }
    for (int k = 0; k < count; ++k) {
      const int entry = entries[k];
      const bool plane_only = entry < 0;  // a flat surface whose face is the closest feature
      const int t = plane_only ? ~entry : entry;
      const double* T = m.triangle + kTriangleDoubles * t;
      const Vec3 ap = local - Vec3{T[0], T[1], T[2]}, inward{T[9], T[10], T[11]};
      const double plane = dot(ap, inward);
      if (fabs(plane) >= keep) continue;  // the whole triangle is further
      ClosestFeature f{ap - plane * inward, 0};
      double dist_sq = plane * plane;
      if (!plane_only) {
        f = closest_feature(ap, {T[3], T[4], T[5]}, {T[6], T[7], T[8]});
        const Vec3 d = ap - f.point;
        dist_sq = dot(d, d);
        if (dist_sq >= keep * keep) continue;
      }
      if (memo) {
        if (memo[1] >= 0 && memo[1] < kMemoEntries)
          memo[2 + memo[1]++] = entry;
        else
          memo[1] = -1;  // too many near: its calls test the whole bin
        if (fabs(plane) >= r || (!plane_only && dist_sq >= r * r)) continue;
      }
      const std::int32_t* K = m.key + kTriangleInts * t;
      const int its_key = K[f.feature];
      double its_gap = plane;
      Vec3 its_normal = inward;
      if (f.feature != 0) {  // off the face: along the line from the feature to the centre
        const Vec3 d = ap - f.point;
        const double dist = sqrt(dist_sq), side = plane < 0 ? -1 : 1;
        its_gap = side * dist;
        if (dist > 0) its_normal = (side / dist) * d;
      }
      int c = 0;
      while (c < n && key[c] != its_key) ++c;
      const bool surface = its_key < m.regions;
      if (c == n) {
        if (n == kCandidates) {
          complete = false;
          continue;
        }
        ++n;
        key[c] = its_key;
        kind[c] = surface ? kFace : f.feature < 4 ? kEdge : kCorner;
        gap[c] = 1e300;
        normal[c] = surface ? inward : its_normal;
        blended[c] = (r - its_gap) * inward;
        weight[c] = r - its_gap;
        mixed[c] = false;
      } else if (surface) {
        // A surface touched on several facets: one contact whose normal is their face normals
        // weighted by overlap, turning smoothly as the sphere crosses from facet to facet
        // (the nearest facet's alone would flip across each fold and rock the sphere on it).
        // A flat surface's facets share one normal, which stays exact.
        blended[c] = blended[c] + (r - its_gap) * inward;
        weight[c] += r - its_gap;
        mixed[c] = mixed[c] || inward.x != normal[c].x || inward.y != normal[c].y ||
                   inward.z != normal[c].z;
      }
      if (its_gap >= gap[c]) continue;
      triangle[c] = t;
      feature[c] = f.feature;
      gap[c] = its_gap;
      normal[c] = surface ? inward : its_normal;
    }
    for (int c = 0; c < n; ++c) {
      // Facets facing apart (a surface wrapped round the sphere, which io/decks.md warns of)
      // cancel: the deepest facet's normal then stands alone.
      const double length = mixed[c] ? norm(blended[c]) : 0;
      if (length > 0.5 * weight[c]) normal[c] = (1 / length) * blended[c];
    }
    // An edge is touched only where neither surface beside it is, a corner only where no
    // face or edge of a triangle around it is: otherwise that face holds the sphere off it.
    bool kept[kCandidates];
    for (int c = 0; c < n; ++c) {
      kept[c] = true;
      const std::int32_t* K = m.key + kTriangleInts * triangle[c];
      if (kind[c] == kEdge) {
        for (int o = 0; o < n; ++o)
          if (kind[o] == kFace && (key[o] == K[0] || key[o] == K[6 + feature[c]])) kept[c] = false;
      } else if (kind[c] == kCorner) {
        const int vertex = key[c] - m.vertex_base;
        for (int o = 0; o < n; ++o) {
          const std::int32_t* O = m.key + kTriangleInts * triangle[o];
          if (kind[o] != kCorner && (O[10] == vertex || O[11] == vertex || O[12] == vertex))
            kept[c] = false;
        }
      }
    }
    for (int c = 0; c < n; ++c) {
      if (!kept[c]) continue;
      wall(key[c], gap[c], normal[c]);
      escaped(-gap[c]);
    }
    return complete;
  }

  // What decides it, for the scene's identity (src/identity.cpp): add(name, value, unit); the
  // triangles (corners, edges and normals) as a list, which the identity hashes.
  template <class Add>
  static void identity(const ContainerGeometry& g, Add&& add) {
    add("triangles", g.surface->triangle, "");
    add("curvature", g.surface->curvature, "degrees");
  }

  template <class Spec>
  static std::string describe(const Spec& c) {
    const MeshSurface& s = *c.mesh;
    std::ostringstream o;
    o << name << " " << s.file << " (scale " << s.scale << "): " << s.mesh.triangles.size()
      << " triangles, " << s.regions << " surface" << (s.regions == 1 ? "" : "s") << " (curvature "
      << s.curvature << " deg), volume " << s.mesh.volume << " m^3, bounding box [" << s.mesh.low.x
      << ", " << s.mesh.low.y << ", " << s.mesh.low.z << "] to [" << s.mesh.high.x << ", "
      << s.mesh.high.y << ", " << s.mesh.high.z << "] m";
    return o.str();
  }

  // Bounding test: the bin lists a triangle (or the centre is beyond the bins).
  PDSIM_HOT static bool near(Vec3 local, double, const ContainerGeometry& g) {
    const int bin = bin_of(local, g.mesh);
    return bin < 0 || g.mesh.bin_start[bin + 1] > g.mesh.bin_start[bin];
  }

  static bool inside(Vec3 local, double r, const ContainerGeometry& g) {
    return g.surface->holds(local, r);
  }
  static double volume(const ContainerGeometry& g) { return g.surface->mesh.volume; }
  static double smallest_inner_size(const ContainerGeometry& g) {
    return g.surface->inscribed_diameter;
  }
  // The edges where surfaces meet (a cavity that is one smooth surface: all its edges).
  static void wireframe(const ContainerGeometry& g, std::vector<Vec3>& points,
                        std::vector<int>& segments) {
    const MeshSurface& s = *g.surface;
    const int base = static_cast<int>(points.size());
    points.insert(points.end(), s.mesh.vertices.begin(), s.mesh.vertices.end());
    for (const auto& e : s.feature_edges)
      segments.insert(segments.end(), {base + e[0], base + e[1]});
    if (!s.feature_edges.empty()) return;
    for (const auto& t : s.mesh.triangles)  // one smooth surface: every edge, once
      for (int k = 0; k < 3; ++k)
        if (t[k] < t[(k + 1) % 3])
          segments.insert(segments.end(), {base + t[k], base + t[(k + 1) % 3]});
  }
};

}  // namespace pdsim

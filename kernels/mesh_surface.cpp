// The host's half of the mesh container (kernels/shape_mesh.hpp): surfaces, feature keys and
// bins, made once per mesh and per engine.
#include <cmath>
#include <cstdint>
#include <algorithm>
#include <array>
#include <map>
#include <numeric>

#include "kernels/shape_mesh.hpp"

namespace pdsim {

namespace {

// The root of t's set (path halving).
int root(std::vector<int>& parent, int t) {
  while (parent[static_cast<std::size_t>(t)] != t)
    t = parent[static_cast<std::size_t>(t)] =
        parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(t)])];
  return t;
}

// Flat surfaces (their triangles in one plane, to rounding of float STL coordinates) and the
// edges that bound them: a bin whose whole reach projects into a flat surface, clear of those
// edges, needs that surface's plane only. A CAD face comes as fans and slivers, dozens to
// hundreds of coplanar triangles near one point (a cylinder's end cap: every triangle at its
// centre); one plane test instead of a closest-feature test for each (~~t in the list).
void plane_entries(const MeshSurface& s, double reach, const MeshBins& b,
                   std::vector<std::vector<std::int32_t>>& lists) {
  const std::size_t n = s.mesh.triangles.size();
  const double tolerance = 1e-7 * norm(s.mesh.high - s.mesh.low);
  auto T = [&](std::size_t t) { return &s.triangle[kTriangleDoubles * t]; };
  auto normal = [&](std::size_t t) { return Vec3{T(t)[9], T(t)[10], T(t)[11]}; };
  auto corner = [&](std::size_t t) { return Vec3{T(t)[0], T(t)[1], T(t)[2]}; };
  std::vector<int> first(static_cast<std::size_t>(s.regions), -1);
  std::vector<char> flat(static_cast<std::size_t>(s.regions), 1);
  std::vector<std::vector<std::array<Vec3, 2>>> boundary(static_cast<std::size_t>(s.regions));
  for (std::size_t t = 0; t < n; ++t) {
    const std::int32_t* K = &s.key[kTriangleInts * t];
    const auto r = static_cast<std::size_t>(K[0]);
    if (first[r] < 0) first[r] = static_cast<int>(t);
    const auto f = static_cast<std::size_t>(first[r]);
    for (int v = 0; v < 3; ++v) {
      const Vec3 p = s.mesh.vertices[static_cast<std::size_t>(K[10 + v])];
      if (std::fabs(dot(p - corner(f), normal(f))) > tolerance) flat[r] = 0;
      if (K[7 + v] != K[0])
        boundary[r].push_back({p, s.mesh.vertices[static_cast<std::size_t>(K[10 + (v + 1) % 3])]});
    }
  }
  for (std::size_t bin = 0; bin < lists.size(); ++bin) {
    std::vector<std::int32_t>& list = lists[bin];
    const auto i = static_cast<int>(bin % static_cast<std::size_t>(b.nx)),
               j = static_cast<int>(bin / static_cast<std::size_t>(b.nx) %
                                    static_cast<std::size_t>(b.ny)),
               k = static_cast<int>(bin / (static_cast<std::size_t>(b.nx) * b.ny));
    const Vec3 centre = b.origin + Vec3{(i + 0.5) * b.cell, (j + 0.5) * b.cell, (k + 0.5) * b.cell};
    // Each flat surface's triangle under the centre, or -1 where the foot is near its boundary.
    std::map<std::int32_t, std::int32_t> plane;
    for (const std::int32_t t : list) {
      const std::int32_t r = s.key[kTriangleInts * static_cast<std::size_t>(t)];
      const auto u = static_cast<std::size_t>(t);
      if (!flat[static_cast<std::size_t>(r)] || plane.count(r)) continue;
      const double* A = T(u);
      // The centre's foot lies in this triangle: on its face, or on an edge or corner inside
      // the surface (the centre of a fan).
      const int f =
          closest_feature(centre - corner(u), {A[3], A[4], A[5]}, {A[6], A[7], A[8]}).feature;
      if (s.key[kTriangleInts * u + static_cast<std::size_t>(f)] != r) continue;
      const Vec3 foot = centre - dot(centre - corner(u), normal(u)) * normal(u);
      bool clear = true;
      for (const auto& e : boundary[static_cast<std::size_t>(r)]) {
        const Vec3 d = e[1] - e[0];
        const double along = std::clamp(dot(foot - e[0], d) / dot(d, d), 0.0, 1.0);
        if (norm(foot - (e[0] + along * d)) < reach) {
          clear = false;
          break;
        }
      }
      // The foot is the surface's, whichever of its triangles found it: one boundary test a
      // surface (testing each of a cap's 2,560 wedges near its rim cost 1.5 s of set-up).
      plane[r] = clear ? t : -1;
    }
    std::vector<std::int32_t> kept;
    for (const std::int32_t t : list) {
      const auto p = plane.find(s.key[kTriangleInts * static_cast<std::size_t>(t)]);
      if (p == plane.end() || p->second < 0) kept.push_back(t);
    }
    if (kept.size() == list.size()) continue;
    for (const auto& [r, t] : plane)
      if (t >= 0) kept.push_back(~t);
    list = std::move(kept);
  }
}

}  // namespace

MeshSurface mesh_surface(TriangleMesh mesh, double curvature_degrees) {
  MeshSurface s;
  s.curvature = curvature_degrees;
  const std::size_t n = mesh.triangles.size();
  s.triangle.resize(kTriangleDoubles * n);
  std::vector<Vec3> inward(n);
  for (std::size_t t = 0; t < n; ++t) {
    const auto& v = mesh.triangles[t];
    const Vec3 a = mesh.vertices[static_cast<std::size_t>(v[0])];
    const Vec3 ab = mesh.vertices[static_cast<std::size_t>(v[1])] - a;
    const Vec3 ac = mesh.vertices[static_cast<std::size_t>(v[2])] - a;
    const Vec3 out = cross(ab, ac);  // counter-clockwise from outside: outward
    inward[t] = (-1.0 / norm(out)) * out;
    const Vec3 row[4] = {a, ab, ac, inward[t]};
    for (int k = 0; k < 4; ++k) {
      s.triangle[kTriangleDoubles * t + 3 * k] = row[k].x;
      s.triangle[kTriangleDoubles * t + 3 * k + 1] = row[k].y;
      s.triangle[kTriangleDoubles * t + 3 * k + 2] = row[k].z;
    }
  }
  // Edges by their vertices (lower first), each with its two triangles (the mesh is closed).
  std::map<std::pair<int, int>, std::array<int, 3>> edges;  // id, triangle, triangle
  for (std::size_t t = 0; t < n; ++t)
    for (int e = 0; e < 3; ++e) {
      const int a = mesh.triangles[t][e], b = mesh.triangles[t][(e + 1) % 3];
      auto [it, fresh] = edges.try_emplace({std::min(a, b), std::max(a, b)},
                                           std::array<int, 3>{0, static_cast<int>(t), -1});
      if (!fresh) it->second[2] = static_cast<int>(t);
    }
  int id = 0;
  for (auto& e : edges) e.second[0] = id++;
  // Surfaces: triangles joined across edges that bend less than the curvature.
  const double joined = std::cos(curvature_degrees * kPi / 180);
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& e : edges) {
    const int t = e.second[1], u = e.second[2];
    if (dot(inward[static_cast<std::size_t>(t)], inward[static_cast<std::size_t>(u)]) >= joined)
      parent[static_cast<std::size_t>(root(parent, t))] = root(parent, u);
  }
  std::vector<int> region(n, -1), number(n, -1);
  for (std::size_t t = 0; t < n; ++t) {
    int& r = number[static_cast<std::size_t>(root(parent, static_cast<int>(t)))];
    if (r < 0) r = s.regions++;
    region[t] = r;
  }
  const int edge_base = s.regions;
  s.vertex_base = edge_base + static_cast<int>(edges.size());
  // A corner inside one surface is that surface's.
  std::vector<int> corner_region(mesh.vertices.size(), -2);  // -2 none yet, -1 several
  for (std::size_t t = 0; t < n; ++t)
    for (int v : mesh.triangles[t]) {
      int& c = corner_region[static_cast<std::size_t>(v)];
      c = c == -2 || c == region[t] ? region[t] : -1;
    }
  s.key.resize(kTriangleInts * n);
  for (std::size_t t = 0; t < n; ++t) {
    std::int32_t* K = &s.key[kTriangleInts * t];
    K[0] = region[t];
    for (int e = 0; e < 3; ++e) {
      const int a = mesh.triangles[t][e], b = mesh.triangles[t][(e + 1) % 3];
      const auto& edge = edges.at({std::min(a, b), std::max(a, b)});
      const int across =
          region[static_cast<std::size_t>(edge[1] == static_cast<int>(t) ? edge[2] : edge[1])];
      K[1 + e] = across == region[t] ? region[t] : edge_base + edge[0];
      K[7 + e] = across;
      const int corner = corner_region[static_cast<std::size_t>(a)];
      K[4 + e] = corner >= 0 ? corner : s.vertex_base + a;
      K[10 + e] = a;
    }
  }
  for (const auto& e : edges)
    if (region[static_cast<std::size_t>(e.second[1])] !=
        region[static_cast<std::size_t>(e.second[2])])
      s.feature_edges.push_back({e.first.first, e.first.second});
  s.mesh = std::move(mesh);
  return s;
}

namespace {

MeshBins build_bins(const MeshSurface& s, double reach) {
  // Bins half the reach wide, so that the near-wall layer is at most 1.9 reach deep; coarser
  // where that would make more than 2 million bins.
  constexpr double kMostBins = 2e6;
  MeshBins b;
  const Vec3 pad{1.01 * reach, 1.01 * reach, 1.01 * reach};
  b.origin = s.mesh.low - pad;
  const Vec3 span = s.mesh.high + pad - b.origin;
  b.cell = std::max(0.5 * reach, std::cbrt(span.x * span.y * span.z / kMostBins));
  b.nx = std::max(1, static_cast<int>(std::ceil(span.x / b.cell)));
  b.ny = std::max(1, static_cast<int>(std::ceil(span.y / b.cell)));
  b.nz = std::max(1, static_cast<int>(std::ceil(span.z / b.cell)));
  const double half_diagonal = 0.5 * std::sqrt(3.0) * b.cell;
  std::vector<std::vector<std::int32_t>> lists(static_cast<std::size_t>(b.nx) * b.ny * b.nz);
  const std::size_t n = s.mesh.triangles.size();
  for (std::size_t t = 0; t < n; ++t) {
    const double* T = &s.triangle[kTriangleDoubles * t];
    const Vec3 a{T[0], T[1], T[2]}, ab{T[3], T[4], T[5]}, ac{T[6], T[7], T[8]};
    Vec3 low = a, high = a;
    for (const Vec3& p : {a + ab, a + ac}) {
      low = {std::min(low.x, p.x), std::min(low.y, p.y), std::min(low.z, p.z)};
      high = {std::max(high.x, p.x), std::max(high.y, p.y), std::max(high.z, p.z)};
    }
    auto first = [&](double x, double o, int count) {
      return std::clamp(static_cast<int>(std::floor((x - reach - o) / b.cell)), 0, count - 1);
    };
    auto last = [&](double x, double o, int count) {
      return std::clamp(static_cast<int>(std::floor((x + reach - o) / b.cell)), 0, count - 1);
    };
    for (int k = first(low.z, b.origin.z, b.nz); k <= last(high.z, b.origin.z, b.nz); ++k)
      for (int j = first(low.y, b.origin.y, b.ny); j <= last(high.y, b.origin.y, b.ny); ++j)
        for (int i = first(low.x, b.origin.x, b.nx); i <= last(high.x, b.origin.x, b.nx); ++i) {
          const Vec3 centre =
              b.origin + Vec3{(i + 0.5) * b.cell, (j + 0.5) * b.cell, (k + 0.5) * b.cell};
          const Vec3 ap = centre - a;
          const Vec3 d = ap - closest_feature(ap, ab, ac).point;
          if (norm(d) <= reach + half_diagonal)
            lists[(static_cast<std::size_t>(k) * b.ny + j) * b.nx + i].push_back(
                static_cast<std::int32_t>(t));
        }
  }
  plane_entries(s, reach + half_diagonal, b, lists);
  b.start.reserve(lists.size() + 1);
  b.start.push_back(0);
  for (const auto& l : lists) {
    b.triangle.insert(b.triangle.end(), l.begin(), l.end());
    b.start.push_back(static_cast<std::int32_t>(b.triangle.size()));
  }
  return b;
}

}  // namespace

std::shared_ptr<const MeshBins> mesh_bins(const MeshSurface& s, double reach) {
  const std::lock_guard<std::mutex> lock(s.bins->mutex);
  auto& bins = s.bins->by_reach[reach];
  if (!bins) bins = std::make_shared<const MeshBins>(build_bins(s, reach));
  return bins;
}

MeshView mesh_view(const MeshSurface& s, const MeshBins& b) {
  MeshView v;
  v.triangle = s.triangle.data();
  v.key = s.key.data();
  v.regions = s.regions;
  v.vertex_base = s.vertex_base;
  v.origin = b.origin;
  v.inv_cell = 1 / b.cell;
  v.nx = b.nx, v.ny = b.ny, v.nz = b.nz;
  v.bin_start = b.start.data();
  v.bin_triangle = b.triangle.data();
  return v;
}

}  // namespace pdsim

#include "io/xdmf.hpp"

#include <cmath>
#include <filesystem>
#include <sstream>
#include <vector>

#include "kernels/shapes.hpp"

namespace pdsim {

namespace {

// The container's wireframe in its own frame: points and the segments joining them.
struct Wireframe {
  std::vector<Vec3> points;
  std::vector<int> segments;  // pairs of point indices
};

Wireframe wireframe(const DamperSnapshots& d) {
  ContainerGeometry g;  // from the edge lengths the file keeps (a cylinder: its diameter)
  g.half_size = {0.5 * d.size.at(0), 0.5 * d.size.at(1), 0.5 * d.size.at(2)};
  g.radius = g.half_size.x;
  Wireframe w;
  with_shape(shape_named(d.shape),
             [&](auto shape) { decltype(shape)::wireframe(g, w.points, w.segments); });
  return w;
}

// An HDF5 array's slice [t] (of shape `tail`), as an XDMF hyperslab.
void slab(std::ostringstream& x, const std::string& source, std::size_t t, std::size_t steps,
          const std::vector<std::size_t>& tail,
          const char* type = "NumberType=\"Float\" Precision=\"8\"") {
  const std::size_t rank = tail.size() + 1;
  std::string dims, full = std::to_string(steps), count = "1", zeros = "0", ones = "1";
  for (std::size_t n : tail) {
    dims += (dims.empty() ? "" : " ") + std::to_string(n);
    full += " " + std::to_string(n);
    count += " " + std::to_string(n);
    zeros += " 0";
    ones += " 1";
  }
  x << "<DataItem ItemType=\"HyperSlab\" Dimensions=\"" << dims << "\" Type=\"HyperSlab\" " << type
    << ">"
    << "<DataItem Dimensions=\"3 " << rank << "\" Format=\"XML\">" << t << zeros.substr(1) << " "
    << ones << " " << count << "</DataItem>"
    << "<DataItem Dimensions=\"" << full << "\" " << type << " Format=\"HDF\">" << source
    << "</DataItem></DataItem>\n";
}

}  // namespace

std::string xdmf_path(const std::string& h5_path) {
  const std::filesystem::path p(h5_path);
  if (p.extension() == ".h5") return std::filesystem::path(p).replace_extension(".xdmf").string();
  return h5_path + ".xdmf";
}

void write_xdmf(const std::string& h5_path, const ParticleSnapshots& s) {
  const std::string file = std::filesystem::path(h5_path).filename().string();
  const std::size_t steps = s.time.size();
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n";
  for (std::size_t k = 0; k < s.dampers.size(); ++k) {
    const DamperSnapshots& d = s.dampers[k];
    const std::size_t n = d.radius.size();
    const std::string group = file + ":/particles/damper" + std::to_string(k) + "/";
    x << "<Grid Name=\"damper" << k << " particles\" GridType=\"Collection\" "
      << "CollectionType=\"Temporal\">\n";
    for (std::size_t t = 0; t < steps; ++t) {
      x << "<Grid Name=\"particles\" GridType=\"Uniform\"><Time Value=\"" << s.time[t] << "\"/>"
        << "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n
        << "\" NodesPerElement=\"1\"/>\n<Geometry GeometryType=\"XYZ\">";
      slab(x, group + "position", t, steps, {n, 3});
      x << "</Geometry>\n<Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\">"
        << "<DataItem Dimensions=\"" << n << "\" NumberType=\"Float\" Precision=\"8\" "
        << "Format=\"HDF\">" << group << "radius</DataItem></Attribute>\n";
      for (const char* vector : {"velocity", "spin"}) {
        x << "<Attribute Name=\"" << vector << "\" AttributeType=\"Vector\" Center=\"Node\">";
        slab(x, group + vector, t, steps, {n, 3});
        x << "</Attribute>\n";
      }
      if (!d.contacts.empty()) {
        x << "<Attribute Name=\"contacts\" AttributeType=\"Scalar\" Center=\"Node\">";
        slab(x, group + "contacts", t, steps, {n}, "NumberType=\"Int\" Precision=\"4\"");
        x << "</Attribute>\n";
      }
      x << "</Grid>\n";
    }
    x << "</Grid>\n";
    // The container: its wireframe moved to each snapshot's pose (inline, a few dozen points).
    const Wireframe w = wireframe(d);
    x << "<Grid Name=\"damper" << k << " container\" GridType=\"Collection\" "
      << "CollectionType=\"Temporal\">\n";
    for (std::size_t t = 0; t < steps; ++t) {
      const double* c = &d.container_position.at(3 * t);
      const double* a = &d.container_axes.at(9 * t);
      x << "<Grid Name=\"container\" GridType=\"Uniform\"><Time Value=\"" << s.time[t] << "\"/>"
        << "<Topology TopologyType=\"Polyline\" NumberOfElements=\"" << w.segments.size() / 2
        << "\" NodesPerElement=\"2\"><DataItem Dimensions=\"" << w.segments.size() / 2
        << " 2\" NumberType=\"Int\" Format=\"XML\">";
      for (int i : w.segments) x << i << " ";
      x << "</DataItem></Topology>\n<Geometry GeometryType=\"XYZ\"><DataItem Dimensions=\""
        << w.points.size() << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">";
      for (const Vec3& p : w.points)
        for (int i = 0; i < 3; ++i) x << c[i] + p.x * a[i] + p.y * a[3 + i] + p.z * a[6 + i] << " ";
      x << "</DataItem></Geometry></Grid>\n";
    }
    x << "</Grid>\n";
  }
  x << "</Domain>\n</Xdmf>\n";
  replace_file(xdmf_path(h5_path), x.str());
}

}  // namespace pdsim

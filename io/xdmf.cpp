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
  Wireframe w;
  if (!d.outline_points.empty()) {  // as the run drew it
    for (std::size_t k = 0; k + 2 < d.outline_points.size(); k += 3)
      w.points.push_back({d.outline_points[k], d.outline_points[k + 1], d.outline_points[k + 2]});
    w.segments.assign(d.outline_segments.begin(), d.outline_segments.end());
    return w;
  }
  ContainerGeometry g;  // older files: from the edge lengths (a cylinder: its diameter)
  g.half_size = {0.5 * d.size.at(0), 0.5 * d.size.at(1), 0.5 * d.size.at(2)};
  g.radius = g.half_size.x;
  with_shape(shape_named(d.shape),
             [&](auto shape) { decltype(shape)::wireframe(g, w.points, w.segments); });
  return w;
}

}  // namespace

std::string xdmf_path(const std::string& h5_path) {
  const std::filesystem::path p(h5_path);
  if (p.extension() == ".h5") return std::filesystem::path(p).replace_extension(".xdmf").string();
  return h5_path + ".xdmf";
}

void write_xdmf(const std::string& h5_path, const ParticleSnapshots& s) {
  const std::string file = std::filesystem::path(h5_path).filename().string();
  std::vector<Wireframe> frames;
  for (const DamperSnapshots& d : s.dampers) frames.push_back(wireframe(d));
  // One temporal collection of one spatial collection a snapshot (every damper's particles and
  // container), each array a whole HDF5 dataset (a snapshot's are views, /particles/damperK/
  // step/T): the structure and the items that ParaView's XDMF reader and its Xdmf3 readers
  // (OpenDataFile's choice) all read.
  std::ostringstream x;
  x.precision(17);
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n<Domain>\n"
    << "<Grid Name=\"snapshots\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  const char* real = "NumberType=\"Float\" Precision=\"8\" Format=\"HDF\"";
  for (std::size_t t = 0; t < s.time.size(); ++t) {
    x << "<Grid Name=\"snapshot " << t << "\" GridType=\"Collection\" "
      << "CollectionType=\"Spatial\"><Time Value=\"" << s.time[t] << "\"/>\n";
    for (std::size_t k = 0; k < s.dampers.size(); ++k) {
      const DamperSnapshots& d = s.dampers[k];
      const std::size_t n = d.radius.size();
      const std::string group = file + ":/particles/damper" + std::to_string(k) + "/";
      const std::string step = group + "step/" + std::to_string(t) + "/";
      x << "<Grid Name=\"damper" << k << " particles\" GridType=\"Uniform\">"
        << "<Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n
        << "\" NodesPerElement=\"1\"><DataItem Dimensions=\"" << n
        << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" << group
        << "vertex</DataItem></Topology>\n<Geometry GeometryType=\"XYZ\"><DataItem Dimensions=\""
        << n << " 3\" " << real << ">" << step << "position</DataItem></Geometry>\n"
        << "<Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\"><DataItem "
        << "Dimensions=\"" << n << "\" " << real << ">" << group
        << "radius</DataItem></Attribute>\n";
      for (const char* vector : {"velocity", "spin"})
        x << "<Attribute Name=\"" << vector << "\" AttributeType=\"Vector\" Center=\"Node\">"
          << "<DataItem Dimensions=\"" << n << " 3\" " << real << ">" << step << vector
          << "</DataItem></Attribute>\n";
      if (!d.contacts.empty())
        x << "<Attribute Name=\"contacts\" AttributeType=\"Scalar\" Center=\"Node\">"
          << "<DataItem Dimensions=\"" << n << "\" NumberType=\"Int\" Precision=\"4\" "
          << "Format=\"HDF\">" << step << "contacts</DataItem></Attribute>\n";
      x << "</Grid>\n";
      // The container: its wireframe moved to the snapshot's pose (inline, a few dozen points).
      const Wireframe& w = frames[k];
      const double* c = &d.container_position.at(3 * t);
      const double* a = &d.container_axes.at(9 * t);
      x << "<Grid Name=\"damper" << k << " container\" GridType=\"Uniform\">"
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
  x << "</Grid>\n</Domain>\n</Xdmf>\n";
  replace_file(xdmf_path(h5_path), x.str());
}

}  // namespace pdsim

// Plain data shared by the DEM kernels on host and device: material constants of a scene,
// container geometry and kinematics, and structure-of-arrays views of the particle state.
#pragma once

#include <cstdint>
#include <limits>

#include "kernels/vec3.hpp"

namespace pdsim {

// Contact constants derived once per scene (see src/scene.cpp for the formulas' sources).
struct ContactParams {
  double linear_stiffness = 0;  // N/m, linear law
  double damping_factor = 0;    // linear: c = damping_factor sqrt(m* k); hertz: -2 sqrt(5/6) beta
  double hertz_modulus_pp = 0;  // E* particle-particle, Pa
  double hertz_modulus_pw = 0;  // E* particle-wall, Pa
  double shear_modulus_pp = 0;  // G* particle-particle, Pa (Mindlin)
  double shear_modulus_pw = 0;  // G* particle-wall, Pa
  double tangential_ratio = 2.0 / 7.0;  // linear law + history: kt = ratio * kn
  double friction = 0;                  // Coulomb coefficient
  double rolling_friction = 0;          // rolling resistance coefficient (torque = mu_r R* |Fn|)
  // Hertz damping per root of (contact radius x m*), derived from the above by
  // with_damping_roots() when an engine takes the scene (NaN until then, so that a kernel
  // given underived constants shows it):
  // damping_factor sqrt(2 E*) and damping_factor sqrt(8 G*), particle-particle and -wall.
  double normal_root_pp = std::numeric_limits<double>::quiet_NaN();
  double normal_root_pw = std::numeric_limits<double>::quiet_NaN();
  double tangent_root_pp = std::numeric_limits<double>::quiet_NaN();
  double tangent_root_pw = std::numeric_limits<double>::quiet_NaN();
};

// max() without the NaN rules of fmax, which compilers turn into a library call.
PDSIM_HD double max_of(double a, double b) {
  return a > b ? a : b;
}

// The backend, as the deck names it and the engine is made with.
enum class Backend { automatic, cpu, cuda };
// The name of a backend in decks and on the command line.
inline const char* backend_name(Backend b) {
  constexpr const char* names[] = {"auto", "cpu", "cuda"};
  return names[static_cast<int>(b)];
}

// A mesh container's triangles and their bins, as the step kernels read them (host or device
// arrays, set by the engine; kernels/shape_mesh.hpp). All in the container frame, m.
struct MeshView {
  const double* triangle = nullptr;   // kTriangleDoubles each: a, b - a, c - a, inward normal
  const std::int32_t* key = nullptr;  // kTriangleInts each (kernels/shape_mesh.hpp)
  std::int32_t regions = 0;           // keys below this name a surface, not an edge or corner
  std::int32_t vertex_base = 0;       // keys from this on name a vertex: key - vertex_base
  Vec3 origin;                        // the bins' low corner
  double inv_cell = 0;                // 1 / bin width
  std::int32_t nx = 0, ny = 0, nz = 0;
  const std::int32_t* bin_start = nullptr;  // nx ny nz + 1: bin b lists bin_triangle[start[b]..)
  const std::int32_t* bin_triangle = nullptr;
  // The CPU engine's (none elsewhere): per particle, the entries of its bin within
  // r (1 + kMemoSlack) of where it was, which serve its walls() calls while it stays in that bin
  // within kMemoSlack r of there (kernels/shape_mesh.hpp).
  std::int32_t* memo = nullptr;  // kMemoInts each: the bin, the count (-1: too many), entries
  double* memo_at = nullptr;     // 4 each: where it was made (container frame) and the radius
};

struct MeshSurface;  // the host's mesh (kernels/shape_mesh.hpp)

struct ContainerGeometry {
  Vec3 half_size;     // box: half edge lengths; cylinder: (radius, radius, half height); mesh:
                      // the largest extent from the origin along each axis
  double radius = 0;  // cylinder radius
  MeshView mesh;      // mesh: its triangles in bins (set by the engine)
  const MeshSurface* surface = nullptr;  // mesh, host only: the surface the bins are made from
};

// The container's axes in the world when its attachment is at rest: the identity, or a
// cylinder laid along another direction. Only the Rotating kernel variants read axes.
struct Orientation {
  Vec3 x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};
  PDSIM_HD bool identity() const {
    return x.x == 1 && x.y == 0 && x.z == 0 && y.x == 0 && y.y == 1 && y.z == 0 && z.x == 0 &&
           z.y == 0 && z.z == 1;
  }
};

// Half extents along the world axes of a container of half size h whose axes are o: what a
// cell grid around it must span. Exactly h for the identity.
inline Vec3 world_half_size(Vec3 h, const Orientation& o) {
  auto span = [&](double ex, double ey, double ez) {
    return fabs(ex) * h.x + fabs(ey) * h.y + fabs(ez) * h.z;
  };
  return {span(o.x.x, o.y.x, o.z.x), span(o.x.y, o.y.y, o.z.y), span(o.x.z, o.y.z, o.z.z)};
}

// Rigid container motion at the start of a step. Rotation (a damper on a beam node) is read only
// by the Rotating kernel variants.
struct ContainerKinematics {
  Vec3 position;                                           // centre, m
  Vec3 velocity;                                           // m/s
  Vec3 axis_x{1, 0, 0}, axis_y{0, 1, 0}, axis_z{0, 0, 1};  // container axes in the world
  Vec3 angular_velocity;                                   // rad/s
};

// Its axes at rest: those of `o` (the container does not turn).
inline void set_axes(ContainerKinematics& k, const Orientation& o) {
  k.axis_x = o.x, k.axis_y = o.y, k.axis_z = o.z;
}

// A container that translates without turning.
inline ContainerKinematics translating(Vec3 position, Vec3 velocity) {
  ContainerKinematics k;
  k.position = position;
  k.velocity = velocity;
  return k;
}

enum StepFlag : int { kNonFinite = 1, kEscaped = 2, kNeighbourOverflow = 4, kWallOverflow = 8 };

// Particle state, one array per component (structure of arrays).
struct ParticleArrays {
  double *x, *y, *z;
  double *vx, *vy, *vz;
  double *wx, *wy, *wz;
};

// Wall contacts a particle may hold history for: box -x,+x,-y,+y,-z,+z; cylinder 0 side, 4 -z,
// 5 +z; mesh: any six surfaces, edges or corners, each slot naming its own (HistoryArrays).
constexpr int kWallSlots = 6;
constexpr int kSlotGroup = 2;  // neighbour lists are padded to multiples of this (slot tests)

// A reverse-list entry names a forward slot by its owner and its place k in the owner's list
// (k < 64, the width of the slot masks), packed in one int32: owner << kSlotBits | k. The
// place is layout-free, so both backends' lists (compact on the CPU, fixed stride on the GPU)
// share the format.
constexpr int kSlotBits = 6;
constexpr int kMaxParticles = (1 << (31 - kSlotBits)) - 1;  // owners that fit in an entry
PDSIM_HD std::int32_t reverse_entry(int owner, int k) {
  return owner << kSlotBits | k;
}
PDSIM_HD int entry_owner(std::int32_t e) {
  return e >> kSlotBits;
}
PDSIM_HD int entry_place(std::int32_t e) {
  return e & ((1 << kSlotBits) - 1);
}

}  // namespace pdsim

// The bottom of every layer, usable on host and device: small vectors, pi, and the macros that
// mark functions for both (host-only types are in kernels/errors.hpp).
#pragma once

#include <cmath>

#if defined(__CUDACC__)
#define PDSIM_HD __host__ __device__ __forceinline__
#else
#define PDSIM_HD inline
#endif

// Hot per-particle functions: always inlined, so that the launcher's loop sees the whole step.
// Rarely taken, heavy paths: out of line on the host so that the hot loop keeps its registers.
#if defined(__CUDACC__)
#define PDSIM_HOT PDSIM_HD
#define PDSIM_COLD PDSIM_HD
#else
#define PDSIM_HOT inline __attribute__((always_inline))
#define PDSIM_COLD __attribute__((noinline))
#endif

namespace pdsim {

constexpr double kPi = 3.14159265358979323846;

struct Vec3 {
  double x = 0, y = 0, z = 0;
};

PDSIM_HD Vec3 operator+(Vec3 a, Vec3 b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
PDSIM_HD Vec3 operator-(Vec3 a, Vec3 b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
PDSIM_HD Vec3 operator-(Vec3 a) {
  return {-a.x, -a.y, -a.z};
}
PDSIM_HD Vec3 operator*(double s, Vec3 a) {
  return {s * a.x, s * a.y, s * a.z};
}
PDSIM_HD Vec3 operator*(Vec3 a, double s) {
  return {s * a.x, s * a.y, s * a.z};
}
PDSIM_HD Vec3& operator+=(Vec3& a, Vec3 b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
PDSIM_HD Vec3& operator-=(Vec3& a, Vec3 b) {
  a.x -= b.x;
  a.y -= b.y;
  a.z -= b.z;
  return a;
}
PDSIM_HD double dot(Vec3 a, Vec3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
PDSIM_HD Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
PDSIM_HD double norm(Vec3 a) {
  return sqrt(dot(a, a));
}

}  // namespace pdsim

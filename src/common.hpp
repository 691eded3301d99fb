// Types shared by every layer: small vectors usable on host and device, and the
// error type that carries a deck position up to the CLI.
#pragma once

#include <cmath>
#include <stdexcept>
#include <string>

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

// Position of a key in a deck, for error messages ("file:line:column").
struct SourcePos {
  std::string file;
  int line = 0;
  int column = 0;
};

// A user error (bad deck, bad option, existing output): the CLI prints it and exits 1.
class InputError : public std::runtime_error {
 public:
  InputError(const SourcePos& where, const std::string& key, const std::string& what)
      : std::runtime_error(format(where, key, what)) {}
  explicit InputError(const std::string& what) : std::runtime_error(what) {}

 private:
  static std::string format(const SourcePos& p, const std::string& key, const std::string& what) {
    std::string s = p.file;
    if (p.line > 0) s += ":" + std::to_string(p.line) + ":" + std::to_string(p.column);
    s += ": ";
    if (!key.empty()) s += "'" + key + "': ";
    return s + what;
  }
};

// A failure of the simulation itself (blow-up, solver failure): reported with step and time.
class SimulationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A run stopped from outside (SIGINT, or a sibling run that failed): not a failure of its own.
class Interrupted : public SimulationError {
 public:
  explicit Interrupted(const std::string& what = "interrupted") : SimulationError(what) {}
};

}  // namespace pdsim

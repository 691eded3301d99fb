#include "src/format.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace pdsim {

std::string number(double v, int precision) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

std::string amplitude_text(double size, double half_width, bool prescribed) {
  std::ostringstream s;
  s.precision(4);
  const double unit = prescribed ? 1.0 : 1e3;
  s << (prescribed ? "force " : "") << size * unit << (prescribed ? " N" : " mm");
  if (std::isnan(half_width))
    s << " (no interval)";
  else if (size > 0)
    s << " +- " << 100 * half_width / size << " %";
  else  // no relative width of nothing (a bed that never touched its walls)
    s << " +- " << half_width * unit << (prescribed ? " N" : " mm");
  return s.str();
}

}  // namespace pdsim

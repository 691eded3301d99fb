#include "src/format.hpp"

#include <algorithm>
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
  s << (prescribed ? "force " : "") << size * (prescribed ? 1.0 : 1e3)
    << (prescribed ? " N" : " mm") << " +- " << 100 * half_width / std::max(size, 1e-300) << " %";
  return s.str();
}

}  // namespace pdsim

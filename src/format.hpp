// Numbers as text for messages, logs and tables.
#pragma once

#include <string>

namespace pdsim {

// `v` in at most `precision` significant digits (messages, tables).
std::string number(double v, int precision = 4);

// "0.4605 mm +- 0.25 %" (prescribed motion: "force 1.2 N +- 3 %").
std::string amplitude_text(double size, double half_width, bool prescribed);

}  // namespace pdsim

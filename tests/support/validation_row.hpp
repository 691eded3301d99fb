// A validation case's outcome for validation/run_all's report (validation/report.md): when the
// environment names a file in PDSIM_VALIDATION_ROWS (ctest sets it), a test appends one line,
// tab-separated: the case, the reference and where it comes from, pdsim's value, the
// difference, the tolerance and whether it passes. The test asserts the same comparison itself;
// the row only reports it.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>

namespace pdsim {

namespace detail {
inline void append_row(const std::string& line) {
  const char* path = std::getenv("PDSIM_VALIDATION_ROWS");
  if (path == nullptr || *path == '\0') return;
  // One write of one line with O_APPEND: rows of tests run side by side do not interleave.
  const int fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return;
  const ssize_t written = write(fd, line.data(), line.size());
  (void)written;
  close(fd);
}
inline std::string text(double x) {
  std::ostringstream s;
  s.precision(4);
  s << x;
  return s.str();
}
}  // namespace detail

// pdsim's `value` against `reference` (from `source`), passing within the relative `tolerance`.
inline void validation_row(const std::string& name, const std::string& source, double reference,
                           double value, double tolerance, const std::string& units) {
  const double difference = value / reference - 1;
  detail::append_row(name + "\t" + detail::text(reference) + " " + units + "\t" + source + "\t" +
                     detail::text(value) + " " + units + "\t" + detail::text(100 * difference) +
                     " %\t" + detail::text(100 * tolerance) + " %\t" +
                     (std::fabs(difference) <= tolerance ? "pass" : "FAIL") + "\n");
}

// pdsim's `value` against an upper `bound` (from `source`).
inline void validation_bound(const std::string& name, const std::string& source, double bound,
                             double value, const std::string& units) {
  detail::append_row(name + "\t<= " + detail::text(bound) + " " + units + "\t" + source + "\t" +
                     detail::text(value) + " " + units + "\t" + detail::text(value / bound) +
                     " of the bound\t-\t" + (value <= bound ? "pass" : "FAIL") + "\n");
}

}  // namespace pdsim

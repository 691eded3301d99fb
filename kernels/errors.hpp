// The bottom of every layer, host only: the error types that carry a deck position or a
// simulation failure up to the command line.
#pragma once

#include <stdexcept>
#include <string>

namespace pdsim {

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

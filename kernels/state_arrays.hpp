// A run's checkpoint: every array its next steps depend on, by name, each in its own type.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <variant>
#include <vector>

#include "kernels/errors.hpp"

namespace pdsim {

// The checkpoint format this pdsim writes and reads. Bump it whenever an array's name, type or
// meaning changes: a checkpoint (or bed file) of another format is refused, not misread.
constexpr int kCheckpointFormat = 5;  // 5: wall_key

using StateArray = std::variant<std::vector<double>, std::vector<std::int32_t>,
                                std::vector<std::uint64_t>, std::vector<std::uint8_t>>;
using StateArrays = std::map<std::string, StateArray>;

// The array `key` of type T; a missing array or another type is a checkpoint this pdsim did not
// write.
template <class T>
const std::vector<T>& state_values(const StateArrays& in, const std::string& key) {
  const auto it = in.find(key);
  if (it == in.end()) throw SimulationError("the checkpoint lacks the array '" + key + "'");
  if (const auto* values = std::get_if<std::vector<T>>(&it->second)) return *values;
  throw SimulationError("the checkpoint's array '" + key + "' has another type than expected");
}
template <class T>
std::vector<T>& state_values(StateArrays& in, const std::string& key) {
  const StateArrays& read = in;
  return const_cast<std::vector<T>&>(state_values<T>(read, key));
}
// A one-value array.
template <class T>
T state_value(const StateArrays& in, const std::string& key) {
  const std::vector<T>& values = state_values<T>(in, key);
  if (values.size() != 1)
    throw SimulationError("the checkpoint's array '" + key + "' should hold one value");
  return values[0];
}

// One state among others in a checkpoint: its arrays under a prefix ("damper0.", "bed.r1."), and
// back.
inline void put_state(StateArrays& out, const std::string& prefix, const StateArrays& state) {
  for (const auto& [name, values] : state) out[prefix + name] = values;
}
inline StateArrays get_state(const StateArrays& in, const std::string& prefix) {
  StateArrays out;
  for (auto it = in.lower_bound(prefix); it != in.end() && it->first.rfind(prefix, 0) == 0; ++it)
    out[it->first.substr(prefix.size())] = it->second;
  return out;
}

}  // namespace pdsim

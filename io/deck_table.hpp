// A deck's TOML table as the readers see it (io/deck.cpp, io/excitations/): every value checked
// where it is read, so that an error names the key in full, its position in the file and what
// was expected, and a misspelt key or name is answered with the nearest valid one.
#pragma once

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io/deck.hpp"
#include "kernels/vec3.hpp"

namespace pdsim::deck_keys {

inline constexpr std::int64_t kMaxPeriods = 1'000'000;
inline constexpr std::size_t kMaxFrequencies = 10'000;

using Check = bool (*)(double);
inline constexpr Check positive = [](double v) { return v > 0; };
inline constexpr Check non_negative = [](double v) { return v >= 0; };
inline constexpr Check any_value = [](double) { return true; };
inline constexpr Check fraction_range = [](double v) {
  return v > 0 && v <= 1;
};  // also restitution
inline constexpr Check poisson_range = [](double v) {
  return v > -1 && v < 0.5;
};  // isotropic bounds

inline SourcePos to_pos(const std::string& file, const toml::source_region& region) {
  return {file, static_cast<int>(region.begin.line), static_cast<int>(region.begin.column)};
}

inline std::string show(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.10g", value);
  return text;
}

// A real as TOML writes it, so that 250.0 is not mistaken for the integer 250.
inline std::string show_real(double value) {
  std::string text = show(value);
  if (std::isfinite(value) && text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

// A value as quoted in a message: long ones cut, so that an error line stays a line.
inline std::string clipped(const std::string& text) {
  constexpr std::size_t kShown = 60;
  if (text.size() <= kShown) return text;
  return text.substr(0, kShown) + "... (" + std::to_string(text.size()) + " characters)";
}

// What the user wrote, for "expected X, got Y".
inline std::string describe(const toml::node& node) {
  if (auto v = node.as_floating_point()) return show_real(v->get());
  if (auto v = node.as_integer()) return std::to_string(v->get());
  if (auto v = node.as_string()) return "\"" + clipped(v->get()) + "\"";
  if (auto v = node.as_boolean()) return v->get() ? "true" : "false";
  if (node.is_array()) return "an array";
  if (node.is_table()) return "a table";
  return "a date or time";
}

inline std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

using Names = std::vector<std::string_view>;

// The valid name nearest to a misspelt one, or "" when none is near enough to be a typo
// (at most `most` edits and a third of its length plus one: 'size' is not a typo of 'shape'),
// so that the message lists the valid names instead of a wrong guess.
inline std::string_view closest(std::string_view given, const Names& valid, std::size_t most = 3) {
  std::string_view best;
  std::size_t best_distance = 1 + std::min(most, 1 + given.size() / 3);
  for (std::string_view name : valid) {
    const std::size_t d = edit_distance(given, name);
    if (d < best_distance) {
      best_distance = d;
      best = name;
    }
  }
  return best;
}

inline std::string one_of(const Names& valid) {
  std::string list;
  for (std::string_view name : valid)
    list += (list.empty() ? "\"" : ", \"") + std::string(name) + "\"";
  return "one of " + list;
}

// A TOML table with its dotted name, so that every error can name the key in full.
class Table {
 public:
  Table(const toml::table& table, std::string name, SourcePos pos)
      : table_(table), name_(std::move(name)), pos_(std::move(pos)) {}

  std::string key(std::string_view k) const {
    return name_.empty() ? std::string(k) : name_ + "." + std::string(k);
  }
  bool has(std::string_view k) const { return table_.contains(k); }
  const SourcePos& pos() const { return pos_; }
  const toml::node* node(std::string_view k) const { return table_.get(k); }

  [[noreturn]] void fail(std::string_view k, const std::string& what) const {
    const toml::node* given = table_.get(k);
    throw InputError(given ? at(*given) : pos_, key(k), what);
  }
  [[noreturn]] void missing(std::string_view k, const std::string& expected,
                            const std::string& why) const {
    throw InputError(pos_, key(k), "missing: expected " + expected + ", required " + why);
  }
  [[noreturn]] void wrong(const toml::node& node, std::string_view k,
                          const std::string& expected) const {
    throw InputError(at(node), key(k), "expected " + expected + ", got " + describe(node));
  }

  // Refuses any key not in `valid`; `context` says why the set is what it is.
  void allow_only(const Names& valid, const std::string& context = "") const {
    for (const auto& entry : table_) {
      const toml::key& k = entry.first;
      if (std::find(valid.begin(), valid.end(), k.str()) != valid.end()) continue;
      // With a context ("for kind = ..."), a key far from every valid one most likely belongs
      // to another kind ('duration' on a stepped sine): only a near typo is guessed.
      const std::string_view best = closest(k.str(), valid, context.empty() ? 3 : 2);
      std::string list;
      for (std::string_view name : valid) list += (list.empty() ? "" : ", ") + std::string(name);
      throw InputError(to_pos(pos_.file, k.source()), key(k.str()),
                       "unknown key" + context +
                           (best.empty() ? "; valid here: " + list
                                         : "; did you mean '" + std::string(best) + "'?"));
    }
  }

  std::optional<double> real(std::string_view k, const std::string& expected, Check ok) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    return real_of(*node, k, expected, ok);
  }
  double need_real(std::string_view k, const std::string& expected, Check ok,
                   const std::string& why) const {
    if (!has(k)) missing(k, expected, why);
    return *real(k, expected, ok);
  }

  std::optional<std::int64_t> integer(std::string_view k, std::int64_t lo, std::int64_t hi,
                                      const std::string& what = "") const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const auto* value = node->as_integer();
    if (!value || value->get() < lo || value->get() > hi) wrong(*node, k, range(lo, hi, what));
    return value->get();
  }
  std::int64_t need_integer(std::string_view k, std::int64_t lo, std::int64_t hi,
                            const std::string& what, const std::string& why) const {
    if (!has(k)) missing(k, range(lo, hi, what), why);
    return *integer(k, lo, hi, what);
  }

  std::optional<std::string> text(std::string_view k) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const auto* value = node->as_string();
    if (!value) wrong(*node, k, "a string");
    return value->get();
  }

  std::optional<bool> boolean(std::string_view k) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const auto* value = node->as_boolean();
    if (!value) wrong(*node, k, "true or false");
    return value->get();
  }

  // A string naming one of `names`; returns its index.
  std::optional<std::size_t> choice(std::string_view k, const Names& names) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const auto* value = node->as_string();
    if (!value) wrong(*node, k, one_of(names));
    const auto found = std::find(names.begin(), names.end(), value->get());
    if (found == names.end()) {
      const std::string_view best = closest(value->get(), names);
      throw InputError(at(*node), key(k),
                       "expected " + one_of(names) + ", got " + describe(*node) +
                           (best.empty() ? "" : "; did you mean \"" + std::string(best) + "\"?"));
    }
    return static_cast<std::size_t>(found - names.begin());
  }
  std::size_t need_choice(std::string_view k, const Names& names, const std::string& why) const {
    if (!has(k)) missing(k, one_of(names), why);
    return *choice(k, names);
  }

  // An array of numbers, each checked; `count` = 0 accepts any non-zero length.
  std::optional<std::vector<double>> reals(std::string_view k, std::size_t count,
                                           const std::string& expected, Check ok) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const toml::array* array = node->as_array();
    if (!array || array->empty() || (count > 0 && array->size() != count))
      throw InputError(at(*node), key(k), "expected " + expected + ", got " + array_shape(*node));
    std::vector<double> values;
    for (const toml::node& element : *array) values.push_back(real_of(element, k, expected, ok));
    return values;
  }

  std::optional<Vec3> vec3(std::string_view k, const std::string& expected, Check ok) const {
    const auto values = reals(k, 3, expected, ok);
    if (!values) return std::nullopt;
    return Vec3{(*values)[0], (*values)[1], (*values)[2]};
  }

  // A non-zero vector, returned normalised.
  std::optional<Vec3> direction(std::string_view k) const {
    const std::string expected = "a non-zero vector of 3 numbers [x, y, z]";
    const auto v = vec3(k, expected, any_value);
    if (!v) return std::nullopt;
    // Scaled by its largest component first, so that [1e308, 0, 1] has a length (1e308^2
    // overflows) and [1e-200, 0, 0] is not taken for zero.
    const double scale = std::max({std::fabs(v->x), std::fabs(v->y), std::fabs(v->z)});
    if (scale == 0) fail(k, "expected " + expected + ", got [0, 0, 0]");
    if (!std::isfinite(scale)) fail(k, "expected " + expected + " (finite)");
    const Vec3 w{v->x / scale, v->y / scale, v->z / scale};  // 1 / a subnormal scale is inf
    return (1.0 / norm(w)) * w;
  }

  std::optional<Table> sub(std::string_view k, const std::string& expected) const {
    const toml::node* node = table_.get(k);
    if (!node) return std::nullopt;
    const toml::table* table = node->as_table();
    if (!table) wrong(*node, k, expected);
    return Table(*table, key(k), at(*node));
  }
  Table need_sub(std::string_view k, const std::string& expected, const std::string& why) const {
    if (!has(k)) missing(k, expected, why);
    return *sub(k, expected);
  }

 private:
  SourcePos at(const toml::node& node) const { return to_pos(pos_.file, node.source()); }

  double real_of(const toml::node& node, std::string_view k, const std::string& expected,
                 Check ok) const {
    std::optional<double> value;
    if (const auto* f = node.as_floating_point()) value = f->get();
    if (const auto* i = node.as_integer()) value = static_cast<double>(i->get());
    if (!value || !std::isfinite(*value) || !ok(*value)) wrong(node, k, expected);
    return *value;
  }

  static std::string range(std::int64_t lo, std::int64_t hi, const std::string& what) {
    return "an integer " + what + (what.empty() ? "" : " ") + "from " + std::to_string(lo) +
           " to " + std::to_string(hi);
  }
  static std::string array_shape(const toml::node& node) {
    const toml::array* array = node.as_array();
    if (!array) return describe(node);
    return "an array of " + std::to_string(array->size());
  }

  const toml::table& table_;
  std::string name_;
  SourcePos pos_;
};

}  // namespace pdsim::deck_keys

// What each excitation kind is, declared once, in ExcitationKind's order: its deck name, how a
// run treats it, and the reader of its keys. The code asks these questions of a kind, not which
// kind it is. Adding a kind: its file in io/excitations/ (its keys), its entry and reader here,
// its name in ExcitationKind (io/specs.hpp); a new drive is src/coupled_system.cpp's, a new way
// to run a point src/frequency_run.cpp's.
#pragma once

#include <algorithm>
#include <vector>

#include "io/specs.hpp"

namespace pdsim {

namespace deck_keys {
class Table;  // io/deck_table.hpp
}

// Each kind's keys, read into `e` (its kind set), in its own file of io/excitations/.
void read_stepped_sine(const deck_keys::Table& t, ExcitationSpec& e);
void read_sine(const deck_keys::Table& t, ExcitationSpec& e);
void read_free_decay(const deck_keys::Table& t, ExcitationSpec& e);
void read_prescribed(const deck_keys::Table& t, ExcitationSpec& e);

struct ExcitationTraits {
  ExcitationKind kind;
  const char* name;  // excitation.kind in a deck
  // Its frequencies run each by several fills side by side (the ensemble of fills, rows in
  // /frf or /prescribed, a checkpoint per point); else one fill runs its one point (a sine's
  // frequency, a free decay). The Driver runs both alike.
  bool points;
  bool moves_containers;  // the containers' motion is prescribed (no structure is driven)
  // A point's periods: kFixed, those of excitation.duration; kSteady, until the steady state
  // (kFixedIfDuration: kFixed when a duration is given).
  enum Periods { kNone, kFixed, kSteady, kFixedIfDuration } periods;
  void (*read)(const deck_keys::Table& t, ExcitationSpec& e);
};

inline constexpr ExcitationTraits kExcitations[] = {
    {ExcitationKind::stepped_sine, "stepped_sine", true, false, ExcitationTraits::kSteady,
     read_stepped_sine},
    {ExcitationKind::sine, "sine", false, false, ExcitationTraits::kFixed, read_sine},
    {ExcitationKind::free_decay, "free_decay", false, false, ExcitationTraits::kNone,
     read_free_decay},
    {ExcitationKind::prescribed, "prescribed", true, true, ExcitationTraits::kFixedIfDuration,
     read_prescribed},
};

constexpr bool in_kind_order() {
  for (std::size_t k = 0; k < std::size(kExcitations); ++k)
    if (static_cast<std::size_t>(kExcitations[k].kind) != k) return false;
  return true;
}
static_assert(in_kind_order(), "kExcitations: its entries in ExcitationKind's order");

inline const ExcitationTraits& traits(ExcitationKind kind) {
  return kExcitations[static_cast<int>(kind)];
}

// Whether x's points run by several fills (stepped_sine, prescribed).
inline bool runs_points(const ExcitationSpec& x) {
  return traits(x.kind).points;
}

// A fixed run (sine, or prescribed motion with a duration) takes the whole periods of its
// duration and reports their means.
inline bool fixed_duration(const ExcitationSpec& x) {
  const auto p = traits(x.kind).periods;
  return p == ExcitationTraits::kFixed ||
         (p == ExcitationTraits::kFixedIfDuration && x.duration > 0);
}

// The fills a run of x starts each point with, and the most a point may grow to (a fixed
// duration keeps its first; one fill where x has no points): the Driver's, check's and the
// memory estimate's count alike.
inline int first_fills(const ExcitationSpec& x) {
  return runs_points(x) ? x.settle.realisations : 1;
}
inline int most_fills(const ExcitationSpec& x) {
  return runs_points(x) && !fixed_duration(x)
             ? std::max(x.settle.realisations, x.settle.max_realisations)
             : first_fills(x);
}

// Whether x's points run each frequency to a steady state (the detector judges them).
inline bool runs_to_steady_state(const ExcitationSpec& x) {
  const auto p = traits(x.kind).periods;
  return p == ExcitationTraits::kSteady ||
         (p == ExcitationTraits::kFixedIfDuration && x.duration <= 0);
}

// Whether x's points measure a harmonic (rows, the ensemble of fills); a free decay's one
// point records its time history only.
inline bool measures_harmonics(const ExcitationSpec& x) {
  return traits(x.kind).periods != ExcitationTraits::kNone;
}

// Whether x's points are an FRF of the structure, with a peak to report (stepped sine).
inline bool sweeps_frf(const ExcitationSpec& x) {
  return traits(x.kind).points && !traits(x.kind).moves_containers;
}

// The drive amplitude of point k: a prescribed motion's (m), else excitation.amplitude (N, m or
// m/s^2 as excitation.input says).
inline double point_amplitude(const ExcitationSpec& x, std::size_t k) {
  if (!x.amplitudes.empty()) return x.amplitudes.at(k);
  return traits(x.kind).moves_containers ? x.motion.amplitude : x.amplitude;
}

}  // namespace pdsim

// The input deck as the user wrote it, parsed and validated (io/decks.md). SI units.
// Derived quantities (masses, time step, kernel variant) live in the Scene, not here.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "io/specs.hpp"
#include "kernels/errors.hpp"

namespace pdsim {

// A parameter sweep, the [sweep] table: each key names a deck value by its dotted name
// ("damper.particles.count"; "damper[1].container.size" for one damper, "damper.x" for every
// one) and lists the values it takes. The points are every combination, numbered from 1 with
// the last key varying fastest; each is the deck with those values (sweep_point below).
struct SweepSpec {
  std::vector<std::string> keys;                     // in deck order
  std::vector<std::vector<std::string>> values;      // each value as TOML writes it
  int points() const;                                // 0 when there is no sweep
  std::vector<std::size_t> choice(int point) const;  // index of each key's value
  std::string describe(int point) const;             // "damper.particles.count = 200, ..."
};

struct Deck {
  std::string path;  // as given on the command line
  std::string text;  // the whole deck, stored as provenance
  std::string title;
  StructureSpec structure;
  std::vector<DamperSpec> dampers;
  ContactSpec contact;
  std::optional<Vec3> gravity;  // absent = no gravity
  ExcitationSpec excitation;
  BedSpec bed;
  CouplingSpec coupling;
  SolverSpec solver;
  OutputSpec output;
  SweepSpec sweep;
  MapSpec map;
  ClusterSpec cluster;
  int point = 0;  // the sweep point this deck is (1-based), 0 for the deck itself
  // Where each key given in the deck stands, by dotted name ("damper[0].particles.count").
  std::map<std::string, SourcePos> positions;

  // Position of a key (or of its closest enclosing table) for error messages.
  SourcePos where(const std::string& key) const;
};

// Parses and validates a deck; throws InputError naming file:line:column, key and expectation.
Deck load_deck(const std::string& path);
Deck parse_deck(const std::string& text, const std::string& path);

// The deck with particle snapshots every `every` seconds (`pdsim run --snapshots`), as if its
// [output] said particles = { every = ... }: a run of one continuous history, so
// settle.realisations defaults to 1 (and an explicit > 1 or start = "independent" is refused). The
// switch joins the deck's text, its provenance.
Deck with_snapshots(Deck deck, double every);

// sbatch options written as a shell would split them ("--partition=short -t '1:00:00'"),
// variables expanded (an undefined one refused when `defined`), no commands run. Throws
// InputError saying what is wrong, after "what: " unless `what` is empty; options that
// `pdsim sweep --slurm` sets itself (--array, --wrap, --parsable, --dependency) are refused.
std::vector<std::string> sbatch_options(const std::string& text, const std::string& what,
                                        bool defined = true);

// A key whose value differs between two decks (each a valid deck's text): its dotted name and
// both values as written ("absent" where one deck lacks it). Layout, comments and the order of
// keys are no change, but for pdsim's own notes (a sweep point's values, a map run's motion,
// --snapshots), compared as the key "pdsim's note".
struct DeckChange {
  std::string key, before, after;
};
// Every change from deck text `before` to `after`, by key.
std::vector<DeckChange> deck_changes(const std::string& before, const std::string& after);

// Sweep point `point` (1 to deck.sweep.points()) of a deck: the deck with that point's values,
// validated. An error names the [sweep] entry that set the value, and the point.
Deck sweep_point(const Deck& deck, int point);

}  // namespace pdsim

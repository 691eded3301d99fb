// Running a deck: the output checked and locked before any work, the fills planned and driven
// (src/driver.hpp), the file written and the summary line.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "io/deck.hpp"
#include "io/results.hpp"
#include "src/identity.hpp"
#include "src/provenance.hpp"
#include "src/run_plan.hpp"
#include "src/scene.hpp"

namespace pdsim {

struct RunOptions {
  std::string output;  // overrides output.file
  bool resume = false;
  bool force = false;
  bool quiet = false;  // no progress lines
  int threads = 0;
  int jobs = 0;  // runs side by side (independent frequencies, realisations); 0 = per core
  std::optional<Backend> backend;
  int stop_after = 0;  // stop (checkpoint kept) after this many frequencies of this session
};

struct RunReport {
  std::string output;   // path of the finished file
  std::string summary;  // one line for the terminal
};

// Output path: --output, else output.file, else the deck's name with ".h5".
std::string output_path(const Deck& deck, const RunOptions& options);
// Refuses an output path no run could write (empty, with NUL, a folder, in a folder that does
// not exist or is not writable), naming it: what `pdsim check` and every run check first.
void check_output_path(const std::string& path);
// A file beside the deck's output named for it: "OUT.h5" -> "OUT<suffix>" ("_map.h5").
std::string output_beside(const Deck& deck, const std::string& suffix);

// How many runs of the plan (fills, or independent frequencies) go side by side on the scene's
// threads (0: every core), `jobs` at most (0: one per thread).
int runs_side_by_side(const RunPlan& plan, const Scene& scene, int jobs);
// The simulated time a run of the plan takes at most, s (every fill to settle.max_periods).
double simulated_time_bound(const RunPlan& plan);
// Memory a run of the plan needs on the scene's threads, MiB (generous: for a scheduler's
// request).
double memory_estimate_mib(const RunPlan& plan, const Scene& scene);
// "" when this machine has that memory available now (/proc/meminfo), else a warning that says
// how much the run may need and how much there is.
std::string memory_shortfall(const RunPlan& plan, const Scene& scene);

// The identity (src/identity.hpp) of `deck`'s scene and bed: of `scene`, built from the deck,
// or built here (fill 0 only).
Identity deck_identity(const Deck& deck, const Scene& scene);
Identity deck_identity(const Deck& deck);

// Why `saved` (a file an earlier run of `deck` wrote: a checkpoint, a map's run, a sweep's
// point) cannot be continued or kept by `deck` now, naming each changed key and, where the keys
// are the same, each changed field of the compiled identity (a mesh file's triangles, a default
// of this pdsim), `scene` being the deck's (none: built here when needed); "" when nothing
// changed but keys that cannot alter finished points (title, solver.threads, [cluster]:
// io/decks.md).
std::string changes_since(const Results& saved, const Deck& deck, const Scene* scene = nullptr);
// The same for a run whose /meta/deck is `text`, its identity now `now()` (asked only when the
// keys agree; an InputError from it is the deck refused now).
std::string changes_since(const Results& saved, const std::string& text,
                          const std::function<Identity()>& now);

// What a run's /meta says of the deck that made it.
DeckRecord deck_record(const Deck& deck);

// Refuses a deck with a [sweep] table (not one of its points): it runs point by point.
void refuse_whole_sweep(const Deck& deck);

// Runs the deck to completion and writes its results. Throws InputError for user errors
// (existing output without --force, resume mismatch) and SimulationError for blow-ups.
RunReport run_deck(const Deck& deck, const RunOptions& options);

// A run once its deck is compiled: what its /meta says of the deck, fill 0's scene, the plan,
// where the deck names bed.file (for its refusals), and why the file of an earlier run (a
// checkpoint) cannot be continued by it ("" when it can; changes_since()).
struct CompiledRun {
  DeckRecord record;
  Scene scene;
  RunPlan plan;
  SourcePos bed_where;
  std::function<std::string(const Results& saved, const Scene& scene)> changes;
};
// `every_fill`: as build_scene().
CompiledRun compile_run(const Deck& deck, int threads, std::optional<Backend> backend,
                        bool every_fill = true);

// Refuses an output no run may write (check_output_path(), an existing file without `force`),
// warns when its disk is nearly full, and holds its lock (removing what a killed run left
// there) until the returned lock is dropped.
std::unique_ptr<OutputLock> claim_output(const std::string& path, bool force);

// Runs `run` into `path` (claimed: claim_output()) as run_deck() does.
RunReport run_compiled(const CompiledRun& run, const std::string& path, const RunOptions& options);

// Runs the deck and returns the results without writing a file (tests, benchmarks); `jobs` runs
// side by side when the deck has several (independent frequencies, realisations).
Results simulate(const Deck& deck, const Scene& scene, bool quiet = true, int jobs = 1);

}  // namespace pdsim

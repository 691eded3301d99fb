// The driver of a run: a plan's points on its fills, side by side, with checkpoints after
// every finished point, the rows of the finished points and the run's provenance.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <optional>

#include "io/results.hpp"
#include "src/provenance.hpp"
#include "src/run_plan.hpp"
#include "src/scene.hpp"

namespace pdsim {

// Runs a plan's points on its fills (realisations: fill seeds seed + r). A point (one
// frequency of one sweep) starts with settle.realisations fills; while the ensemble mean is
// not known to the tolerance, fills are added up to settle.max_realisations. In a carried
// sweep every fill carries its state from one point to the next, so that a fill added at a
// point first catches up: it runs every earlier point from its own settled bed, to its own
// criterion, exactly as a fill carried all the way (its values there join those points). With
// start = "independent" a task is one point, its fills from their own beds, the tasks side by
// side. Fills run `jobs` at a time; what a fill computes never depends on that schedule.
class Driver {
 public:
  using SceneMaker = std::function<Scene(int fill)>;
  // `plan` says what runs, `first` is fill 0's scene, `make_scene(r)` builds fill r's;
  // `kept_beds` the beds read from bed.file (read_bed_file()), if any; `dump_path` receives the
  // particles of a run that blows up ("" : none).
  Driver(DeckRecord deck, RunPlan plan, std::optional<Results> kept_beds, Scene first,
         SceneMaker make_scene, int jobs, bool quiet, std::string dump_path);
  ~Driver();
  // Continues from the checkpoint of an interrupted run (its points, beds and records).
  void resume_from(const Results& partial);
  // Runs every point not yet done; `checkpoint` receives a snapshot after each finished point
  // while points remain; `stop_after` > 0 stops after that many points (checkpoint kept).
  Results run(const std::function<void(const Results&)>& checkpoint, int stop_after);
  bool stopped() const;
  // What a failed run had computed, or nullptr.
  const Results* failed() const;
  std::size_t finished() const;  // points finished in this process

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pdsim

#include "src/bed_file.hpp"

#include <filesystem>

#include "src/format.hpp"

namespace pdsim {

std::optional<Results> read_bed_file(const Scene& scene, const RunPlan& plan,
                                     const SourcePos& where) {
  const std::string& file = plan.bed.file;
  if (file.empty()) return std::nullopt;
  std::error_code unseen;
  const bool there = std::filesystem::exists(file, unseen);
  if (unseen)
    throw InputError(where, "bed.file",
                     "'" + file + "' cannot be examined (" + unseen.message() +
                         "); expected a file pdsim may read and write");
  if (!there) return std::nullopt;
  Results saved;
  try {
    saved = read_results(file);
  } catch (const std::exception& e) {
    throw InputError(where, "bed.file",
                     "'" + file + "' is not a bed pdsim kept (" + e.what() +
                         "); delete it or name another file");
  }
  const auto kept = saved.meta_text.find("identity");
  if (kept == saved.meta_text.end())
    throw InputError(where, "bed.file",
                     "'" + file +
                         "' holds a bed kept by an older pdsim, which did not record what it "
                         "was settled for; delete it (the bed is settled again) or name "
                         "another file");
  if (const std::string differ =
          identity_difference(parse_identity(kept->second), scene_identity(scene, plan.bed),
                              IdentityScope::bed, "in the file", "in the deck");
      !differ.empty())
    throw InputError(where, "bed.file",
                     "'" + file + "' holds a bed settled for another damper (" + differ +
                         "); delete it or name another file");
  const double held =
      saved.meta_numbers.count("realisations") != 0 ? saved.meta_numbers.at("realisations") : 0.0;
  const int first = plan.first_fills;
  if (held < first)
    throw InputError(where, "bed.file",
                     "'" + file + "' holds " + number(held) +
                         " settled fills, the run starts with " + std::to_string(first) +
                         " (settle.realisations); delete it or name another file");
  return saved;
}

}  // namespace pdsim

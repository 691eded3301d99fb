// A bounded fuzz driver for the deck parser and the scene builder, run in CI: every deck of
// tests/decks and examples/ is mutated a fixed number of times (fixed seed, so a failure
// reproduces) by the edits that found bugs before (extreme numbers, wrong types, cut or
// doubled lines, stray bytes), and each mutant must either build or be refused with an
// InputError that names its file and line. Anything else (another exception, a crash, a hang
// that trips the test timeout) is a defect. Build with -fsanitize=address,undefined to extend
// the same driver to memory errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "io/deck.hpp"
#include "src/scene.hpp"

using namespace pdsim;
namespace fs = std::filesystem;

namespace {

std::vector<std::string> corpus() {
  std::vector<std::string> decks;
  for (const char* folder : {"/decks", "/../examples"})
    for (const auto& entry : fs::directory_iterator(std::string(PDSIM_TEST_DIR) + folder))
      if (entry.path().extension() == ".toml") {
        std::ifstream in(entry.path());
        std::stringstream s;
        s << in.rdbuf();
        decks.push_back(s.str());
      }
  std::sort(decks.begin(), decks.end());  // the directory order is the file system's
  return decks;
}

// One random edit of `text`.
std::string mutate(std::string text, std::mt19937_64& rng) {
  static const std::vector<std::string> values = {
      "1e308",    "-1e308",      "5e-324",        "0",
      "-1",       "nan",         "inf",           "-inf",
      "1e-300",   "\"\"",        "\"x\"",         "[]",
      "{}",       "true",        "[1e308, 0, 1]", "9223372036854775807",
      "-0.0",     "1e30",        "2e9",           "[0, 0, 0]",
      "50000000", "\"lattice\"", "[[1]]"};
  auto pick = [&](std::size_t n) {
    return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
  };
  if (text.empty()) return text;
  switch (pick(6)) {
    case 0: {  // a value replaced
      const std::size_t eq = text.find(" = ", pick(text.size()));
      if (eq == std::string::npos) break;
      const std::size_t end = text.find_first_of(",}\n#", eq + 3);
      text.replace(eq + 3, (end == std::string::npos ? text.size() : end) - eq - 3,
                   values[pick(values.size())]);
      break;
    }
    case 1: {  // a line dropped
      const std::size_t start = text.rfind('\n', pick(text.size()));
      const std::size_t from = start == std::string::npos ? 0 : start + 1;
      const std::size_t end = text.find('\n', from);
      text.erase(from, end == std::string::npos ? std::string::npos : end - from + 1);
      break;
    }
    case 2: {  // a line doubled
      const std::size_t start = text.rfind('\n', pick(text.size()));
      const std::size_t from = start == std::string::npos ? 0 : start + 1;
      const std::size_t end = text.find('\n', from);
      text.insert(from,
                  text.substr(from, end == std::string::npos ? std::string::npos : end - from + 1));
      break;
    }
    case 3:  // a byte changed
      text[pick(text.size())] = static_cast<char>(pick(256));
      break;
    case 4:  // cut short
      text.resize(pick(text.size()));
      break;
    default: {  // a digit changed (a count, a size, an exponent)
      const std::size_t at = text.find_first_of("0123456789", pick(text.size()));
      if (at != std::string::npos) text[at] = static_cast<char>('0' + pick(10));
      break;
    }
  }
  return text;
}

}  // namespace

TEST_CASE("fuzzed decks either build or are refused with their file and line, nothing else") {
  const std::vector<std::string> decks = corpus();
  REQUIRE(decks.size() >= 8);
  std::mt19937_64 rng(20261201);
  int built = 0, refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string text = decks[static_cast<std::size_t>(trial) % decks.size()];
    const int edits = 1 + trial % 3;
    for (int k = 0; k < edits; ++k) text = mutate(text, rng);
    CAPTURE(trial);
    CAPTURE(text);
    try {
      const Deck deck = parse_deck(text, "fuzz.toml");
      if (deck.sweep.points() > 0) sweep_point(deck, 1);
      build_scene(deck, 1, Backend::cpu);
      ++built;
    } catch (const InputError& e) {
      ++refused;
      CHECK(std::string(e.what()).rfind("fuzz.toml", 0) == 0);
    }
  }
  MESSAGE(built << " mutants built, " << refused << " refused");
  CHECK(refused > 500);  // the mutations do reach the checks
  CHECK(built > 100);    // and do not only break the syntax
}

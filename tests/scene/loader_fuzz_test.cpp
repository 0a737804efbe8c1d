// Robustness of the loaders: valid NFF and JSON text, randomly mutated, must
// come back as an error naming the input or as a scene that validates; never
// a crash, a hang or (under LOCUS_SANITIZE) a memory error. Seeded: a failure
// prints its seed, and LOCUS_FUZZ_SEED=<n> replays from it.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "common/scene/scene_io.h"

namespace locus {
namespace {

std::string read(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

unsigned first_seed() {
  const char* env = std::getenv("LOCUS_FUZZ_SEED");
  return env ? static_cast<unsigned>(std::strtoul(env, nullptr, 10)) : 1u;
}

// One random edit: the kinds of damage a hand-edited or truncated scene
// file shows, plus bytes from the format's own alphabet so that mutants
// often stay nearly valid and reach the deeper checks.
std::string mutate(std::string text, std::mt19937& rng, bool json) {
  static const char* kNffPieces[] = {
      " ",  "\n", "-",   "0", "1e999", "nan", "inf", "#",      "p ",   "pp",       "s ",
      "c ", "f ", "v\n", "3", "-1",    ".",   "e",   "1e-300", "\r\n", "l 0 0 0 ", "99999999999"};
  static const char* kJsonPieces[] = {"{",
                                      "}",
                                      "[",
                                      "]",
                                      "\"",
                                      ":",
                                      ",",
                                      "0",
                                      "-1",
                                      "\"NaN\"",
                                      "1e9",
                                      "null",
                                      "true",
                                      "\"x\"",
                                      "\\",
                                      " ",
                                      "\"csg\": {\"left\": 0, \"right\": 0}",
                                      "\"radius\": 0",
                                      "\"sphere\"",
                                      "[[[[",
                                      "1e999"};
  auto pos = [&] { return text.empty() ? size_t{0} : rng() % (text.size() + 1); };
  switch (rng() % 7) {
    case 0: {  // delete a range
      const size_t at = pos();
      text.erase(at, rng() % 16);
      break;
    }
    case 1: {  // insert a piece of the format
      const char* piece = json ? kJsonPieces[rng() % std::size(kJsonPieces)]
                               : kNffPieces[rng() % std::size(kNffPieces)];
      text.insert(pos(), piece);
      break;
    }
    case 2: {  // overwrite a byte with anything
      if (!text.empty()) text[rng() % text.size()] = static_cast<char>(rng() % 256);
      break;
    }
    case 3:  // truncate
      text.resize(pos());
      break;
    case 4: {  // duplicate a range
      const size_t at = pos();
      const std::string piece = text.substr(at, rng() % 64);
      text.insert(pos(), piece);
      break;
    }
    case 5: {  // swap two ranges' first bytes
      if (text.size() > 1) std::swap(text[rng() % text.size()], text[rng() % text.size()]);
      break;
    }
    default: {  // flip a digit
      for (int tries = 0; tries < 32 && !text.empty(); ++tries) {
        char& c = text[rng() % text.size()];
        if (c >= '0' && c <= '9') {
          c = static_cast<char>('0' + rng() % 10);
          break;
        }
      }
      break;
    }
  }
  return text;
}

// Returns how many mutants loaded, so the caller can tell that mutants
// reach past the syntax checks.
int fuzz(const std::string& base, const std::string& name, bool json, int rounds) {
  // Mutants of s1/teapot.nff keep its zero-area patches: one warning each.
  const spdlog::level::level_enum level = spdlog::get_level();
  spdlog::set_level(spdlog::level::err);
  struct Restore {
    spdlog::level::level_enum level;
    ~Restore() { spdlog::set_level(level); }
  } restore{level};
  const unsigned start = first_seed();
  int accepted = 0;
  for (unsigned seed = start; seed < start + static_cast<unsigned>(rounds); ++seed) {
    std::mt19937 rng(seed);
    std::string text = base;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) text = mutate(std::move(text), rng, json);
    Result<Scene> r = json ? parse_scene_json(text, name, "") : parse_nff(text, name);
    if (r.ok()) {
      ++accepted;
      const std::vector<std::string> problems = validate_scene(*r);
      EXPECT_TRUE(problems.empty()) << "seed " << seed << ": accepted a scene that does not "
                                    << "validate: " << problems[0];
    } else {
      EXPECT_EQ(r.status().message().rfind(name + ":", 0), 0u)
          << "seed " << seed << ": message does not name the input: " << r.status().message();
    }
    if (testing::Test::HasFailure()) break;
  }
  std::printf("%s: %d of %d mutants loaded\n", name.c_str(), accepted, rounds);
  return accepted;
}

TEST(LoaderFuzz, MutatedNff) {
  for (const char* file : {"s1/jacks.nff", "s1/tetra.nff", "s1/teapot.nff", "s1/rings.nff"}) {
    SCOPED_TRACE(file);
    const std::string text = read(std::string(LOCUS_SHARED_DIR) + "/spd/" + file);
    ASSERT_FALSE(text.empty());
    EXPECT_GT(fuzz(text, "fuzz.nff", false, 400), 10);
  }
}

TEST(LoaderFuzz, MutatedJson) {
  const std::string text = R"({
  "camera": {"from": [0, 2, 8], "at": [0, 0.5, 0], "angle": 40, "width": 32, "height": 24},
  "background": [0.1, 0.2, 0.3],
  "lights": [{"position": [-5, 8, 6]}, {"position": [5, 6, 4], "color": [1, 1, 1]}],
  "materials": [{"kd": 0.8}, {"ks": 0.2, "t": 0.7, "ior": 1.5, "absorption": [0.1, 0.1, 0.1]}],
  "objects": [
    {"polygon": {"vertices": [-5, 0, 5, 5, 0, 5, 5, 0, -5, -5, 0, -5]}},
    {"material": 1, "sphere": {"center": [0, 1, 0], "radius": 1}},
    {"box": {"min": [-3, 0, -1], "max": [-2, 1, 0]}, "transform": {"rotate": [{"axis": [0, 1, 0], "degrees": 30}]}},
    {"prism": {"sides": 6, "radius": 0.5, "base": [2.5, 0, 0], "apex": [2.5, 1.5, 0]}},
    {"cylinder": {"base": [0, 0, 0], "apex": [0, 0.3, 0], "radius": 0.6, "capped": true}},
    {"cone": {"base": [0, 0, 0], "base_radius": 0.5, "apex": [0, 1, 0], "capped": true}},
    {"csg": {"op": "DIFFERENCE", "left": 4, "right": 5}, "transform": {"translate": [-2, 0, 2]}},
    {"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0.2, 0.2, 0.2]}},
    {"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1],
                    "faces": [{"vertices": [0, 2, 1]}, {"vertices": [0, 1, 3]}, {"vertices": [0, 3, 2]}, {"vertices": [1, 2, 3]}]}},
    {"patch": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "normals": [0, 0, 1, 0, 0, 1, 0, 0, 1]}},
    {"mesh": {"positions": [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0], "indices": [0, 1, 2, 2, 1, 3]},
     "transform": {"matrix": [1, 0, 0, -4, 0, 1, 0, 0, 0, 0, 1, -3, 0, 0, 0, 1]}}
  ]
})";
  ASSERT_TRUE(parse_scene_json(text, "fuzz.json", "").ok());
  EXPECT_GT(fuzz(text, "fuzz.json", true, 1500), 20);
}

}  // namespace
}  // namespace locus

// The fuzz targets' bodies (tests/fuzz/) replayed in the ordinary build,
// and under ASan in build-asan: on every seed in tests/fuzz/corpus/ and
// every input in tests/fuzz/regressions/, where an input that once crashed
// a target is kept (named after what it found) once fixed. A violated
// property aborts, which fails the test binary.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "tests/fuzz/coordinator_target.h"
#include "tests/fuzz/http_target.h"
#include "tests/fuzz/fuzz_util.h"

namespace locus::fuzz {
namespace {
namespace fs = std::filesystem;

// Runs `target` on every file of tests/fuzz/{corpus,regressions}/<dir>;
// returns how many.
template <typename Target>
int replay(const std::string& dir, Target target) {
  // Keep this process's logs as they are (the targets silence them).
  setenv("LOCUS_FUZZ_LOG", "1", 1);
  int n = 0;
  for (const char* kind : {"corpus", "regressions"}) {
    const fs::path root = fs::path(LOCUS_SOURCE_DIR) / "tests" / "fuzz" / kind / dir;
    if (!fs::is_directory(root)) continue;
    for (const auto& entry : fs::directory_iterator(root)) {
      if (!entry.is_regular_file() || entry.path().filename().string()[0] == '.') continue;
      std::ifstream in(entry.path(), std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      const std::string input = bytes.str();
      SCOPED_TRACE(entry.path().string());
      target(reinterpret_cast<const uint8_t*>(input.data()), input.size());
      ++n;
    }
  }
  unsetenv("LOCUS_FUZZ_LOG");
  return n;
}

TEST(FuzzRegression, NffInputs) { EXPECT_GE(replay("nff", fuzz_nff), 5); }
TEST(FuzzRegression, SceneJsonInputs) { EXPECT_GE(replay("json", fuzz_scene_json), 4); }
TEST(FuzzRegression, CoordinatorInputs) { EXPECT_GE(replay("coordinator", fuzz_coordinator), 3); }
TEST(FuzzRegression, HttpInputs) { EXPECT_GE(replay("http", fuzz_http), 3); }

}  // namespace
}  // namespace locus::fuzz

// libFuzzer target: the native JSON scene loader (syntax pre-check,
// protobuf's JSON parser, conversion and validation) on arbitrary text.
// Relative OBJ paths resolve under an empty directory, so they name
// nothing; an absolute one may read a file, which the loader must survive.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common/scene_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  locus::fuzz::quiet_logs();
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto scene = locus::parse_scene_json(text, "fuzz.json", locus::fuzz::empty_dir());
  if (!scene.ok()) {
    locus::fuzz::check_error(scene.status(), "fuzz.json");
    return 0;
  }
  locus::fuzz::check_round_trip(*scene);
  return 0;
}

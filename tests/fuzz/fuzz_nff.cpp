// libFuzzer target: the NFF loader on arbitrary text. Every input must come
// back as a scene that survives the wire form's round trip, or as an error
// naming the input; never a crash, a hang or a sanitizer report.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "common/scene_io.h"
#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  locus::fuzz::quiet_logs();
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto scene = locus::parse_nff(text, "fuzz.nff");
  if (!scene.ok()) {
    locus::fuzz::check_error(scene.status(), "fuzz.nff");
    return 0;
  }
  locus::fuzz::check_round_trip(*scene);
  return 0;
}

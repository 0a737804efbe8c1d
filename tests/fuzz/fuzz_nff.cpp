// libFuzzer target: the NFF loader on arbitrary text (fuzz_util.h).
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return locus::fuzz::fuzz_nff(data, size);
}

// libFuzzer target: the coordinator's request handling without a network
// (coordinator_target.h).
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/coordinator_target.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return locus::fuzz::fuzz_coordinator(data, size);
}

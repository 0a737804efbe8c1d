// libFuzzer target: the HTTP API's request handling without a socket
// (http_target.h).
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/http_target.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return locus::fuzz::fuzz_http(data, size);
}

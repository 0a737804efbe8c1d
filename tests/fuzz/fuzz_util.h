// What the fuzz targets share: silence, and the properties checked on every
// input beyond "no crash" (a failed check aborts, which libFuzzer reports).
#pragma once

#include <google/protobuf/stubs/logging.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "common/scene_io.h"
#include "common/status.h"
#include "proto/scene.pb.h"

namespace locus::fuzz {

// LOCUS_FUZZ_LOG=1 keeps the logs, to see what an input reaches.
inline void quiet_logs() {
  if (std::getenv("LOCUS_FUZZ_LOG")) return;
  spdlog::set_level(spdlog::level::off);
  google::protobuf::SetLogHandler(nullptr);  // e.g. "invalid UTF-8" on every such input
}

[[noreturn]] inline void violated(const std::string& what) {
  std::fprintf(stderr, "fuzz property violated: %s\n", what.c_str());
  std::abort();
}

// A user error names the input it is about.
inline void check_error(const Status& status, const std::string& name) {
  if (status.code() != Code::kInvalidArgument && status.code() != Code::kNotFound &&
      status.code() != Code::kFailedPrecondition) {
    violated("unexpected status code for " + name + ": " + status.message());
  }
  if (status.message().find(name) == std::string::npos)
    violated("error does not name the input: " + status.message());
}

// A loaded scene goes on the wire and comes back as a valid scene.
inline void check_round_trip(const Scene& scene) {
  const v1::Scene proto = scene_to_proto(scene);
  auto back = scene_from_proto(proto, "round trip");
  if (!back.ok()) violated("scene_from_proto(scene_to_proto(s)) failed: " + back.status().message());
  if (back->objects.size() != scene.objects.size() || back->lights.size() != scene.lights.size())
    violated("round trip changed the scene's size");
}

// An empty directory for relative paths to resolve under.
inline const std::string& empty_dir() {
  static const std::string dir = [] {
    std::string t = (std::filesystem::temp_directory_path() / "locus-fuzz-XXXXXX").string();
    if (!mkdtemp(t.data())) violated("cannot create a temporary directory");
    return t;
  }();
  return dir;
}

}  // namespace locus::fuzz

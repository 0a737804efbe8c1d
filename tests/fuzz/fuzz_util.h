// What the fuzz targets share: silence, and the properties checked on every
// input beyond "no crash" (a failed check aborts, which libFuzzer reports).
#pragma once

#include <google/protobuf/stubs/logging.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "common/base/status.h"
#include "common/scene/scene_io.h"
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

// A scratch directory, removed at exit: relative OBJ paths resolve under
// it (it holds no OBJ file), and the coordinator target keeps its data there.
inline const std::string& scratch_dir() {
  struct Dir {
    std::string path;
    Dir() {
      path = (std::filesystem::temp_directory_path() / "locus-fuzz-XXXXXX").string();
      if (!mkdtemp(path.data())) violated("cannot create a temporary directory");
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

// The loader targets' bodies (fuzz_nff.cpp, fuzz_scene_json.cpp), also
// replayed on the corpus by the gtest suite (tests/fuzz_corpus_test.cpp).
// Every input must come back as a scene that survives the wire form's
// round trip, or as an error naming the input.
inline int fuzz_nff(const uint8_t* data, size_t size) {
  quiet_logs();
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto scene = parse_nff(text, "fuzz.nff");
  if (!scene.ok()) {
    check_error(scene.status(), "fuzz.nff");
    return 0;
  }
  check_round_trip(*scene);
  return 0;
}

// Relative OBJ paths resolve under a directory that does not exist, so they name
// nothing; an absolute one may read a file, which the loader must survive.
inline int fuzz_scene_json(const uint8_t* data, size_t size) {
  quiet_logs();
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto scene = parse_scene_json(text, "fuzz.json", scratch_dir() + "/scenes");
  if (!scene.ok()) {
    check_error(scene.status(), "fuzz.json");
    return 0;
  }
  check_round_trip(*scene);
  return 0;
}

}  // namespace locus::fuzz

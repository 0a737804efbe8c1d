// The per-part semantic checks behind validate_scene (scene_io.h). The
// loaders call them too, so that each rule lives once while every loader
// words the location its own way: "balls.nff:12: sphere radius ..." for NFF,
// "scene.json: objects[3].sphere.radius: ..." for JSON.
#pragma once

#include <string>
#include <vector>

#include "common/base/status.h"
#include "common/base/text.h"
#include "common/scene/scene.h"

namespace locus {

// One thing wrong with a part of the scene. `field` is relative to the part
// ("radius", "faces[2]"), empty when the part as a whole is wrong.
struct Problem {
  std::string field;
  std::string what;
};
using Problems = std::vector<Problem>;

// Tolerances, relative to the size (bounding-box diagonal) of the polygon or
// polyhedron at hand. A polygon may bend off its plane by kPlanarityTolerance
// (round-off in printed coordinates is far below it); twice its area must
// exceed kAreaTolerance * size^2, else its vertices are taken as collinear.
inline constexpr double kPlanarityTolerance = 1e-4;
inline constexpr double kAreaTolerance = 1e-12;

// A shape's own geometry, in object space. CSG operand indices need the whole
// scene and are checked by validate_scene.
Problems check_shape(const Shape& shape);
Problems check_camera(const Camera& camera);
Problems check_light(const Light& light);
Problems check_material(const Material& material);

// A planar polygon: at least 3 finite vertices, none repeated, not all
// collinear, planar within kPlanarityTolerance.
Problems check_polygon(const std::vector<Vec3>& vertices);
// True when the vertices are finite but span no area (all collinear or
// coincident), the case the NFF loader drops rather than rejects.
bool has_zero_area(const std::vector<Vec3>& vertices);

// ---- Plumbing shared by the loaders ----

// One InvalidArgument carrying the problems one per line; past kMaxReported
// lines the rest is counted, not listed (a file can be wrong on every line).
inline constexpr size_t kMaxReported = 100;
Status problems_status(const std::vector<std::string>& problems);

// The whole file; NotFound naming the path and the reason when unreadable.
Result<std::string> read_text_file(const std::string& path);

}  // namespace locus

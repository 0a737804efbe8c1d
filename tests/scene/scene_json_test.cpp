// The native JSON loader and the proto conversion (common/scene/scene_json.cpp,
// json_syntax.cpp, scene_proto.cpp, obj.cpp): defaults, every semantic error named by its
// JSON path, OBJ meshes, and the wire round trip.
#include <google/protobuf/util/message_differencer.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/scene/polyhedron.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCamera =
    R"("camera": {"from": [0, 0, 5], "at": [0, 0, 0], "width": 64, "height": 48})";

// A scene with a camera, one material and the given objects (and extra
// top-level fields, if any).
std::string scene_with(const std::string& objects, const std::string& extra = "") {
  return std::string("{") + kCamera + R"(, "materials": [{}], "objects": [)" + objects + "]" +
         (extra.empty() ? "" : ", " + extra) + "}";
}

Result<Scene> parse(const std::string& json) { return parse_scene_json(json, "scene.json", ""); }

std::string error_of(const std::string& json) {
  Result<Scene> r = parse(json);
  EXPECT_FALSE(r.ok()) << "accepted:\n" << json;
  return r.ok() ? "" : r.status().message();
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() / ("locus_" + std::string(info->test_suite_name()) + "_" +
                                         info->name() + "_" + std::to_string(::getpid()));
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  fs::path write(const std::string& name, const std::string& text) const {
    std::ofstream(path_ / name) << text;
    return path_ / name;
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

TEST(SceneJson, MinimalSceneTakesTheDefaults) {
  Result<Scene> r = parse(scene_with(R"({"sphere": {"radius": 1}})"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Scene& s = *r;
  EXPECT_EQ(s.source, "scene.json");
  ASSERT_TRUE(s.has_camera);
  EXPECT_EQ(s.camera.up, Vec3(0, 1, 0));
  EXPECT_EQ(s.camera.angle, 45.0);
  EXPECT_EQ(s.camera.hither, 1e-3);
  EXPECT_EQ(s.camera.width, 64);
  EXPECT_EQ(s.background, Color(0.0));
  EXPECT_FALSE(s.ambient);
  const Material& m = s.materials[0];
  EXPECT_EQ(m.color, Color(1.0));
  EXPECT_EQ(m.kd, 1.0);
  EXPECT_EQ(m.ks, 0.0);
  EXPECT_EQ(m.t, 0.0);
  EXPECT_EQ(m.ior, 1.0);
  EXPECT_EQ(m.absorption, Color(0.0));
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].origin, "objects[0]");
  EXPECT_EQ(std::get<Sphere>(s.objects[0].shape).center, Vec3(0.0));
  EXPECT_EQ(s.objects[0].world_from_object, Mat4(1.0));
}

// The example in docs/scene-format.md is a complete, valid scene.
TEST(SceneJson, DocumentedExampleLoads) {
  std::ifstream in(fs::path(LOCUS_SOURCE_DIR) / "docs/scene-format.md");
  ASSERT_TRUE(in) << "docs/scene-format.md";
  std::string line, json;
  bool inside = false;
  while (std::getline(in, line)) {
    if (line == "```json") {
      inside = true;
    } else if (inside && line == "```") {
      break;
    } else if (inside) {
      json += line + "\n";
    }
  }
  ASSERT_FALSE(json.empty());
  Result<Scene> r = parse_scene_json(json, "example.json", "");
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Scene& s = *r;
  EXPECT_EQ(s.camera.width, 320);
  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_FALSE(s.lights[0].emission);
  EXPECT_EQ(*s.lights[1].emission, Color(0.5, 0.45, 0.4));
  EXPECT_EQ(s.materials[1].absorption, Color(0.1, 0.02, 0.02));
  ASSERT_EQ(s.objects.size(), 9u);
  EXPECT_EQ(std::get<Polyhedron>(s.objects[2].shape).faces.size(), 6u);  // box
  EXPECT_EQ(std::get<Polyhedron>(s.objects[3].shape).faces.size(), 8u);  // hexagonal prism
  const Cone& tube = std::get<Cone>(s.objects[4].shape);
  EXPECT_EQ(tube.base_radius, tube.apex_radius);
  EXPECT_TRUE(tube.capped);
  EXPECT_EQ(std::get<Csg>(s.objects[6].shape).op, CsgOp::kDifference);
  EXPECT_EQ(std::get<Polyhedron>(s.objects[7].shape).faces.size(), 4u);  // hull
  EXPECT_EQ(std::get<Mesh>(s.objects[8].shape).triangles.size(), 2u);
  EXPECT_EQ(transform_point(s.objects[8].world_from_object, Vec3(0.0)), Vec3(-4, 0, -3));
  const std::vector<bool> operand = csg_operand_mask(s);
  EXPECT_TRUE(operand[4] && operand[5]);
  EXPECT_FALSE(operand[6] || operand[1]);
}

TEST(SceneJson, LightsAndAmbient) {
  Result<Scene> r = parse(scene_with("", R"("ambient": 0.2, "lights": [{"position": [1, 2, 3]},
           {"position": [0, 0, 0], "color": [1, 0.5, 0], "intensity": 2},
           {"position": [0, 0, 0], "intensity": 0.25}])"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->lights[0].position, Vec3(1, 2, 3));
  EXPECT_FALSE(r->lights[0].emission);
  EXPECT_EQ(*r->lights[1].emission, Color(2, 1, 0));
  EXPECT_EQ(*r->lights[2].emission, Color(0.25));
  EXPECT_EQ(ambient_intensity(*r), 0.2);
  EXPECT_DOUBLE_EQ(light_emission(*r, 0).x, std::sqrt(3.0) / 6.0);
}

TEST(SceneJson, TransformsComposeScaleRotateTranslate) {
  Result<Scene> r = parse(scene_with(
      R"({"sphere": {"radius": 1}, "transform": {"scale": 2,
          "rotate": [{"axis": [0, 0, 1], "degrees": 90}], "translate": [10, 0, 0]}},
         {"sphere": {"radius": 1}, "transform": {"scale": [1, 2, 3]}},
         {"sphere": {"radius": 1},
          "transform": {"matrix": [1, 0, 0, 4, 0, 1, 0, 5, 0, 0, 1, 6, 0, 0, 0, 1]}})"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Vec3 p = transform_point(r->objects[0].world_from_object, Vec3(1, 0, 0));
  EXPECT_NEAR(p.x, 10, 1e-12);
  EXPECT_NEAR(p.y, 2, 1e-12);
  EXPECT_NEAR(p.z, 0, 1e-12);
  EXPECT_EQ(transform_point(r->objects[1].world_from_object, Vec3(1, 1, 1)), Vec3(1, 2, 3));
  // Row-major in the file, column-major in glm.
  EXPECT_EQ(r->objects[2].world_from_object[3], glm::dvec4(4, 5, 6, 1));
}

TEST(SceneJson, ShapesBecomeTheSceneModel) {
  Result<Scene> r = parse(scene_with(
      R"({"cylinder": {"base": [0, 0, 0], "apex": [0, 2, 0], "radius": 0.5}},
         {"cone": {"base": [0, 0, 0], "base_radius": 1, "apex": [0, 1, 0], "capped": true}},
         {"box": {"min": [0, 0, 0], "max": [1, 2, 3]}},
         {"prism": {"sides": 5, "radius": 1, "base": [0, 0, 0], "apex": [0, 0, 1]}},
         {"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1],
                         "faces": [{"vertices": [0, 2, 1]}, {"vertices": [0, 1, 3]},
                                   {"vertices": [0, 3, 2]}, {"vertices": [1, 2, 3]}]}},
         {"polygon": {"vertices": [0, 0, 0, 2, 0, 0, 1, 1, 0, 0, 2, 0]}},
         {"patch": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "normals": [0, 0, 1, 0, 0, 1, 0, 0, 1]}},
         {"mesh": {"positions": [0, 0, 0, 1, 0, 0, 0, 1, 0], "indices": [0, 1, 2]}})"));
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto& objects = r->objects;
  const Cone& cyl = std::get<Cone>(objects[0].shape);
  EXPECT_EQ(cyl.base_radius, 0.5);
  EXPECT_EQ(cyl.apex_radius, 0.5);
  EXPECT_FALSE(cyl.capped);
  EXPECT_EQ(std::get<Cone>(objects[1].shape).apex_radius, 0.0);
  EXPECT_EQ(std::get<Polyhedron>(objects[2].shape).vertices.size(), 8u);
  EXPECT_EQ(std::get<Polyhedron>(objects[3].shape).faces.size(), 7u);
  EXPECT_EQ(std::get<Polyhedron>(objects[4].shape).faces[0], (std::vector<int>{0, 2, 1}));
  EXPECT_EQ(std::get<Polygon>(objects[5].shape).vertices.size(), 4u);
  EXPECT_EQ(std::get<Patch>(objects[6].shape).normals.size(), 3u);
  EXPECT_EQ(std::get<Mesh>(objects[7].shape).triangles[0], (std::array<int, 3>{0, 1, 2}));
}

// ---- Syntax and schema errors ----

TEST(SceneJson, UnknownFieldIsRejectedWithItsPath) {
  EXPECT_EQ(error_of(scene_with(R"({"sphere": {"radius": 1, "radious": 2}})")),
            "scene.json: objects[0].sphere.radious: unknown field (docs/scene-format.md lists the "
            "fields)");
  EXPECT_EQ(error_of(R"({"camra": {}})"),
            "scene.json: camra: unknown field (docs/scene-format.md lists the fields)");
}

TEST(SceneJson, SyntaxErrorsNameLineAndColumn) {
  EXPECT_EQ(error_of("{\n  \"camera\": {\n    \"from\": [0, 0, 5]\n    \"at\": [0, 0, 0]\n}}"),
            "scene.json:4:5: expected ',' or '}' after a value in an object");
  EXPECT_EQ(error_of("{\"background\": [1, 2, ]}"),
            "scene.json:1:23: expected a value (a number, string, object, array, true, false or "
            "null)");
  EXPECT_EQ(error_of("[1, 2]"), "scene.json:1:1: a scene file must hold one JSON object { ... }");
  EXPECT_EQ(error_of("{} extra"), "scene.json:1:4: unexpected text after the scene object");
  EXPECT_EQ(error_of("{\"a\": \"open"), "scene.json:1:12: the file ends inside a string");
  EXPECT_EQ(error_of(""), "scene.json:1:1: a scene file must hold one JSON object { ... }");
  EXPECT_CONTAINS(error_of(std::string(200, '[')), "scene.json:1:1:");
  EXPECT_CONTAINS(error_of("{\"a\":" + std::string(200, '[')), "nested deeper than 100 levels");
}

TEST(SceneJson, RepeatedKeysAreRejected) {
  EXPECT_EQ(error_of(R"({"camera": {"from": [0, 0, 5], "from": [1, 1, 1]}})"),
            "scene.json:1:32: camera: key \"from\" appears twice");
  EXPECT_EQ(
      error_of(scene_with(
          R"({"cone": {"base_radius": 1, "baseRadius": 2, "base": [0,0,0], "apex": [0,1,0]}})")),
      "scene.json:1:136: objects[0].cone: key \"baseRadius\" appears twice");
}

TEST(SceneJson, TypeErrorsNameTheirPath) {
  EXPECT_EQ(error_of(R"({"camera": {"width": 1.5}})"),
            "scene.json: camera.width: invalid value 1.5 for type TYPE_INT32");
  EXPECT_CONTAINS(error_of(scene_with(R"({"csg": {"op": "XOR"}})")),
                  "scene.json: objects[0].csg.op: invalid value \"XOR\"");
  EXPECT_CONTAINS(error_of(scene_with(R"({"sphere": {"radius": 1}, "box": {}})")),
                  "scene.json: objects[0]: ");
}

TEST(SceneJson, VectorsNeedExactlyThreeNumbers) {
  std::string e = error_of(R"({"camera": {"from": [0, 5], "at": [0, 0, 0, 0], "width": 8,
                                          "height": 8}})");
  EXPECT_CONTAINS(e, "scene.json: camera.from: must hold exactly 3 numbers [x, y, z], got 2");
  EXPECT_CONTAINS(e, "scene.json: camera.at: must hold exactly 3 numbers [x, y, z], got 4");
  e = error_of(R"({"camera": {"width": 8, "height": 8}})");
  EXPECT_CONTAINS(e, "scene.json: camera.from: is missing (expected 3 numbers [x, y, z])");
  e = error_of(scene_with(R"({"polygon": {"vertices": [0, 0, 0, 1, 0, 0, 1]}})",
                          R"("background": [1], "lights": [{"position": [1, 1, 1], "color": 5}])"));
  EXPECT_CONTAINS(e,
                  "scene.json: objects[0].polygon.vertices: must hold x, y, z triples; 7 "
                  "numbers is not a multiple of 3");
  EXPECT_CONTAINS(e, "scene.json: background: must hold exactly 3 numbers [x, y, z], got 1");
  EXPECT_CONTAINS(e, "scene.json: lights[0].color: must hold exactly 3 numbers [x, y, z], got 1");
}

// ---- Semantic errors, by JSON path ----

TEST(SceneJson, SphereRadius) {
  EXPECT_EQ(error_of(scene_with(R"({"sphere": {"radius": 1}}, {"sphere": {"radius": 1}},
                                   {"sphere": {"radius": 1}}, {"sphere": {"radius": -1}})")),
            "scene.json: objects[3].sphere.radius: must be positive, got -1");
}

TEST(SceneJson, NonFiniteNumbers) {
  const std::string e = error_of(scene_with(R"({"sphere": {"center": [0, "NaN", 0], "radius": 1}},
                                               {"sphere": {"radius": "Infinity"}})"));
  EXPECT_CONTAINS(e, "scene.json: objects[0].sphere.center: must be finite, got [0, nan, 0]");
  EXPECT_CONTAINS(e, "scene.json: objects[1].sphere.radius: must be positive, got inf");
}

TEST(SceneJson, MaterialRanges) {
  const std::string e = error_of(std::string("{") + kCamera + R"(, "materials": [
      {"kd": 1.5, "ks": -0.1, "t": 2, "shine": -1, "ior": 0.9, "color": [1, -1, 0],
       "absorption": [0, 0, -1]}]})");
  for (const char* want :
       {"scene.json: materials[0].kd: must be in [0, 1], got 1.5",
        "scene.json: materials[0].ks: must be in [0, 1], got -0.1",
        "scene.json: materials[0].t: must be in [0, 1], got 2",
        "scene.json: materials[0].shine: must be a finite number >= 0, got -1",
        "scene.json: materials[0].ior: must be a finite number >= 1, got 0.9",
        "scene.json: materials[0].color: must be finite and >= 0 in every channel, got [1, -1, 0]",
        "scene.json: materials[0].absorption: must be finite and >= 0"}) {
    EXPECT_CONTAINS(e, want);
  }
}

TEST(SceneJson, MaterialIndexInRange) {
  EXPECT_EQ(error_of(scene_with(R"({"sphere": {"radius": 1}, "material": 1})")),
            "scene.json: objects[0].material: index 1 out of range; the scene has 1 materials");
  EXPECT_CONTAINS(
      error_of(std::string("{") + kCamera + R"(, "objects": [{"sphere": {"radius": 1}}]})"),
      "scene.json: objects[0].material: index 0 out of range; the scene has 0 "
      "materials");
}

TEST(SceneJson, CameraProblems) {
  const std::string e = error_of(R"({"camera": {"from": [1, 1, 1], "at": [1, 1, 1], "angle": 0,
                                               "hither": -1, "width": 0, "height": 99999}})");
  for (const char* want : {"scene.json: camera.angle: must be in (0, 180) degrees, got 0",
                           "scene.json: camera.hither: must be a finite number >= 0, got -1",
                           "scene.json: camera.width: must be in [1, 16384] pixels, got 0",
                           "scene.json: camera.height: must be in [1, 16384] pixels, got 99999",
                           "scene.json: camera.at: coincides with from at [1, 1, 1]"}) {
    EXPECT_CONTAINS(e, want);
  }
  EXPECT_CONTAINS(error_of(R"({"camera": {"from": [0, 5, 0], "at": [0, 0, 0], "width": 8,
                                          "height": 8}})"),
                  "scene.json: camera.up: is parallel to the view direction");
  EXPECT_EQ(error_of("{}"),
            "scene.json: camera: missing; a scene needs a camera (NFF: a v entity; JSON: "
            "\"camera\")");
}

TEST(SceneJson, DegeneratePolygons) {
  const std::string e = error_of(scene_with(
      R"({"polygon": {"vertices": [0, 0, 0, 1, 0, 0]}},
         {"polygon": {"vertices": [0, 0, 0, 1, 0, 0, 2, 0, 0]}},
         {"polygon": {"vertices": [0, 0, 0, 1, 0, 0, 1, 1, 0, 1, 0, 0]}},
         {"polygon": {"vertices": [0, 0, 0, 1, 0, 0, 1, 1, 1, 0, 1, 0]}},
         {"patch": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "normals": [0, 0, 1]}})"));
  for (const char* want :
       {"scene.json: objects[0].polygon.vertices: must number at least 3, got 2",
        "scene.json: objects[1].polygon.vertices: are all collinear; the polygon has no area",
        "scene.json: objects[2].polygon.vertices: 1 and 3 coincide at [1, 0, 0]",
        "scene.json: objects[3].polygon.vertices: are not coplanar",
        "scene.json: objects[4].patch.normals: needs one normal per vertex: 3 vertices, 1 "
        "normals"}) {
    EXPECT_CONTAINS(e, want);
  }
}

TEST(SceneJson, DerivedShapesNameTheFieldsWritten) {
  const std::string e = error_of(scene_with(
      R"({"cylinder": {"base": [0, 0, 0], "apex": [0, 1, 0], "radius": 0}},
         {"cylinder": {"base": [0, 0, 0], "apex": [0, 0, 0], "radius": 1}},
         {"box": {"min": [0, 0, 0], "max": [1, 0, 1]}},
         {"prism": {"sides": 2, "radius": -1, "base": [0, 0, 0], "apex": [0, 0, 1]}},
         {"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0]}},
         {"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0]}},
         {"cone": {"base": [0, 0, 0], "apex": [0, 1, 0], "base_radius": -1}},
         {})"));
  for (const char* want :
       {"scene.json: objects[0].cylinder.radius: must be positive, got 0",
        "scene.json: objects[1].cylinder: base and apex coincide at [0, 0, 0]",
        "scene.json: objects[2].box: max must exceed min in every component, got min [0, 0, 0] "
        "and max [1, 0, 1]",
        "scene.json: objects[3].prism.sides: must be in [3, 1024], got 2",
        "scene.json: objects[3].prism.radius: must be positive, got -1",
        "scene.json: objects[4].polyhedron.vertices: do not span a volume",
        "scene.json: objects[5].polyhedron.vertices: the convex hull (no faces given) takes 4 to "
        "1024 vertices, got 3",
        "scene.json: objects[6].cone.base_radius: must not be negative, got -1",
        "scene.json: objects[7]: has no shape (expected one of sphere, cylinder, cone, box, prism, "
        "polyhedron, polygon, mesh, patch, csg, bezier)"}) {
    EXPECT_CONTAINS(e, want);
  }
}

TEST(SceneJson, PolyhedronFacesMustBeOutwardConvexAndClosed) {
  // The tetrahedron of ShapesBecomeTheSceneModel with one face turned inward.
  std::string e = error_of(scene_with(
      R"({"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1],
          "faces": [{"vertices": [0, 1, 2]}, {"vertices": [0, 1, 3]},
                    {"vertices": [0, 3, 2]}, {"vertices": [1, 2, 3]}]}})"));
  EXPECT_CONTAINS(e,
                  "scene.json: objects[0].polyhedron.faces[0]: vertex 3 lies outside this "
                  "face's plane");
  e = error_of(scene_with(
      R"({"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1],
          "faces": [{"vertices": [0, 2, 1]}, {"vertices": [0, 1, 3]},
                    {"vertices": [0, 3, 2]}, {"vertices": [1, 2, 9]}]}})"));
  EXPECT_CONTAINS(e,
                  "scene.json: objects[0].polyhedron.faces[3]: vertex index 9 out of range [0, 4)");
  e = error_of(scene_with(
      R"({"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1],
          "faces": [{"vertices": [0, 2, 1]}, {"vertices": [0, 1, 3]},
                    {"vertices": [0, 3, 2]}, {"vertices": [1, 2, 3]}, {"vertices": [1, 2, 3]}]}})"));
  EXPECT_CONTAINS(e, "faces[4]: edge 1 -> 2 also runs the same way in faces[3]");
  // A unit cube (vertex i at x = bit 0, y = bit 1, z = bit 2) whose top is
  // only half covered.
  e = error_of(scene_with(
      R"({"polyhedron": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0,
                                      0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1],
          "faces": [{"vertices": [0, 4, 6, 2]}, {"vertices": [1, 3, 7, 5]},
                    {"vertices": [0, 1, 5, 4]}, {"vertices": [2, 6, 7, 3]},
                    {"vertices": [0, 2, 3, 1]}, {"vertices": [4, 5, 7]}]}})"));
  EXPECT_CONTAINS(e, "borders no other face; the polyhedron must be closed");
}

TEST(SceneJson, CsgOperands) {
  const std::string solids =
      R"({"sphere": {"radius": 1}}, {"sphere": {"radius": 1}},
         {"cylinder": {"base": [0, 0, 0], "apex": [0, 1, 0], "radius": 1}},
         {"polygon": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0]}})";
  EXPECT_EQ(error_of(scene_with(solids + R"(, {"csg": {"left": 0, "right": 9}})")),
            "scene.json: objects[4].csg.right: index 9 out of range; the scene has 5 objects");
  EXPECT_EQ(error_of(scene_with(solids + R"(, {"csg": {"left": 4, "right": 0}})")),
            "scene.json: objects[4].csg.left: a CSG node cannot be its own operand");
  EXPECT_EQ(error_of(scene_with(solids + R"(, {"csg": {"left": 0, "right": 2}})")),
            "scene.json: objects[4].csg.right: objects[2] is a cone, not a solid (sphere, capped "
            "cone or cylinder, polyhedron, or another csg)");
  EXPECT_CONTAINS(error_of(scene_with(solids + R"(, {"csg": {"left": 3, "right": 0}})")),
                  "objects[4].csg.left: objects[3] is a polygon, not a solid");
  EXPECT_EQ(error_of(scene_with(solids + R"(, {"csg": {"left": 0, "right": 1}},
                                           {"csg": {"op": "INTERSECTION", "left": 1, "right": 0}})")),
            "scene.json: objects[5].csg.left: objects[1] is already an operand of objects[4]; an "
            "operand belongs to one CSG node\n"
            "scene.json: objects[5].csg.right: objects[0] is already an operand of objects[4]; an "
            "operand belongs to one CSG node");
  EXPECT_CONTAINS(error_of(scene_with(solids + R"(, {"csg": {"left": 0, "right": 0}})")),
                  "objects[4].csg.right: objects[0] is already an operand of objects[4]");
  const std::string cycle = error_of(scene_with(
      solids + R"(, {"csg": {"left": 0, "right": 5}}, {"csg": {"left": 1, "right": 4}})"));
  EXPECT_CONTAINS(cycle,
                  "scene.json: objects[4].csg: operands form a cycle: objects[4] <- "
                  "objects[5] <- objects[4]");
  Result<Scene> nested = parse(scene_with(
      solids + R"(, {"csg": {"left": 0, "right": 1}}, {"csg": {"op": "DIFFERENCE", "left": 4,
                   "right": 6}}, {"sphere": {"radius": 2}})"));
  EXPECT_TRUE(nested.ok()) << nested.status().message();
}

TEST(SceneJson, TransformProblems) {
  const std::string e = error_of(scene_with(
      R"({"sphere": {"radius": 1}, "transform": {"matrix": [1, 0, 0, 0], "translate": [1, 1, 1]}},
         {"sphere": {"radius": 1}, "transform": {"matrix": [1, 0, 0]}},
         {"sphere": {"radius": 1}, "transform": {"rotate": [{"axis": [0, 0, 0], "degrees": 5}]}},
         {"sphere": {"radius": 1}, "transform": {"scale": [1, 2]}},
         {"sphere": {"radius": 1}, "transform": {"scale": 0}},
         {"sphere": {"radius": 1},
          "transform": {"matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]}})"));
  for (const char* want :
       {"scene.json: objects[0].transform: give either matrix or translate/rotate/scale, not both",
        "scene.json: objects[1].transform.matrix: must hold 16 numbers (4 rows of 4), got 3",
        "scene.json: objects[2].transform.rotate[0].axis: must be a finite, non-zero vector",
        "scene.json: objects[3].transform.scale: must hold 1 number (uniform) or 3 [x, y, z], got "
        "2",
        "scene.json: objects[4].transform: is singular",
        "scene.json: objects[5].transform: must be affine (last matrix row [0, 0, 0, 1])"}) {
    EXPECT_CONTAINS(e, want);
  }
}

TEST(SceneJson, ReportsAllProblemsAtOnce) {
  const std::string e = error_of(scene_with(
      R"({"sphere": {"radius": -1}}, {"box": {"min": [0, 0], "max": [1, 1, 1]}},
         {"sphere": {"radius": 0}})"));
  EXPECT_EQ(e,
            "scene.json: objects[1].box.min: must hold exactly 3 numbers [x, y, z], got 2\n"
            "scene.json: objects[0].sphere.radius: must be positive, got -1\n"
            "scene.json: objects[2].sphere.radius: must be positive, got 0");
}

// ---- Files ----

TEST(SceneJson, LoadsObjMeshesRelativeToTheSceneFile) {
  TempDir dir;
  fs::create_directories(dir.path() / "meshes");
  // A quad with normals (two triangles) and a triangle without.
  dir.write("meshes/quad.obj",
            "# a unit quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
            "f 1//1 2//1 3//1 4//1\n");
  dir.write("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path scene = dir.write("scene.json", scene_with(R"({"mesh": {"obj": "meshes/quad.obj"}},
                                  {"mesh": {"obj": "flat.obj"}, "name": "flat"})"));
  Result<Scene> r = load_scene(scene.string());
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->source, scene.string());
  const Mesh& quad = std::get<Mesh>(r->objects[0].shape);
  EXPECT_EQ(quad.triangles.size(), 2u);
  EXPECT_EQ(quad.positions.size(), 4u);
  ASSERT_EQ(quad.normals.size(), 4u);
  EXPECT_EQ(quad.normals[0], Vec3(0, 0, 1));
  const Mesh& flat = std::get<Mesh>(r->objects[1].shape);
  EXPECT_EQ(flat.triangles.size(), 1u);
  EXPECT_TRUE(flat.normals.empty());
  EXPECT_EQ(r->objects[1].name, "flat");
}

TEST(SceneJson, ObjProblems) {
  TempDir dir;
  dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
  const fs::path scene = dir.write("scene.json", scene_with(R"({"mesh": {"obj": "missing.obj"}},
                                  {"mesh": {"obj": "bad.obj", "indices": [0, 1, 2]}},
                                  {"mesh": {"obj": "bad.obj"}})"));
  Result<Scene> r = load_scene_json(scene.string());
  ASSERT_FALSE(r.ok());
  const std::string& e = r.status().message();
  EXPECT_CONTAINS(e, scene.string() + ": objects[0].mesh.obj: cannot read '" +
                         (dir.path() / "missing.obj").string() + "': no such file");
  EXPECT_CONTAINS(e, scene.string() +
                         ": objects[1].mesh: give either obj or inline positions/normals/indices, "
                         "not both");
  EXPECT_CONTAINS(e, scene.string() + ": objects[2].mesh.obj:");
}

TEST(SceneJson, MissingFile) {
  Result<Scene> r = load_scene("/nonexistent/scene.json");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kNotFound);
  EXPECT_CONTAINS(r.status().message(), "/nonexistent/scene.json: cannot open");
}

TEST(Validate, ScenesBuiltInCodeAreNamedByPath) {
  Scene s;
  s.has_camera = true;
  s.materials.emplace_back();
  Object o;
  o.shape = Sphere{Vec3(0.0), -1};
  s.objects.push_back(o);
  o.shape = Polygon{{Vec3(0.0), Vec3(1, 0, 0)}};
  o.material = 4;
  s.objects.push_back(o);
  EXPECT_EQ(validate_scene(s),
            (std::vector<std::string>{
                "objects[0].sphere.radius: must be positive, got -1",
                "objects[1].polygon.vertices: must number at least 3, got 2",
                "objects[1].material: index 4 out of range; the scene has 1 materials"}));
}

// ---- The wire form ----

void expect_same(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.has_camera, b.has_camera);
  EXPECT_EQ(a.camera.from, b.camera.from);
  EXPECT_EQ(a.camera.at, b.camera.at);
  EXPECT_EQ(a.camera.up, b.camera.up);
  EXPECT_EQ(a.camera.angle, b.camera.angle);
  EXPECT_EQ(a.camera.hither, b.camera.hither);
  EXPECT_EQ(a.camera.width, b.camera.width);
  EXPECT_EQ(a.camera.height, b.camera.height);
  EXPECT_EQ(a.background, b.background);
  EXPECT_EQ(a.ambient, b.ambient);
  ASSERT_EQ(a.lights.size(), b.lights.size());
  for (size_t i = 0; i < a.lights.size(); ++i) {
    EXPECT_EQ(a.lights[i].position, b.lights[i].position);
    EXPECT_EQ(a.lights[i].emission, b.lights[i].emission);
  }
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (size_t i = 0; i < a.materials.size(); ++i) {
    const Material &m = a.materials[i], &n = b.materials[i];
    EXPECT_EQ(m.color, n.color);
    EXPECT_EQ(m.kd, n.kd);
    EXPECT_EQ(m.ks, n.ks);
    EXPECT_EQ(m.shine, n.shine);
    EXPECT_EQ(m.t, n.t);
    EXPECT_EQ(m.ior, n.ior);
    EXPECT_EQ(m.absorption, n.absorption);
  }
  ASSERT_EQ(a.objects.size(), b.objects.size());
  for (size_t i = 0; i < a.objects.size(); ++i) {
    const Object &o = a.objects[i], &p = b.objects[i];
    SCOPED_TRACE("objects[" + std::to_string(i) + "]");
    EXPECT_EQ(o.material, p.material);
    EXPECT_EQ(o.name, p.name);
    EXPECT_EQ(o.world_from_object, p.world_from_object);
    ASSERT_EQ(o.shape.index(), p.shape.index());
    std::visit(
        [&](const auto& s) {
          using T = std::decay_t<decltype(s)>;
          const T& t = std::get<T>(p.shape);
          if constexpr (std::is_same_v<T, Sphere>) {
            EXPECT_EQ(s.center, t.center);
            EXPECT_EQ(s.radius, t.radius);
          } else if constexpr (std::is_same_v<T, Cone>) {
            EXPECT_EQ(s.base, t.base);
            EXPECT_EQ(s.apex, t.apex);
            EXPECT_EQ(s.base_radius, t.base_radius);
            EXPECT_EQ(s.apex_radius, t.apex_radius);
            EXPECT_EQ(s.capped, t.capped);
          } else if constexpr (std::is_same_v<T, Polyhedron>) {
            EXPECT_EQ(s.vertices, t.vertices);
            EXPECT_EQ(s.faces, t.faces);
          } else if constexpr (std::is_same_v<T, Polygon>) {
            EXPECT_EQ(s.vertices, t.vertices);
          } else if constexpr (std::is_same_v<T, Mesh>) {
            EXPECT_EQ(s.positions, t.positions);
            EXPECT_EQ(s.normals, t.normals);
            EXPECT_EQ(s.triangles, t.triangles);
          } else if constexpr (std::is_same_v<T, Patch>) {
            EXPECT_EQ(s.vertices, t.vertices);
            EXPECT_EQ(s.normals, t.normals);
          } else if constexpr (std::is_same_v<T, BezierSurface>) {
            ASSERT_EQ(s.patches.size(), t.patches.size());
            for (size_t k = 0; k < s.patches.size(); ++k) {
              EXPECT_EQ(s.patches[k].points, t.patches[k].points);
            }
          } else {
            EXPECT_EQ(s.op, t.op);
            EXPECT_EQ(s.left, t.left);
            EXPECT_EQ(s.right, t.right);
          }
        },
        o.shape);
  }
}

TEST(SceneProto, RoundTripGivesTheSameScene) {
  TempDir dir;
  dir.write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
  const std::string json = scene_with(
      R"({"name": "ball", "sphere": {"center": [1, 2, 3], "radius": 0.7},
          "transform": {"scale": [1, 2, 1], "rotate": [{"axis": [1, 1, 0], "degrees": 33}],
                        "translate": [0.1, 0.2, 0.3]}},
         {"cone": {"base": [0, 0, 0], "base_radius": 1, "apex": [0, 1, 0], "apex_radius": 0.25,
                   "capped": true}},
         {"box": {"min": [0, 0, 0], "max": [1, 2, 3]}},
         {"polyhedron": {"vertices": [0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2, 0.1, 0.1, 0.1]}},
         {"csg": {"op": "INTERSECTION", "left": 2, "right": 3}},
         {"polygon": {"vertices": [0, 0, 0, 2, 0, 0, 1, 1, 0, 0, 2, 0]}},
         {"patch": {"vertices": [0, 0, 0, 1, 0, 0, 0, 1, 0], "normals": [0, 0, 1, 0, 0.1, 1, 0, 0, 1]}},
         {"mesh": {"obj": "quad.obj"}})",
      R"("background": [0.1, 0.2, 0.3], "ambient": 0.05,
         "lights": [{"position": [1, 2, 3]}, {"position": [3, 2, 1], "color": [0.5, 0.5, 1]}])");
  Result<Scene> first = parse_scene_json(json, "scene.json", dir.path().string());
  ASSERT_TRUE(first.ok()) << first.status().message();
  Scene original = *first;
  original.materials[0] = Material{Color(0.5, 0.25, 1), 0.6, 0.3, 12.5, 0.4, 1.33, Color(0.1)};

  const v1::Scene proto = scene_to_proto(original);
  EXPECT_TRUE(proto.objects(7).mesh().obj().empty());  // meshes go inline
  Result<Scene> back = scene_from_proto(proto, "wire", "");
  ASSERT_TRUE(back.ok()) << back.status().message();
  expect_same(original, *back);
  EXPECT_EQ(back->source, "wire");
  EXPECT_TRUE(google::protobuf::util::MessageDifferencer::Equals(proto, scene_to_proto(*back)));
}

TEST(SceneProto, NffScenesAndBezierSurfacesRoundTrip) {
  for (const std::string& path : {std::string(LOCUS_SHARED_DIR) + "/spd/s1/rings.nff",
                                  std::string(LOCUS_SOURCE_DIR) + "/scenes/teapot.json"}) {
    SCOPED_TRACE(path);
    Result<Scene> scene = load_scene(path);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    Result<Scene> back = scene_from_proto(scene_to_proto(*scene), "wire");
    ASSERT_TRUE(back.ok()) << back.status().message();
    expect_same(*scene, *back);
  }
}

TEST(SceneProto, FromProtoValidates) {
  v1::Scene p = scene_to_proto(Scene{});
  Result<Scene> r = scene_from_proto(p, "job 7");
  ASSERT_FALSE(r.ok());
  EXPECT_CONTAINS(r.status().message(), "job 7: camera: missing");
}

}  // namespace
}  // namespace locus

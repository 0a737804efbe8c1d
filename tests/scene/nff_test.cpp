// The NFF loader (common/scene/nff.cpp): every SPD file loads, and every kind of
// bad input is rejected with the file, the line and what is wrong.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/scene/scene_io.h"

namespace locus {
namespace {

namespace fs = std::filesystem;

const fs::path kSpd = fs::path(LOCUS_SHARED_DIR) / "spd";

// A valid viewpoint and light: lines 1 to 8 of every test scene, so an
// entity appended after it starts on line 9.
constexpr const char* kHeader =
    "v\n"
    "from 0 0 5\n"
    "at 0 0 0\n"
    "up 0 1 0\n"
    "angle 45\n"
    "hither 0.01\n"
    "resolution 64 48\n"
    "l 1 2 3\n";

// Lines of the file whose first token is one of `keywords`, like grep -c.
int count_entities(const fs::path& file, const std::vector<std::string>& keywords) {
  std::ifstream in(file);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string first;
    words >> first;
    for (const std::string& k : keywords) n += first == k;
  }
  return n;
}

std::string error_of(const std::string& text, const std::string& name = "t.nff") {
  Result<Scene> r = parse_nff(text, name);
  EXPECT_FALSE(r.ok()) << "accepted:\n" << text;
  return r.ok() ? "" : r.status().message();
}

TEST(Nff, EverySpdFileLoads) {
  int files = 0;
  for (const char* set : {"def", "s1", "s2"}) {
    for (const auto& entry : fs::directory_iterator(kSpd / set)) {
      if (entry.path().extension() != ".nff") continue;
      ++files;
      const std::string path = entry.path().string();
      const auto start = std::chrono::steady_clock::now();
      Result<Scene> r = load_nff(path);
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      ASSERT_TRUE(r.ok()) << r.status().message();
      const Scene& s = *r;
      EXPECT_TRUE(s.has_camera) << path;
      EXPECT_FALSE(s.lights.empty()) << path;
      EXPECT_FALSE(s.objects.empty()) << path;
      EXPECT_EQ(s.source, path);
      for (const Object& o : s.objects) {
        ASSERT_EQ(o.origin.rfind(path + ":", 0), 0u) << o.origin;
        ASSERT_GE(o.material, 0);
        ASSERT_LT(o.material, static_cast<int>(s.materials.size()));
      }
      EXPECT_TRUE(validate_scene(s).empty()) << path;
      RecordProperty(std::string(set) + "/" + entry.path().filename().string() + "_seconds",
                     std::to_string(seconds));
    }
  }
  EXPECT_EQ(files, 33);
}

TEST(Nff, ObjectCountsMatchTheFile) {
  struct Case {
    const char* file;
    std::vector<std::string> objects;
  };
  for (const Case& c : {Case{"def/balls.nff", {"s", "p"}}, Case{"def/gears.nff", {"p"}},
                        Case{"def/lattice.nff", {"c", "s"}}, Case{"def/teapot.nff", {"p", "pp"}},
                        Case{"s2/rings.nff", {"c", "s", "p"}}}) {
    Result<Scene> r = load_nff((kSpd / c.file).string());
    ASSERT_TRUE(r.ok()) << r.status().message();
    EXPECT_EQ(static_cast<int>(r->objects.size()), count_entities(kSpd / c.file, c.objects))
        << c.file;
    EXPECT_EQ(static_cast<int>(r->materials.size()), count_entities(kSpd / c.file, {"f"}))
        << c.file;
    EXPECT_EQ(static_cast<int>(r->lights.size()), count_entities(kSpd / c.file, {"l"})) << c.file;
  }
  // Known values: grep -c '^s ' def/balls.nff is 7381, plus its floor.
  Result<Scene> balls = load_nff((kSpd / "def/balls.nff").string());
  ASSERT_TRUE(balls.ok());
  EXPECT_EQ(balls->objects.size(), 7382u);
  Result<Scene> gears = load_nff((kSpd / "def/gears.nff").string());
  ASSERT_TRUE(gears.ok());
  EXPECT_EQ(gears->objects.size(), 9345u);
}

TEST(Nff, DropsTheZeroAreaPatchesOfSmallTeapot) {
  // s1/teapot.nff has 4 patches collapsed to a line at the spout's tip.
  const fs::path file = kSpd / "s1/teapot.nff";
  Result<Scene> r = load_nff(file.string());
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(static_cast<int>(r->objects.size()), count_entities(file, {"p", "pp"}) - 4);
}

TEST(Nff, ReadsEveryEntity) {
  const std::string text =
      "# a comment line\n"
      "b 0.1 0.2 0.3\n"
      "v\n"
      "from 1 2 3\n"
      "at 0 0 0\n"
      "up 0 0 1\n"
      "angle 30\n"
      "hither 0.5\n"
      "resolution 320 200\n"
      "\n"
      "l 1 1 1\n"
      "l 2 2 2 0.5 0.25 1   # a coloured light\n"
      "s 0 0 0 1\n"  // before any f: the default material
      "f 1 0 0 0.7 0.2 10 0 0\n"
      "c 0 0 0 1 0 0 2 0.5\n"
      "c\n"
      "0 0 0 1\n"
      "0 0 2 1\n"
      "f 0 1 0 0.5 0.5 3 0.5 1.5\n"
      "p 3\n"
      "0 0 0\n"
      "1 0 0\n"
      "0 1 0\n"
      "pp 3\n"
      "0 0 0 0 0 1\n"
      "1 0 0 0 0 1\n"
      "0 1 0 0 0.1 1\n";
  Result<Scene> r = parse_nff(text, "all.nff");
  ASSERT_TRUE(r.ok()) << r.status().message();
  const Scene& s = *r;
  EXPECT_EQ(s.background, Color(0.1, 0.2, 0.3));
  ASSERT_TRUE(s.has_camera);
  EXPECT_EQ(s.camera.from, Vec3(1, 2, 3));
  EXPECT_EQ(s.camera.up, Vec3(0, 0, 1));
  EXPECT_EQ(s.camera.angle, 30);
  EXPECT_EQ(s.camera.hither, 0.5);
  EXPECT_EQ(s.camera.width, 320);
  EXPECT_EQ(s.camera.height, 200);
  ASSERT_EQ(s.lights.size(), 2u);
  EXPECT_FALSE(s.lights[0].emission);
  ASSERT_TRUE(s.lights[1].emission);
  EXPECT_EQ(*s.lights[1].emission, Color(0.5, 0.25, 1));

  ASSERT_EQ(s.materials.size(), 3u);  // the default, then one per f
  EXPECT_EQ(s.materials[1].color, Color(1, 0, 0));
  EXPECT_EQ(s.materials[1].kd, 0.7);
  EXPECT_EQ(s.materials[1].ks, 0.2);
  EXPECT_EQ(s.materials[1].shine, 10);
  EXPECT_EQ(s.materials[1].ior, 1.0);  // SPD's ior 0 of an opaque material
  EXPECT_EQ(s.materials[2].t, 0.5);
  EXPECT_EQ(s.materials[2].ior, 1.5);

  ASSERT_EQ(s.objects.size(), 5u);
  EXPECT_EQ(s.objects[0].material, 0);
  EXPECT_EQ(s.objects[0].origin, "all.nff:13");
  const auto& sphere = std::get<Sphere>(s.objects[0].shape);
  EXPECT_EQ(sphere.radius, 1.0);

  const auto& cone = std::get<Cone>(s.objects[1].shape);
  EXPECT_EQ(s.objects[1].material, 1);
  EXPECT_EQ(cone.base_radius, 1.0);
  EXPECT_EQ(cone.apex, Vec3(0, 0, 2));
  EXPECT_EQ(cone.apex_radius, 0.5);
  EXPECT_FALSE(cone.capped);
  EXPECT_EQ(s.objects[2].origin, "all.nff:16");  // a c spread over three lines

  EXPECT_EQ(s.objects[3].material, 2);
  EXPECT_EQ(std::get<Polygon>(s.objects[3].shape).vertices.size(), 3u);
  const auto& patch = std::get<Patch>(s.objects[4].shape);
  EXPECT_EQ(patch.normals[2], Vec3(0, 0.1, 1));
  EXPECT_EQ(s.objects[4].origin, "all.nff:24");
}

TEST(Nff, ToleratesCommentsAnywhereAndCrlf) {
  const std::string text =
      "v\r\nfrom 0 0 5 # eye\r\nat 0 0 0\r\nup 0 1 0\r\nangle 45\r\n"
      "hither 1\r\nresolution 8 8\r\n\r\n   \t\r\n"
      "s 0 0 0 1#no space before the comment\r\n";
  Result<Scene> r = parse_nff(text, "crlf.nff");
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->objects.size(), 1u);
  EXPECT_EQ(r->objects[0].origin, "crlf.nff:10");
}

TEST(Nff, HitherMayBeOmittedAndFieldsComeInAnyOrder) {
  Result<Scene> r = parse_nff(
      "v\nresolution 10 20\nangle 60\nup 0 1 0\nat 0 0 0\nfrom 0 0 3\ns 0 0 0 1\n", "old.nff");
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->camera.width, 10);
  EXPECT_EQ(r->camera.height, 20);
  EXPECT_EQ(r->camera.hither, Camera{}.hither);
}

TEST(Nff, LightIntensitiesFollowSpd) {
  Result<Scene> r = load_nff((kSpd / "def/balls.nff").string());
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->lights.size(), 3u);
  const double e = std::sqrt(3.0) / 6.0;  // sqrt(L) / (2L)
  EXPECT_DOUBLE_EQ(light_emission(*r, 0).x, e);
  EXPECT_DOUBLE_EQ(light_emission(*r, 2).z, e);
  EXPECT_DOUBLE_EQ(ambient_intensity(*r), e);

  Scene s = *r;
  s.lights[1].emission = Color(1, 0.5, 0);
  EXPECT_EQ(light_emission(s, 1), Color(1, 0.5, 0));
  EXPECT_DOUBLE_EQ(light_emission(s, 0).y, e);
  EXPECT_DOUBLE_EQ(ambient_intensity(s), e);  // unchanged by coloured lights
  s.ambient = 0.25;
  EXPECT_EQ(ambient_intensity(s), 0.25);
  s.ambient.reset();
  s.lights.clear();
  EXPECT_EQ(ambient_intensity(s), 0.0);
}

// ---- Rejected input: file, line, what is wrong, the expected form ----

TEST(Nff, NegativeSphereRadius) {
  EXPECT_EQ(error_of(std::string(kHeader) + "s 0 0 0 -0.5\n", "balls.nff"),
            "balls.nff:9: sphere radius must be positive, got -0.5 (expected: s x y z radius)");
}

TEST(Nff, NegativeConeRadii) {
  const std::string e = error_of(std::string(kHeader) + "c 0 0 0 -1 0 0 1 -1\n");
  EXPECT_NE(e.find("t.nff:9: cone base radius must not be negative, got -1"), std::string::npos)
      << e;
  EXPECT_NE(e.find("t.nff:9: cone apex radius must not be negative, got -1"), std::string::npos)
      << e;
  EXPECT_NE(e.find("(expected: c base.x"), std::string::npos) << e;
}

TEST(Nff, CoincidentConeEnds) {
  const std::string e = error_of(std::string(kHeader) + "c 1 1 1 1 1 1 1 0.5\n");
  EXPECT_NE(e.find("t.nff:9: cone: base and apex coincide"), std::string::npos) << e;
}

TEST(Nff, TruncatedFile) {
  EXPECT_EQ(error_of(std::string(kHeader) + "s 0 0"),
            "t.nff:9: sphere is cut short: the file ends before its centre z (expected: s x y z "
            "radius)");
  const std::string e = error_of(std::string(kHeader) + "p 3\n0 0 0\n1 0 0\n");
  EXPECT_NE(e.find("t.nff:9: polygon is cut short: the file ends before its vertex 2 x"),
            std::string::npos)
      << e;
  EXPECT_NE(error_of("v\nfrom 0 0 1\nat 0 0").find("t.nff:1: viewpoint is cut short"),
            std::string::npos);
}

TEST(Nff, NonNumericToken) {
  EXPECT_EQ(error_of(std::string(kHeader) + "s 0 0 zero 1\n"),
            "t.nff:9: sphere centre z: expected a number, got 'zero' (expected: s x y z radius)");
  const std::string e = error_of(std::string(kHeader) + "f 1 1 1 0.5 0.5 3 0 1x\n");
  EXPECT_NE(e.find("t.nff:9: material ior: expected a number, got '1x'"), std::string::npos) << e;
  // The token's own line, in a multi-line entity.
  const std::string p = error_of(std::string(kHeader) + "p 3\n0 0 0\n1 0 0\n0 one 0\n");
  EXPECT_NE(p.find("t.nff:12: polygon vertex 2 y: expected a number, got 'one'"), std::string::npos)
      << p;
}

TEST(Nff, NonFiniteNumbers) {
  for (const char* bad : {"nan", "inf", "-inf", "NaN", "infinity"}) {
    const std::string e = error_of(std::string(kHeader) + "s 0 0 0 " + bad + "\n");
    EXPECT_NE(e.find(std::string("t.nff:9: sphere radius: must be a finite number, got '") + bad),
              std::string::npos)
        << e;
  }
  const std::string e = error_of(std::string(kHeader) + "s 1e999 0 0 1\n");
  EXPECT_NE(e.find("t.nff:9: sphere centre x: '1e999' is out of the range of double"),
            std::string::npos)
      << e;
}

TEST(Nff, UnknownEntity) {
  const std::string e = error_of(std::string(kHeader) + "sphere 0 0 0 1\n");
  EXPECT_NE(e.find("t.nff:9: unknown entity 'sphere' (expected one of v, b, l, f, c, s, p, pp"),
            std::string::npos)
      << e;
  EXPECT_NE(error_of("\x01\x02garbage").find("t.nff:1: unknown entity '\\x01\\x02garbage'"),
            std::string::npos);
}

TEST(Nff, WrongVertexCounts) {
  // Fewer vertices than the count: the next entity keyword is not a number.
  std::string e = error_of(std::string(kHeader) + "p 4\n0 0 0\n1 0 0\n1 1 0\ns 0 0 0 1\n");
  EXPECT_NE(e.find("t.nff:13: polygon vertex 3 x: expected a number, got 's' (expected: p count"),
            std::string::npos)
      << e;
  // More vertices than the count.
  e = error_of(std::string(kHeader) + "p 3\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n");
  EXPECT_NE(e.find("t.nff:13: unexpected number '0' where an entity keyword was expected"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("the entity before it (line 9) has too many values"), std::string::npos) << e;
  e = error_of(std::string(kHeader) + "p 2\n0 0 0\n1 0 0\n");
  EXPECT_NE(e.find("t.nff:9: polygon needs at least 3 vertices, got a count of 2"),
            std::string::npos)
      << e;
  e = error_of(std::string(kHeader) + "pp 3.5\n");
  EXPECT_NE(e.find("t.nff:9: patch vertex count: expected a whole number, got '3.5'"),
            std::string::npos)
      << e;
  e = error_of(std::string(kHeader) + "p -3\n");
  EXPECT_NE(e.find("needs at least 3 vertices, got a count of -3"), std::string::npos) << e;
}

TEST(Nff, HugeVertexCountOnATruncatedFileFailsCleanly) {
  const std::string e = error_of(std::string(kHeader) + "p 999999999999\n0 0 0\n");
  EXPECT_NE(e.find("t.nff:9: polygon is cut short"), std::string::npos) << e;
}

TEST(Nff, DegeneratePolygons) {
  std::string e = error_of(std::string(kHeader) + "p 4\n0 0 0\n1 0 0\n1 0 0\n0 1 0\n");
  EXPECT_NE(e.find("t.nff:9: polygon vertices 1 and 2 coincide at [1, 0, 0]"), std::string::npos)
      << e;
  e = error_of(std::string(kHeader) + "p 4\n0 0 0\n1 0 0\n1 1 0.5\n0 1 0\n");
  EXPECT_NE(e.find("t.nff:9: polygon vertices are not coplanar"), std::string::npos) << e;
  e = error_of(std::string(kHeader) + "pp 3\n0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n");
  EXPECT_NE(e.find("t.nff:9: patch normals[1] must not be zero"), std::string::npos) << e;
}

TEST(Nff, ZeroAreaPolygonsAreDropped) {
  Result<Scene> r =
      parse_nff(std::string(kHeader) + "p 3\n0 0 0\n1 0 0\n2 0 0\ns 0 0 0 1\n", "line.nff");
  ASSERT_TRUE(r.ok()) << r.status().message();
  ASSERT_EQ(r->objects.size(), 1u);
  EXPECT_EQ(r->objects[0].origin, "line.nff:13");
}

TEST(Nff, MaterialOutOfRange) {
  std::string e = error_of(std::string(kHeader) + "f 1 1 1 1.5 0 0 0 1\n");
  EXPECT_NE(e.find("t.nff:9: material kd must be in [0, 1], got 1.5 (expected: f r g b Kd Ks "
                   "Shine T index_of_refraction)"),
            std::string::npos)
      << e;
  e = error_of(std::string(kHeader) + "f 1 1 1 0.5 0 0 0.5 0.8\n");
  EXPECT_NE(e.find("t.nff:9: material ior must be a finite number >= 1, got 0.8"),
            std::string::npos)
      << e;
  e = error_of(std::string(kHeader) + "f 1 -1 1 0.5 0 -2 0 1\n");
  EXPECT_NE(e.find("material color must be finite and >= 0"), std::string::npos) << e;
  EXPECT_NE(e.find("material shine must be a finite number >= 0, got -2"), std::string::npos) << e;
}

TEST(Nff, ViewpointProblems) {
  const std::string view = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\n";
  std::string e = error_of(view + "resolution 0 64\n");
  EXPECT_NE(e.find("t.nff:1: viewpoint width must be in [1, 16384] pixels, got 0"),
            std::string::npos)
      << e;
  e = error_of(view + "resolution 64 20000\n");
  EXPECT_NE(e.find("viewpoint height must be in [1, 16384] pixels, got 20000"), std::string::npos)
      << e;
  e = error_of("v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 180\nresolution 8 8\n");
  EXPECT_NE(e.find("t.nff:1: viewpoint angle must be in (0, 180) degrees, got 180"),
            std::string::npos)
      << e;
  e = error_of("v\nfrom 0 0 5\nat 0 0 0\nup 0 0 -2\nangle 45\nresolution 8 8\n");
  EXPECT_NE(e.find("t.nff:1: viewpoint up is parallel to the view direction"), std::string::npos)
      << e;
  e = error_of("v\nfrom 1 2 3\nat 1 2 3\nup 0 1 0\nangle 45\nresolution 8 8\n");
  EXPECT_NE(e.find("t.nff:1: viewpoint at coincides with from"), std::string::npos) << e;
  e = error_of("v\nfrom 1 2 3\nat 0 0 0\nup 0 1 0\nresolution 8 8\ns 0 0 0 1\n");
  EXPECT_NE(e.find("t.nff:1: viewpoint lacks its angle line"), std::string::npos) << e;
  e = error_of("v\nfrom 1 2 3\nfrom 1 2 3\n");
  EXPECT_NE(e.find("t.nff:3: viewpoint gives 'from' twice"), std::string::npos) << e;
  e = error_of(std::string(kHeader) + "v\nfrom 0 0 1\n");
  EXPECT_NE(e.find("t.nff:9: viewpoint is given twice (first at line 1)"), std::string::npos) << e;
  e = error_of(view + "resolution 64.5 64\n");
  EXPECT_NE(e.find("resolution width: expected a whole number, got '64.5'"), std::string::npos)
      << e;
}

TEST(Nff, NoViewpoint) {
  EXPECT_EQ(error_of("l 1 1 1\ns 0 0 0 1\n"),
            "t.nff: no viewpoint (expected: a v entity: v, then from x y z, at x y z, up x y z, "
            "angle degrees, hither distance, resolution width height)");
}

TEST(Nff, ReportsEveryProblemOneLineEach) {
  const std::string e = error_of(std::string(kHeader) +
                                 "s 0 0 0 -1\n"
                                 "f 1 1 1 2 0 0 0 1\n"
                                 "s 0 0 0 0\n");
  EXPECT_EQ(e,
            "t.nff:9: sphere radius must be positive, got -1 (expected: s x y z radius)\n"
            "t.nff:10: material kd must be in [0, 1], got 2 (expected: f r g b Kd Ks Shine T "
            "index_of_refraction)\n"
            "t.nff:11: sphere radius must be positive, got 0 (expected: s x y z radius)");
}

TEST(Nff, ManyProblemsAreCapped) {
  std::string text = kHeader;
  for (int i = 0; i < 500; ++i) text += "s 0 0 0 -1\n";
  const std::string e = error_of(text);
  EXPECT_NE(e.find("... and 400 more problems"), std::string::npos);
}

TEST(Nff, MissingFileAndUnknownExtension) {
  Result<Scene> r = load_nff("/nonexistent/dir/scene.nff");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kNotFound);
  EXPECT_NE(r.status().message().find("/nonexistent/dir/scene.nff: cannot open"),
            std::string::npos);
  r = load_scene("/nonexistent/scene.NFF");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kNotFound);
  r = load_scene("scene.obj");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(),
            "scene.obj: unknown scene format '.obj' (expected a .nff file or a .json scene, "
            "docs/scene-format.md)");
  r = load_scene((kSpd / "s1/jacks.nff").string());
  EXPECT_TRUE(r.ok());
}

}  // namespace
}  // namespace locus

namespace locus {
namespace {

// `locus validate` lists every problem: those found before a syntax error
// that stops the parse are reported with it.
TEST(Nff, SyntaxErrorStillReportsEarlierProblems) {
  const std::string text = std::string(kHeader) +
                           "f 1 0 0 1 0 0 0 1\n"
                           "s 0 0 0 -1\n"
                           "s 0 0 zero 1\n";
  const std::string msg = error_of(text, "both.nff");
  EXPECT_NE(msg.find("both.nff:10: sphere radius must be positive"), std::string::npos) << msg;
  EXPECT_NE(msg.find("both.nff:11:"), std::string::npos) << msg;
}

}  // namespace
}  // namespace locus

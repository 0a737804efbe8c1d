// NFF reader (../shared/spd/NFF.TXT): v, b, l, f, c, s, p, pp and comments.
// Interpretation notes are in docs/scene-format.md.
//
// The text is read as a stream of whitespace-separated tokens, so an entity
// may span lines (SPD puts "c" on one line, the spec on three); only the
// optional colour of "l" must stay on the light's line. Syntax errors stop
// the parse; semantic problems (a negative radius, Kd > 1) are collected with
// their line and the parse goes on, so one run reports all of them.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <climits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

#include "common/base/labels.h"
#include "common/scene/scene_io.h"
#include "common/scene/validate.h"

namespace locus {
namespace {

struct Token {
  std::string_view text;
  int line = 0;
};

class Lexer {
 public:
  explicit Lexer(std::string_view text) : text_(text) {}

  std::optional<Token> next() {
    skip_space();
    if (pos_ >= text_.size()) return std::nullopt;
    const size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_]) && text_[pos_] != '#') ++pos_;
    return Token{text_.substr(start, pos_ - start), line_};
  }

  std::optional<Token> peek() {
    const size_t pos = pos_;
    const int line = line_;
    std::optional<Token> t = next();
    pos_ = pos;
    line_ = line;
    return t;
  }

  int line() const { return line_; }

 private:
  static bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }

  // Whitespace and comments: "#" starts a comment anywhere on a line.
  void skip_space() {
    while (pos_ < text_.size()) {
      const char c = text_[pos_];
      if (c == '\n') {
        ++line_;
        ++pos_;
      } else if (is_space(c)) {
        ++pos_;
      } else if (c == '#') {
        while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
      } else {
        break;
      }
    }
  }

  std::string_view text_;
  size_t pos_ = 0;
  int line_ = 1;
};

std::optional<double> to_double(std::string_view s) {
  double x = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return x;
}

// A quoted token for messages, cut short: fuzzed or binary input can hold
// tokens of any length and any byte.
std::string quote(std::string_view s) {
  std::string out = "'";
  for (char c : s.substr(0, 40)) {
    out += (c >= 0x20 && c < 0x7f) ? std::string(1, c) : fmt::format("\\x{:02x}", c & 0xff);
  }
  return out + (s.size() > 40 ? "...'" : "'");
}

// The keyword that starts each entity: what the parser looks for and what
// its messages list.
enum class Keyword { kViewpoint, kBackground, kLight, kFill, kCone, kSphere, kPolygon, kPatch };
constexpr Labels<Keyword, 8> kKeywords = {{{Keyword::kViewpoint, "v"},
                                           {Keyword::kBackground, "b"},
                                           {Keyword::kLight, "l"},
                                           {Keyword::kFill, "f"},
                                           {Keyword::kCone, "c"},
                                           {Keyword::kSphere, "s"},
                                           {Keyword::kPolygon, "p"},
                                           {Keyword::kPatch, "pp"}}};

struct Entity {
  Keyword keyword;
  const char* name;  // in messages: "sphere radius must be positive"
  const char* args;  // what follows the keyword in its form (form())
};

constexpr Entity kViewpoint{Keyword::kViewpoint, "viewpoint",
                            ", then from x y z, at x y z, up x y z, angle degrees, hither "
                            "distance, resolution width height"};
constexpr Entity kBackground{Keyword::kBackground, "background", " r g b"};
constexpr Entity kLight{Keyword::kLight, "light", " x y z [r g b], the colour on the same line"};
constexpr Entity kFill{Keyword::kFill, "material", " r g b Kd Ks Shine T index_of_refraction"};
constexpr Entity kCone{Keyword::kCone, "cone",
                       " base.x base.y base.z base_radius apex.x apex.y apex.z apex_radius"};
constexpr Entity kSphere{Keyword::kSphere, "sphere", " x y z radius"};
constexpr Entity kPolygon{Keyword::kPolygon, "polygon", " count, then count vertices x y z"};
constexpr Entity kPatch{Keyword::kPatch, "patch", " count, then count vertices x y z nx ny nz"};

std::string_view keyword(const Entity& e) { return label_name(kKeywords, e.keyword); }

// In messages: "(expected: s x y z radius)".
std::string form(const Entity& e) { return std::string(keyword(e)) + e.args; }

// "v, b, l, f, c, s, p, pp, or # for a comment".
std::string entity_choices() {
  std::string out;
  for (const auto& k : kKeywords) out += std::string(k.name) + ", ";
  return out + "or # for a comment";
}

// The lines of a viewpoint, each starting with its keyword (hither may be
// absent, as in NFF before 2.7).
enum class ViewField { kFrom, kAt, kUp, kAngle, kHither, kResolution };
constexpr Labels<ViewField, 6> kViewFields = {{{ViewField::kFrom, "from"},
                                               {ViewField::kAt, "at"},
                                               {ViewField::kUp, "up"},
                                               {ViewField::kAngle, "angle"},
                                               {ViewField::kHither, "hither"},
                                               {ViewField::kResolution, "resolution"}}};

class NffParser {
 public:
  NffParser(std::string_view text, std::string name) : lex_(text), name_(std::move(name)) {
    scene_.source = name_;
  }

  Result<Scene> parse() {
    while (std::optional<Token> t = lex_.next()) {
      line_ = t->line;
      if (!entity(*t)) {
        // The parse stops here; problems found before it are reported too.
        problems_.push_back(error_);
        return problems_status(problems_);
      }
    }
    if (!scene_.has_camera) {
      problems_.push_back(fmt::format("{}: no viewpoint (expected: a {} entity: {})", name_,
                                      keyword(kViewpoint), form(kViewpoint)));
    }
    if (!problems_.empty()) return problems_status(problems_);
    if (dropped_ > 0) {
      // SPD's teapot at low sizes has patches collapsed to a line; they have
      // no surface to render, so they are dropped rather than rejected.
      spdlog::warn("{}:{}: dropped {} zero-area polygon(s) or patch(es) (this is the first)", name_,
                   first_dropped_line_, dropped_);
    }
    const std::vector<std::string> problems = validate_scene(scene_);
    if (!problems.empty()) return problems_status(problems);
    return std::move(scene_);
  }

 private:
  bool entity(const Token& t) {
    const std::string_view k = t.text;
    if (const std::optional<Keyword> kind = label_value(kKeywords, k)) {
      switch (*kind) {
        case Keyword::kViewpoint:
          return viewpoint();
        case Keyword::kBackground:
          return background();
        case Keyword::kLight:
          return light();
        case Keyword::kFill:
          return fill();
        case Keyword::kCone:
          return cone();
        case Keyword::kSphere:
          return sphere();
        case Keyword::kPolygon:
          return polygon(false);
        case Keyword::kPatch:
          return polygon(true);
      }
    }
    if (to_double(k)) {
      if (entity_line_ == 0) {
        return fail(
            fmt::format("unexpected number {} at the start of the file (expected one of "
                        "{})",
                        quote(k), entity_choices()));
      }
      return fail(
          fmt::format("unexpected number {} where an entity keyword was expected ({}); "
                      "the entity before it (line {}) has too many values",
                      quote(k), entity_choices(), entity_line_));
    }
    return fail(fmt::format("unknown entity {} (expected one of {})", quote(k), entity_choices()));
  }

  // ---- Errors ----

  // A syntax error: the parse stops.
  bool fail(const std::string& what) {
    error_ = fmt::format("{}:{}: {}", name_, line_, what);
    return false;
  }
  bool fail(const Entity& e, const std::string& what) {
    return fail(fmt::format("{} {} (expected: {})", e.name, what, form(e)));
  }

  // Semantic problems of a parsed entity: collected, the parse goes on.
  void report(const Entity& e, const Problems& problems) {
    for (const Problem& p : problems) {
      std::string field = p.field;
      std::replace(field.begin(), field.end(), '_', ' ');
      problems_.push_back(fmt::format("{}:{}: {}{}{} (expected: {})", name_, entity_line_, e.name,
                                      field.empty() ? ": " : " " + field + " ", p.what, form(e)));
    }
  }

  // ---- Values ----

  // `what` names the value in a problem; `axis` (x, y, z, r, g, b), if
  // given, is its component. The name is written only for a problem.
  std::optional<double> number(const Entity& e, std::string_view what_base, char axis = 0) {
    auto what = [&] {
      return axis ? fmt::format("{} {}", what_base, axis) : std::string(what_base);
    };
    const std::optional<Token> t = lex_.next();
    if (!t) {
      line_ = entity_line_;
      fail(e, fmt::format("is cut short: the file ends before its {}", what()));
      return std::nullopt;
    }
    line_ = t->line;
    double x = 0.0;
    const char* end = t->text.data() + t->text.size();
    const auto [stop, ec] = std::from_chars(t->text.data(), end, x);
    if (ec == std::errc::result_out_of_range && stop == end) {
      fail(e, fmt::format("{}: {} is out of the range of double", what(), quote(t->text)));
      return std::nullopt;
    }
    if (ec != std::errc() || stop != end) {
      fail(e, fmt::format("{}: expected a number, got {}", what(), quote(t->text)));
      return std::nullopt;
    }
    if (!is_finite(x)) {
      fail(e, fmt::format("{}: must be a finite number, got {}", what(), quote(t->text)));
      return std::nullopt;
    }
    return x;
  }

  std::optional<Vec3> vec3(const Entity& e, std::string_view what) {
    Vec3 v;
    for (int k = 0; k < 3; ++k) {
      const std::optional<double> x = number(e, what, "xyz"[k]);
      if (!x) return std::nullopt;
      v[k] = *x;
    }
    return v;
  }

  std::optional<Color> color(const Entity& e, std::string_view what) {
    Color c;
    for (int k = 0; k < 3; ++k) {
      const std::optional<double> x = number(e, what, "rgb"[k]);
      if (!x) return std::nullopt;
      c[k] = *x;
    }
    return c;
  }

  // A whole number: vertex counts and the resolution.
  std::optional<long long> integer(const Entity& e, std::string_view what) {
    const std::optional<Token> t = lex_.next();
    if (!t) {
      line_ = entity_line_;
      fail(e, fmt::format("is cut short: the file ends before its {}", what));
      return std::nullopt;
    }
    line_ = t->line;
    long long n = 0;
    const auto [end, ec] = std::from_chars(t->text.data(), t->text.data() + t->text.size(), n);
    if (ec != std::errc() || end != t->text.data() + t->text.size()) {
      fail(e, fmt::format("{}: expected a whole number, got {}", what, quote(t->text)));
      return std::nullopt;
    }
    return n;
  }

  void begin() { entity_line_ = line_; }

  int material() {
    // Objects before the first "f" get a default material (white, Kd 1).
    if (current_material_ < 0) {
      current_material_ = static_cast<int>(scene_.materials.size());
      scene_.materials.emplace_back();
    }
    return current_material_;
  }

  void add_object(Shape shape) {
    Object o;
    o.shape = std::move(shape);
    o.material = material();
    // "file:line", made by hand: one a polygon of a 262,144-polygon file
    // (SPD tetra level 9) cost its load 27 ms through fmt::format.
    char line[16];
    const auto [end, ec] = std::to_chars(line, line + sizeof line, entity_line_);
    o.origin.reserve(name_.size() + 1 + (end - line));
    o.origin.append(name_).append(1, ':').append(line, end);
    scene_.objects.push_back(std::move(o));
  }

  // ---- Entities ----

  bool viewpoint() {
    begin();
    if (scene_.has_camera) {
      return fail(kViewpoint, fmt::format("is given twice (first at line {})", camera_line_));
    }
    Camera c;
    // Fields in any order, each once.
    bool seen[kViewFields.size()] = {};
    while (std::optional<Token> t = lex_.peek()) {
      const std::optional<ViewField> field = label_value(kViewFields, t->text);
      if (!field) break;
      lex_.next();
      line_ = t->line;
      bool& given = seen[static_cast<size_t>(*field)];
      if (given) return fail(kViewpoint, fmt::format("gives {} twice", quote(t->text)));
      given = true;
      if (!view_field(*field, c)) return false;
    }
    for (const auto& field : kViewFields) {
      if (!seen[static_cast<size_t>(field.value)] && field.value != ViewField::kHither) {
        line_ = entity_line_;
        return fail(kViewpoint, fmt::format("lacks its {} line", field.name));
      }
    }
    scene_.camera = c;
    scene_.has_camera = true;
    camera_line_ = entity_line_;
    report(kViewpoint, check_camera(c));
    return true;
  }

  // The values after a viewpoint line's keyword.
  bool view_field(ViewField field, Camera& c) {
    const std::string name(label_name(kViewFields, field));
    std::optional<Vec3> v;
    std::optional<double> x;
    std::optional<long long> w, h;
    switch (field) {
      case ViewField::kFrom:
        if (!(v = vec3(kViewpoint, name))) return false;
        c.from = *v;
        break;
      case ViewField::kAt:
        if (!(v = vec3(kViewpoint, name))) return false;
        c.at = *v;
        break;
      case ViewField::kUp:
        if (!(v = vec3(kViewpoint, name))) return false;
        c.up = *v;
        break;
      case ViewField::kAngle:
        if (!(x = number(kViewpoint, name))) return false;
        c.angle = *x;
        break;
      case ViewField::kHither:
        if (!(x = number(kViewpoint, name))) return false;
        c.hither = *x;
        break;
      case ViewField::kResolution:
        if (!(w = integer(kViewpoint, name + " width"))) return false;
        if (!(h = integer(kViewpoint, name + " height"))) return false;
        // Clamped into int; check_camera rejects anything that far out.
        c.width = static_cast<int>(std::clamp<long long>(*w, INT_MIN, INT_MAX));
        c.height = static_cast<int>(std::clamp<long long>(*h, INT_MIN, INT_MAX));
        break;
    }
    return true;
  }

  bool background() {
    begin();
    const std::optional<Color> c = color(kBackground, "colour");
    if (!c) return false;
    scene_.background = *c;
    if (min_component(*c) < 0.0) {
      report(kBackground, {{"colour", "must be >= 0 in every channel, got " + format_vec(*c)}});
    }
    return true;
  }

  bool light() {
    begin();
    Light l;
    const std::optional<Vec3> p = vec3(kLight, "position");
    if (!p) return false;
    l.position = *p;
    // The optional colour: numbers left on the light's own line.
    const std::optional<Token> t = lex_.peek();
    if (t && t->line == line_ && to_double(t->text)) {
      const std::optional<Color> c = color(kLight, "colour");
      if (!c) return false;
      l.emission = *c;
    }
    scene_.lights.push_back(l);
    report(kLight, check_light(l));
    return true;
  }

  bool fill() {
    begin();
    static constexpr const char* kNames[] = {"r", "g", "b", "Kd", "Ks", "Shine", "T", "ior"};
    double v[8];
    for (int k = 0; k < 8; ++k) {
      const std::optional<double> x = number(kFill, kNames[k]);
      if (!x) return false;
      v[k] = *x;
    }
    Material m;
    m.color = Color(v[0], v[1], v[2]);
    m.kd = v[3];
    m.ks = v[4];
    m.shine = v[5];
    m.t = v[6];
    // SPD writes ior 0 for opaque materials; the ior of a material that
    // transmits nothing is never used, so it is stored as 1.
    m.ior = (m.t == 0.0 && v[7] < 1.0) ? 1.0 : v[7];
    current_material_ = static_cast<int>(scene_.materials.size());
    scene_.materials.push_back(m);
    report(kFill, check_material(m));
    return true;
  }

  bool cone() {
    begin();
    Cone c;
    std::optional<Vec3> p;
    std::optional<double> r;
    if (!(p = vec3(kCone, "base"))) return false;
    c.base = *p;
    if (!(r = number(kCone, "base radius"))) return false;
    c.base_radius = *r;
    if (!(p = vec3(kCone, "apex"))) return false;
    c.apex = *p;
    if (!(r = number(kCone, "apex radius"))) return false;
    c.apex_radius = *r;
    c.capped = false;  // NFF cylinders and cones have no end caps
    report(kCone, check_shape(c));
    add_object(c);
    return true;
  }

  bool sphere() {
    begin();
    Sphere s;
    std::optional<Vec3> p;
    std::optional<double> r;
    if (!(p = vec3(kSphere, "centre"))) return false;
    s.center = *p;
    if (!(r = number(kSphere, "radius"))) return false;
    s.radius = *r;
    report(kSphere, check_shape(s));
    add_object(s);
    return true;
  }

  bool polygon(bool patch) {
    const Entity& e = patch ? kPatch : kPolygon;
    begin();
    const std::optional<long long> count = integer(e, "vertex count");
    if (!count) return false;
    if (*count < 3) {
      return fail(e, fmt::format("needs at least 3 vertices, got a count of {}", *count));
    }
    std::vector<Vec3> vertices, normals;
    // Reserve no more than the text could hold: a corrupt count must not
    // allocate gigabytes before the file runs out.
    const size_t plausible = static_cast<size_t>(std::min<long long>(*count, 1 << 16));
    vertices.reserve(plausible);
    if (patch) normals.reserve(plausible);
    for (long long i = 0; i < *count; ++i) {
      const std::optional<Vec3> v = vec3(e, fmt::format("vertex {}", i));
      if (!v) return false;
      vertices.push_back(*v);
      if (patch) {
        const std::optional<Vec3> n = vec3(e, fmt::format("normal {}", i));
        if (!n) return false;
        normals.push_back(*n);
      }
    }
    if (has_zero_area(vertices)) {
      if (dropped_++ == 0) first_dropped_line_ = entity_line_;
      return true;
    }
    if (patch) {
      Patch p{std::move(vertices), std::move(normals)};
      report(e, check_shape(p));
      add_object(std::move(p));
    } else {
      Polygon p{std::move(vertices)};
      report(e, check_shape(p));
      add_object(std::move(p));
    }
    return true;
  }

  Lexer lex_;
  std::string name_;
  Scene scene_;
  std::string error_;
  std::vector<std::string> problems_;
  int line_ = 1;         // where a syntax error is reported
  int entity_line_ = 0;  // first line of the entity being read, 0 before any
  int camera_line_ = 0;
  int current_material_ = -1;
  int dropped_ = 0;
  int first_dropped_line_ = 0;
};

}  // namespace

Result<Scene> parse_nff(std::string_view text, const std::string& name) {
  return NffParser(text, name).parse();
}

Result<Scene> load_nff(const std::string& path) {
  Result<std::string> text = read_text_file(path);
  if (!text.ok()) return text.status();
  return parse_nff(*text, path);
}

}  // namespace locus

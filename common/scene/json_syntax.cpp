// The JSON syntax check of the native scene format (json_syntax.h): a strict
// RFC 8259 walker that names the line and column of a syntax error and the
// JSON path of a repeated key, and the rewording of protobuf's JSON errors.
#include "common/scene/json_syntax.h"

#include <fmt/format.h>

#include <cctype>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace locus {
namespace {

// protobuf's JSON parser reports a syntax error with a 40-character excerpt
// and no position, and lets a repeated key silently overwrite the first. This
// strict RFC 8259 pass runs first and names the line and column, or the JSON
// path of a repeated key; it checks nothing about the schema.
class JsonSyntax {
 public:
  explicit JsonSyntax(std::string_view text) : t_(text) {}

  // Empty when the text is one well-formed JSON object.
  std::string check() {
    skip_space();
    if (pos_ >= t_.size() || t_[pos_] != '{') {
      fail("a scene file must hold one JSON object { ... }");
      return error_;
    }
    if (value(0)) {
      skip_space();
      if (pos_ < t_.size()) fail("unexpected text after the scene object");
    }
    return error_;
  }

 private:
  static constexpr int kMaxDepth = 100;  // protobuf's own recursion limit

  bool fail(const std::string& what) {
    int line = 1;
    size_t line_start = 0;
    for (size_t i = 0; i < pos_ && i < t_.size(); ++i) {
      if (t_[i] == '\n') {
        ++line;
        line_start = i + 1;
      }
    }
    error_ = fmt::format("{}:{}: {}", line, pos_ - line_start + 1, what);
    return false;
  }

  void skip_space() {
    while (pos_ < t_.size() &&
           (t_[pos_] == ' ' || t_[pos_] == '\t' || t_[pos_] == '\n' || t_[pos_] == '\r')) {
      ++pos_;
    }
  }

  std::string path() const {
    std::string out;
    for (const std::string& s : path_) out += (out.empty() || s[0] == '[' ? "" : ".") + s;
    return out.empty() ? "the top level" : out;
  }

  bool value(int depth) {
    if (depth > kMaxDepth) return fail(fmt::format("nested deeper than {} levels", kMaxDepth));
    skip_space();
    if (pos_ >= t_.size()) return fail("the file ends where a value was expected");
    switch (t_[pos_]) {
      case '{':
        return object(depth);
      case '[':
        return array(depth);
      case '"':
        return string(nullptr);
      case 't':
        return literal("true");
      case 'f':
        return literal("false");
      case 'n':
        return literal("null");
      default:
        return number();
    }
  }

  bool object(int depth) {
    ++pos_;  // {
    std::set<std::string> keys;
    skip_space();
    if (pos_ < t_.size() && t_[pos_] == '}') {
      ++pos_;
      return true;
    }
    while (true) {
      skip_space();
      if (pos_ >= t_.size() || t_[pos_] != '"') return fail("expected a \"key\" in quotes");
      const size_t key_pos = pos_;
      std::string key;
      if (!string(&key)) return false;
      // protobuf takes both spellings of a field name (base_radius and
      // baseRadius) as the same field.
      std::string normal;
      for (size_t i = 0; i < key.size(); ++i) {
        if (key[i] == '_' && i + 1 < key.size()) {
          normal += static_cast<char>(std::toupper(static_cast<unsigned char>(key[++i])));
        } else {
          normal += key[i];
        }
      }
      if (!keys.insert(normal).second) {
        pos_ = key_pos;
        return fail(fmt::format("{}: key \"{}\" appears twice", path(), key));
      }
      skip_space();
      if (pos_ >= t_.size() || t_[pos_] != ':') return fail("expected ':' after the key");
      ++pos_;
      path_.push_back(key);
      if (!value(depth + 1)) return false;
      path_.pop_back();
      const Next next = after_value('}', "expected ',' or '}' after a value in an object");
      if (next == Next::kMore) continue;
      return next == Next::kClosed;
    }
  }

  // After a member or an element: a ',' (another follows), `close` (the
  // object or array ends) or an error, reported as `expected`.
  enum class Next { kMore, kClosed, kFailed };
  Next after_value(char close, const char* expected) {
    skip_space();
    if (pos_ < t_.size() && t_[pos_] == ',') {
      ++pos_;
      return Next::kMore;
    }
    if (pos_ < t_.size() && t_[pos_] == close) {
      ++pos_;
      return Next::kClosed;
    }
    fail(expected);
    return Next::kFailed;
  }

  bool array(int depth) {
    ++pos_;  // [
    skip_space();
    if (pos_ < t_.size() && t_[pos_] == ']') {
      ++pos_;
      return true;
    }
    for (size_t index = 0;; ++index) {
      path_.push_back(fmt::format("[{}]", index));
      if (!value(depth + 1)) return false;
      path_.pop_back();
      const Next next = after_value(']', "expected ',' or ']' after a value in an array");
      if (next == Next::kMore) continue;
      return next == Next::kClosed;
    }
  }

  bool string(std::string* out) {
    ++pos_;  // "
    while (pos_ < t_.size()) {
      const char c = t_[pos_];
      if (c == '"') {
        ++pos_;
        return true;
      }
      if (static_cast<unsigned char>(c) < 0x20) {
        return fail("control character in a string (write \\n, \\t, ...)");
      }
      if (c == '\\') {
        const size_t start = pos_;
        if (++pos_ >= t_.size()) break;
        const char e = t_[pos_];
        if (e == 'u') {
          for (int k = 1; k <= 4; ++k) {
            if (pos_ + k >= t_.size() || !std::isxdigit(static_cast<unsigned char>(t_[pos_ + k]))) {
              return fail("\\u must be followed by 4 hex digits");
            }
          }
          pos_ += 4;
        } else if (std::string_view("\"\\/bfnrt").find(e) == std::string_view::npos) {
          return fail(fmt::format("invalid escape \\{} in a string", e));
        }
        // Keys are compared as written: only repeated keys matter here.
        if (out) *out += t_.substr(start, pos_ + 1 - start);
      } else if (out) {
        *out += c;
      }
      ++pos_;
    }
    return fail("the file ends inside a string");
  }

  bool literal(std::string_view word) {
    if (t_.substr(pos_, word.size()) != word) return fail("expected a value");
    pos_ += word.size();
    return true;
  }

  // -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  bool number() {
    auto digits = [&] {
      const size_t start = pos_;
      while (pos_ < t_.size() && std::isdigit(static_cast<unsigned char>(t_[pos_]))) ++pos_;
      return pos_ > start;
    };
    const size_t start = pos_;
    if (pos_ < t_.size() && t_[pos_] == '-') ++pos_;
    if (pos_ < t_.size() && t_[pos_] == '0') {
      ++pos_;
    } else if (!digits()) {
      pos_ = start;
      return fail("expected a value (a number, string, object, array, true, false or null)");
    }
    if (pos_ < t_.size() && t_[pos_] == '.') {
      ++pos_;
      if (!digits()) return fail("expected digits after the decimal point");
    }
    if (pos_ < t_.size() && (t_[pos_] == 'e' || t_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < t_.size() && (t_[pos_] == '+' || t_[pos_] == '-')) ++pos_;
      if (!digits()) return fail("expected digits in the exponent");
    }
    return true;
  }

  std::string_view t_;
  size_t pos_ = 0;
  std::vector<std::string> path_;
  std::string error_;
};

}  // namespace

std::string json_syntax_error(std::string_view text) { return JsonSyntax(text).check(); }

// protobuf 3.21 words errors as "(objects[0].sphere) radiuss: Cannot find
// field." or "(camera.width): invalid value 1.5 for type TYPE_INT32"; this
// turns them into "objects[0].sphere.radiuss: unknown field" and
// "camera.width: invalid value 1.5 for type TYPE_INT32".
std::string rewrite_protobuf_error(std::string_view message) {
  message = message.substr(0, message.find('\n'));
  std::string path;
  if (!message.empty() && message[0] == '(') {
    const size_t close = message.find(')');
    if (close != std::string_view::npos) {
      path = std::string(message.substr(1, close - 1));
      message.remove_prefix(close + 1);
      if (!message.empty() && message[0] == ':') message.remove_prefix(1);
      while (!message.empty() && message[0] == ' ') message.remove_prefix(1);
    }
  }
  constexpr std::string_view kUnknown = ": Cannot find field.";
  if (message.size() > kUnknown.size() && message.ends_with(kUnknown)) {
    const std::string field(message.substr(0, message.size() - kUnknown.size()));
    return fmt::format("{}{}: unknown field (docs/scene-format.md lists the fields)",
                       path.empty() ? "" : path + ".", field);
  }
  return path.empty() ? std::string(message) : path + ": " + std::string(message);
}

}  // namespace locus

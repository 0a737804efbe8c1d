#include "common/base/text.h"

#include <fmt/format.h>

namespace locus {

std::string format_number(double x) { return fmt::format("{}", x); }

std::string format_vec(const Vec3& v) {
  return fmt::format("[{}, {}, {}]", format_number(v.x), format_number(v.y), format_number(v.z));
}

}  // namespace locus

// Numbers as messages quote them.
#pragma once

#include <string>

#include "common/base/math.h"

namespace locus {

// Shortest text that reads back as the same double: messages quote values
// exactly as the loader saw them.
std::string format_number(double x);
std::string format_vec(const Vec3& v);

}  // namespace locus

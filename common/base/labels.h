// Enum names from one table per enum (yocto-gl's `*_labels` habit): the same
// table serves printing, parsing, and the choices a message or `--help`
// lists, so a new value is named in one place.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace locus {

template <class E>
struct Label {
  E value;
  std::string_view name;
};

template <class E, size_t N>
using Labels = std::array<Label<E>, N>;

// The name of `value`, or `fallback` for a value the table lacks (a
// corrupted or newer enum value from the wire).
template <class E, size_t N>
constexpr std::string_view label_name(const Labels<E, N>& labels, E value,
                                      std::string_view fallback = "unknown") {
  for (const auto& l : labels) {
    if (l.value == value) return l.name;
  }
  return fallback;
}

// The value named `name` exactly, if any.
template <class E, size_t N>
constexpr std::optional<E> label_value(const Labels<E, N>& labels, std::string_view name) {
  for (const auto& l : labels) {
    if (l.name == name) return l.value;
  }
  return std::nullopt;
}

// "a, b or c": the choices, for messages.
template <class E, size_t N>
std::string label_choices(const Labels<E, N>& labels) {
  std::string out;
  for (size_t i = 0; i < N; ++i) {
    if (i > 0) out += i + 1 == N ? " or " : ", ";
    out += labels[i].name;
  }
  return out;
}

// Every name, in order: the choices of a CLI option (CLI::IsMember).
template <class E, size_t N>
std::vector<std::string> label_names(const Labels<E, N>& labels) {
  std::vector<std::string> names;
  for (const auto& l : labels) names.emplace_back(l.name);
  return names;
}

}  // namespace locus

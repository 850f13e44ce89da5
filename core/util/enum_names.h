// Names of enums as written in scene files, on the command line, in EXR metadata, on the wire and in the database: one
// table per enum beside it (e.g. core/render/light.h, protocol/job.h), read in both directions by the functions here.
#pragma once

#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace tessera {

/// The name of `e` in `names`, a table listing every enumerator's name in declaration order.
template <class E, std::size_t N>
constexpr std::string_view enum_name(E e, const std::string_view (&names)[N]) {
  const auto i = static_cast<std::size_t>(e);
  return i < N ? names[i] : std::string_view("unknown");
}

/// The enumerator named `s` in `names` (declaration order), or nothing when no name matches.
template <class E, std::size_t N>
constexpr std::optional<E> enum_from_name(std::string_view s, const std::string_view (&names)[N]) {
  for (std::size_t i = 0; i < N; ++i)
    if (names[i] == s) return static_cast<E>(i);
  return std::nullopt;
}

/// enum_name as a C string (every table entry is a string literal, so it ends in a NUL).
template <class E, std::size_t N>
constexpr const char* enum_c_name(E e, const std::string_view (&names)[N]) {
  return enum_name(e, names).data();
}

/// The enumerator named `s` in `names`; throws std::invalid_argument ("unknown <what> '<s>'") when no name matches.
template <class E, std::size_t N>
E enum_from_name_or_throw(std::string_view s, const std::string_view (&names)[N], std::string_view what) {
  if (const std::optional<E> e = enum_from_name<E>(s, names)) return *e;
  throw std::invalid_argument("unknown " + std::string(what) + " '" + std::string(s) + "'");
}

/// The table as strings, e.g. for a command-line option's list of allowed values.
template <std::size_t N>
std::vector<std::string> enum_names(const std::string_view (&names)[N]) {
  return std::vector<std::string>(std::begin(names), std::end(names));
}

}  // namespace tessera

// The names of an enumeration in one table: parse_name() and name_of() read the same table, so
// a value and its spelling are declared once (options, problem files, reports and messages all
// use it). A parse error names the kind of value and lists every accepted spelling.
#pragma once

#include <array>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace htfeti {

template <class E>
struct EnumName {
  E value;
  const char* name;
};

/// The value spelled `text`; throws std::invalid_argument("unknown WHAT 'text' (expected a, b
/// or c)").
template <class E, size_t N>
E parse_name(const std::array<EnumName<E>, N>& names, std::string_view text, const char* what) {
  for (const auto& n : names)
    if (text == n.name) return n.value;
  std::string list;
  for (size_t i = 0; i < N; ++i)
    list += std::string(i == 0 ? "" : i + 1 == N ? " or " : ", ") + names[i].name;
  throw std::invalid_argument("unknown " + std::string(what) + " '" + std::string(text) +
                              "' (expected " + list + ")");
}

/// The spelling of `value` ("?" for a value the table lacks).
template <class E, size_t N>
std::string name_of(const std::array<EnumName<E>, N>& names, E value) {
  for (const auto& n : names)
    if (n.value == value) return n.name;
  return "?";
}

/// Every spelling, in table order.
template <class E, size_t N>
std::vector<std::string> names_of(const std::array<EnumName<E>, N>& names) {
  std::vector<std::string> out;
  for (const auto& n : names) out.emplace_back(n.name);
  return out;
}

}  // namespace htfeti

#pragma once
// Text of generated C (c_export.hpp): the helpers both generators write with.
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>

#include "analyzer/ident/term.hpp"

namespace inertia::compensate::c_text {

inline bool is_identifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

inline std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// A constant in the generated code: shortest round-trip digits, cast to the real type.
inline std::string literal(double v) {
  if (std::isnan(v)) return "(R)NAN";
  return fmt::format("(R){}", v);
}

/// The name of a variable's slot in the state's histories and the inputs.
inline std::string slot(ident::Variable v) {
  std::string s = ident::variable_name(v);
  return s == "T" ? "temp" : s;
}

/// f(v)^power as C, with its slope when `slope` is set.
inline std::string factor_code(const ident::Factor& f, const std::string& v, bool slope) {
  const int p = f.power;
  switch (f.function) {
    case ident::FactorFunction::Plain:
      if (!slope) return fmt::format("ipow({}, {})", v, p);
      return fmt::format("(R){} * ipow({}, {})", p, v, p - 1);
    case ident::FactorFunction::Abs:
      if (!slope) return fmt::format("ipow(fabs({}), {})", v, p);
      return fmt::format("(R){} * ipow(fabs({}), {}) * sgn({})", p, v, p - 1, v);
    case ident::FactorFunction::Sign:
      return slope ? std::string("(R)0") : fmt::format("ipow(sgn({}), {})", v, p);
  }
  return "(R)0";
}

}  // namespace inertia::compensate::c_text

#include "analyzer/ident/term.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <map>
#include <utility>

#include <fmt/format.h>

#include "common/input_error.hpp"

namespace inertia::ident {

namespace {

constexpr std::array<const char*, kVariableCount> kVariableNames = {
    "a_i", "a_p", "a_o", "a_x", "a_y", "a_z", "w_i", "w_p", "w_o", "w_x", "w_y", "w_z", "T", "y", "e"};

bool is_acceleration(Variable v) { return v <= Variable::Az; }
bool is_rate(Variable v) { return v >= Variable::Wi && v <= Variable::Wz; }

std::string factor_to_string(const Factor& f) {
  const std::string lag = f.lag > 0 ? fmt::format("[k-{}]", f.lag) : std::string();
  const std::string power = f.power > 1 ? fmt::format("^{}", f.power) : std::string();
  const char* name = variable_name(f.variable);
  switch (f.function) {
    case FactorFunction::Plain: return name + power + lag;
    case FactorFunction::Abs: return "abs(" + (name + lag) + ")" + power;
    case FactorFunction::Sign: return "sign(" + (name + lag) + ")" + power;
  }
  return {};
}

std::string join(const std::vector<Factor>& factors) {
  if (factors.empty()) return "1";
  std::string s;
  for (const Factor& f : factors) {
    if (!s.empty()) s += '*';
    s += factor_to_string(f);
  }
  return s;
}

}  // namespace

const char* variable_name(Variable v) { return kVariableNames[static_cast<std::size_t>(v)]; }

Term Term::from_factors(std::vector<Factor> factors) {
  const std::string as_given = join(factors);
  const auto fail = [&](const std::string& why) {
    return InputError(fmt::format("term '{}': {}", as_given, why));
  };
  // Per (variable, lag): x^p |x|^q sign(x)^s = |x|^(p+q) sign(x)^(p+s).
  struct Powers {
    int plain = 0, abs = 0, sign = 0;
  };
  std::map<std::pair<Variable, int>, Powers> groups;
  for (const Factor& f : factors) {
    if (f.lag < 0 || f.lag > kMaxLag) throw fail(fmt::format("lag {} is outside 0..{}", f.lag, kMaxLag));
    if (f.power < 1 || f.power > kMaxPower) throw fail(fmt::format("power {} is outside 1..{}", f.power, kMaxPower));
    if (f.variable == Variable::E && f.lag == 0) {
      throw fail("the residual e is only known for past samples; write it lagged, e.g. e[k-1]");
    }
    Powers& g = groups[{f.variable, f.lag}];
    (f.function == FactorFunction::Plain ? g.plain : f.function == FactorFunction::Abs ? g.abs : g.sign) += f.power;
  }
  Term term;
  for (const auto& [key, g] : groups) {
    const int n = g.plain + g.abs;              // power of |x|
    const bool odd_sign = ((g.plain + g.sign) % 2) != 0;
    const Factor base{key.first, key.second, FactorFunction::Plain, 1};
    if (n == 0) {
      if (!odd_sign) {
        throw fail(fmt::format("sign({})^{} is the constant 1 (except at 0); use the bias '1'",
                               variable_name(key.first), g.sign));
      }
      term.factors_.push_back(Factor{key.first, key.second, FactorFunction::Sign, 1});
      continue;
    }
    if (n > kMaxPower) throw fail(fmt::format("power {} is above {}", n, kMaxPower));
    // |x|^n sign(x)^s: x^n when n and s have the same parity, else x^(n-1) |x|.
    const bool plain_only = (n % 2 == 0) == !odd_sign;
    if (plain_only) {
      term.factors_.push_back(Factor{base.variable, base.lag, FactorFunction::Plain, n});
    } else {
      if (n > 1) term.factors_.push_back(Factor{base.variable, base.lag, FactorFunction::Plain, n - 1});
      term.factors_.push_back(Factor{base.variable, base.lag, FactorFunction::Abs, 1});
    }
  }
  // The unlagged output goes first: y*T, y*w_i read as the output-multiplied (rational) terms
  // they are, as docs/design.md spells them; everything else follows the variable order.
  std::sort(term.factors_.begin(), term.factors_.end(), [](const Factor& a, const Factor& b) {
    const bool a_first = a.variable == Variable::Y && a.lag == 0;
    const bool b_first = b.variable == Variable::Y && b.lag == 0;
    if (a_first != b_first) return a_first;
    return a < b;
  });
  const bool only_current_y = !term.factors_.empty() && std::all_of(term.factors_.begin(), term.factors_.end(), [](const Factor& f) {
    return f.variable == Variable::Y && f.lag == 0;
  });
  if (only_current_y) {
    throw fail("the output y(k) cannot explain itself; use it lagged (y[k-1]) or multiplied by an input "
               "(y*T, y*w_i)");
  }
  return term;
}

std::string Term::to_string() const { return join(factors_); }

int Term::max_lag() const {
  int m = 0;
  for (const Factor& f : factors_) m = std::max(m, f.lag);
  return m;
}

Term Term::denominator_factor() const {
  if (!is_output_multiplied()) return *this;
  std::vector<Factor> rest;
  for (const Factor& f : factors_) {
    if (f.variable == Variable::Y && f.lag == 0) {
      if (f.power > 1) rest.push_back({Variable::Y, 0, f.function, f.power - 1});
      continue;
    }
    rest.push_back(f);
  }
  return rest.empty() ? Term() : from_factors(std::move(rest));
}

bool Term::is_output_multiplied() const {
  return std::any_of(factors_.begin(), factors_.end(),
                     [](const Factor& f) { return f.variable == Variable::Y && f.lag == 0; });
}

bool Term::is_noise_term() const { return uses(Variable::E); }

std::vector<Variable> Term::variables() const {
  std::array<bool, kVariableCount> used{};
  for (const Factor& f : factors_) used[static_cast<std::size_t>(f.variable)] = true;
  std::vector<Variable> v;
  for (int i = 0; i < kVariableCount; ++i) {
    if (used[static_cast<std::size_t>(i)]) v.push_back(static_cast<Variable>(i));
  }
  return v;
}

bool Term::uses(Variable v) const {
  return std::any_of(factors_.begin(), factors_.end(), [v](const Factor& f) { return f.variable == v; });
}

namespace {

class TermParser {
 public:
  explicit TermParser(std::string_view text) : text_(text) {}

  Term parse() {
    skip_space();
    if (at_end()) throw error(pos_, "empty term");
    if (text_[pos_] == '1') {
      const std::size_t one = pos_++;
      skip_space();
      if (!at_end()) {
        throw error(one, "'1' (the bias) must stand alone, not in a product");
      }
      return Term{};
    }
    std::vector<Factor> factors;
    std::size_t first_y = std::string_view::npos;
    for (;;) {
      skip_space();
      if (at_end() || text_[pos_] == '*') throw error(pos_, "empty factor");
      const std::size_t start = pos_;
      const Factor f = parse_factor();
      if (f.variable == Variable::E && f.lag == 0) {
        throw error(start, "the residual e is only known for past samples; write it lagged, e.g. e[k-1]");
      }
      if (f.variable == Variable::Y && f.lag == 0 && first_y == std::string_view::npos) first_y = start;
      factors.push_back(f);
      skip_space();
      if (at_end()) break;
      if (text_[pos_] != '*') throw error(pos_, fmt::format("expected '*' or the end, found '{}'", text_[pos_]));
      ++pos_;
    }
    const bool only_current_y = std::all_of(factors.begin(), factors.end(), [](const Factor& f) {
      return f.variable == Variable::Y && f.lag == 0;
    });
    if (only_current_y) {
      throw error(first_y, "the output y(k) cannot explain itself; use it lagged (y[k-1]) or multiplied by an "
                           "input (y*T, y*w_i)");
    }
    try {
      return Term::from_factors(std::move(factors));
    } catch (const InputError& e) {
      // Rules that need the whole product (powers after merging, sign(x)^2): no single position.
      throw InputError(fmt::format("term '{}': {}", text_, strip_prefix(e.what())));
    }
  }

 private:
  static std::string strip_prefix(const std::string& what) {
    const std::size_t colon = what.find("': ");
    return colon == std::string::npos ? what : what.substr(colon + 3);
  }

  [[nodiscard]] bool at_end() const { return pos_ >= text_.size(); }

  void skip_space() {
    while (!at_end() && std::isspace(static_cast<unsigned char>(text_[pos_])) != 0) ++pos_;
  }

  InputError error(std::size_t at, const std::string& why) const {
    return InputError(fmt::format("term '{}': {} at character {}", text_, why, at + 1));
  }

  std::string_view identifier() {
    const std::size_t start = pos_;
    while (!at_end() && (std::isalnum(static_cast<unsigned char>(text_[pos_])) != 0 || text_[pos_] == '_')) ++pos_;
    return text_.substr(start, pos_ - start);
  }

  Variable variable() {
    skip_space();
    const std::size_t start = pos_;
    const std::string_view name = identifier();
    if (name.empty()) {
      throw error(start, at_end() ? std::string("expected a variable, found the end")
                                  : fmt::format("expected a variable, found '{}'", text_[start]));
    }
    if (name == "1") throw error(start, "'1' (the bias) must stand alone, not in a product");
    for (int i = 0; i < kVariableCount; ++i) {
      if (name == kVariableNames[static_cast<std::size_t>(i)]) return static_cast<Variable>(i);
    }
    throw error(start, fmt::format("unknown variable '{}' (known: a_i a_p a_o a_x a_y a_z w_i w_p w_o w_x w_y w_z "
                                   "T y e, and abs(...), sign(...))",
                                   name));
  }

  void expect(char c, std::string_view what) {
    skip_space();
    if (at_end() || text_[pos_] != c) {
      throw error(pos_, fmt::format("malformed {}: expected '{}'{}", what, c,
                                    at_end() ? std::string(", found the end") : fmt::format(", found '{}'", text_[pos_])));
    }
    ++pos_;
  }

  int integer(std::string_view what) {
    skip_space();
    const std::size_t start = pos_;
    long value = 0;
    while (!at_end() && std::isdigit(static_cast<unsigned char>(text_[pos_])) != 0) {
      value = std::min<long>(value * 10 + (text_[pos_] - '0'), 1L << 30);
      ++pos_;
    }
    if (pos_ == start) {
      throw error(start, fmt::format("malformed {}: expected a non-negative integer{}", what,
                                     at_end() ? std::string(", found the end") : fmt::format(", found '{}'", text_[pos_])));
    }
    return static_cast<int>(value);
  }

  // "[k-j]", the '[' already seen at pos_.
  int lag() {
    const std::size_t start = pos_;
    ++pos_;
    skip_space();
    if (at_end() || text_[pos_] != 'k') throw error(pos_, "malformed lag: expected 'k' as in [k-1]");
    ++pos_;
    skip_space();
    if (!at_end() && text_[pos_] == ']') throw error(start, "lag 0 ([k]) is the current sample; drop the lag");
    expect('-', "lag (write [k-j], j >= 1)");
    const int j = integer("lag");
    expect(']', "lag");
    if (j == 0) throw error(start, "lag 0 ([k-0]) is the current sample; drop the lag");
    if (j > kMaxLag) throw error(start, fmt::format("lag {} is above {}", j, kMaxLag));
    return j;
  }

  int power() {
    const std::size_t start = pos_;
    ++pos_;  // '^'
    const int n = integer("power");
    if (n < 1) throw error(start, "power 0 is the constant 1; use the bias '1'");
    if (n > kMaxPower) throw error(start, fmt::format("power {} is above {}", n, kMaxPower));
    return n;
  }

  Factor parse_factor() {
    Factor f;
    bool has_lag = false;
    const std::size_t start = pos_;
    const std::string_view word = identifier();
    bool function = false;
    if (word == "abs" || word == "sign") {
      skip_space();
      function = !at_end() && text_[pos_] == '(';
    }
    if (function) {
      f.function = word == "abs" ? FactorFunction::Abs : FactorFunction::Sign;
      ++pos_;  // '('
      f.variable = variable();
      skip_space();
      if (!at_end() && text_[pos_] == '[') {
        f.lag = lag();
        has_lag = true;
      }
      expect(')', fmt::format("{}(...)", word));
    } else {
      pos_ = start;
      f.variable = variable();
    }
    bool has_power = false;
    for (;;) {
      skip_space();
      if (at_end()) break;
      if (text_[pos_] == '^') {
        if (has_power) throw error(pos_, "malformed power: a factor takes one power");
        f.power = power();
        has_power = true;
      } else if (text_[pos_] == '[') {
        if (has_lag) throw error(pos_, "malformed lag: a factor takes one lag");
        f.lag = lag();
        has_lag = true;
      } else {
        break;
      }
    }
    return f;
  }

  std::string_view text_;
  std::size_t pos_ = 0;
};

}  // namespace

Term parse_term(std::string_view text) { return TermParser(text).parse(); }

std::vector<Term> parse_terms(const std::vector<std::string>& texts) {
  std::vector<Term> terms;
  terms.reserve(texts.size());
  for (std::size_t i = 0; i < texts.size(); ++i) {
    Term t = parse_term(texts[i]);
    for (std::size_t j = 0; j < terms.size(); ++j) {
      if (terms[j] == t) {
        throw InputError(fmt::format("terms '{}' and '{}' are the same term '{}'", texts[j], texts[i], t.to_string()));
      }
    }
    terms.push_back(std::move(t));
  }
  return terms;
}

std::vector<std::string> to_strings(const std::vector<Term>& terms) {
  std::vector<std::string> s;
  s.reserve(terms.size());
  for (const Term& t : terms) s.push_back(t.to_string());
  return s;
}

const char* physical_name(const Term& term, dataset::SensorKind kind) {
  const auto& fs = term.factors();
  if (fs.empty()) return "bias";
  if (term.uses(Variable::E)) return "coloured noise";
  if (term.max_lag() > 0) return "dynamics";
  if (term.is_output_multiplied()) {
    const bool only_temperature = std::all_of(fs.begin(), fs.end(), [](const Factor& f) {
      return f.variable == Variable::Y || (f.variable == Variable::T && f.function == FactorFunction::Plain);
    });
    return only_temperature ? "scale-factor temperature coefficient" : "scale-factor nonlinearity";
  }
  if (term.uses(Variable::T)) {
    return term.variables().size() == 1 ? "bias temperature coefficient" : "scale-factor temperature coefficient";
  }
  const bool gyro = kind == dataset::SensorKind::Gyroscope;
  const bool any_acceleration = std::any_of(fs.begin(), fs.end(), [](const Factor& f) { return is_acceleration(f.variable); });
  const bool any_rate = std::any_of(fs.begin(), fs.end(), [](const Factor& f) { return is_rate(f.variable); });
  if (gyro && any_acceleration) return "g-sensitivity";
  if (!gyro && any_rate) return "rate sensitivity";
  // Only the sensed quantity remains (a_* for an accelerometer, w_* for a gyro).
  const Variable input_axis = gyro ? Variable::Wi : Variable::Ai;
  if (fs.size() == 1) {
    const Factor& f = fs[0];
    switch (f.function) {
      case FactorFunction::Sign: return "asymmetry/hysteresis";
      case FactorFunction::Abs: return "rectification";
      case FactorFunction::Plain:
        if (f.power == 1) return f.variable == input_axis ? "scale factor" : "misalignment/cross-axis sensitivity";
        return f.power == 2 ? "second-order nonlinearity" : "higher-order nonlinearity";
    }
  }
  if (fs.size() == 2 && fs[0].power == 1 && fs[1].power == 1) {
    if (fs[0].variable == fs[1].variable && fs[0].function == FactorFunction::Plain &&
        fs[1].function == FactorFunction::Abs) {
      return "odd quadratic";
    }
    if (fs[0].function == FactorFunction::Plain && fs[1].function == FactorFunction::Plain) {
      return "cross-coupling (vibropendulous)";
    }
  }
  return "higher-order nonlinearity";
}

}  // namespace inertia::ident

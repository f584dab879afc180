// Term grammar (docs/design.md, "Model terms"; analyzer/ident/term.hpp).
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <utility>
#include <vector>

#include "analyzer/ident/term.hpp"
#include "common/input_error.hpp"

namespace inertia::ident {
namespace {

using dataset::SensorKind;

TEST(Term, CanonicalExamplesRoundTrip) {
  for (const char* text : {"1", "a_i", "a_i^2", "a_i*a_p", "a_i*abs(a_i)", "sign(a_i)", "abs(a_i)", "a_i*T",
                           "y[k-1]", "a_o^2[k-1]", "y*w_i", "y*T", "T", "T[k-1]", "e[k-3]", "a_x", "w_z",
                           "a_i*a_i[k-1]", "abs(a_i[k-2])", "sign(a_p[k-1])", "a_i^2*abs(a_i)", "a_i^3",
                           "y[k-1]*y[k-12]", "a_i*a_p*a_o", "a_i[k-1]*abs(a_i[k-1])"}) {
    EXPECT_EQ(parse_term(text).to_string(), text);
  }
}

TEST(Term, CanonicalizesOrderPowersLagsAndSpaces) {
  const std::vector<std::pair<const char*, const char*>> cases = {
      {"a_p*a_i", "a_i*a_p"},
      {"a_i*a_i", "a_i^2"},
      {"a_i^2*a_i", "a_i^3"},
      {"a_o[k-1]^2", "a_o^2[k-1]"},
      {"a_o[k-1]*a_o[k-1]", "a_o^2[k-1]"},
      {" a_i * T ", "a_i*T"},
      {"T*a_i", "a_i*T"},
      {"w_i*y", "y*w_i"},
      {"abs(a_i)*a_i", "a_i*abs(a_i)"},
      {"sign(a_i)*a_i^2*abs(a_p)", "a_i*abs(a_i)*abs(a_p)"},
      {"a_i[k-1]*a_i", "a_i*a_i[k-1]"},
      {"y[k-2]*y[k-1]", "y[k-1]*y[k-2]"},
      {"abs(a_i)[k-2]", "abs(a_i[k-2])"},
      {"abs( a_i [ k - 2 ] )", "abs(a_i[k-2])"},
      {"a_i^1", "a_i"},
      // identities x = |x| sign(x), sign(x)^2 = 1:
      {"abs(a_i)^2", "a_i^2"},
      {"abs(a_i)*abs(a_i)", "a_i^2"},
      {"a_i*sign(a_i)", "abs(a_i)"},
      {"abs(a_i)*sign(a_i)", "a_i"},
      {"abs(a_i)^3", "a_i^2*abs(a_i)"},
      {"a_i^2*sign(a_i)", "a_i*abs(a_i)"},
  };
  for (const auto& [in, out] : cases) EXPECT_EQ(parse_term(in).to_string(), out) << in;
}

TEST(Term, OrderIsVariablesThenLagThenFunction) {
  // The design's variable order, checked on a product of all of them.
  EXPECT_EQ(parse_term("e[k-1]*y[k-1]*T*w_z*w_y*w_x*w_o*w_p*w_i*a_z*a_y*a_x*a_o*a_p*a_i").to_string(),
            "a_i*a_p*a_o*a_x*a_y*a_z*w_i*w_p*w_o*w_x*w_y*w_z*T*y[k-1]*e[k-1]");
  // ...except that the unlagged output leads (docs/design.md: y*T, y*w_i).
  EXPECT_EQ(parse_term("a_i*y[k-1]*T*y").to_string(), "y*a_i*T*y[k-1]");
  EXPECT_EQ(parse_term("sign(a_i[k-1])*abs(a_i[k-1])*sign(a_i)*a_i[k-2]").to_string(),
            "sign(a_i)*a_i[k-1]*a_i[k-2]");  // sign*abs at one lag is the plain variable
}

struct Rejected {
  const char* text;
  const char* part;   // expected in what(), with the position when there is one
};

TEST(Term, RejectsWithTextAndPosition) {
  for (const Rejected& r : std::vector<Rejected>{
           {"a_q", "unknown variable 'a_q' (known"},
           {"a_i*b_x", "unknown variable 'b_x'"},
           {"a_i*b_x", "at character 5"},
           {"", "empty term at character 1"},
           {"a_i**a_p", "empty factor at character 5"},
           {"*a_i", "empty factor at character 1"},
           {"a_i*", "empty factor at character 5"},
           {"y", "output y(k) cannot explain itself; use it lagged (y[k-1]) or multiplied by an input (y*T, y*w_i) at character 1"},
           {"y^2", "output y(k)"},
           {"y*y", "output y(k)"},
           {"e", "residual e is only known for past samples; write it lagged, e.g. e[k-1] at character 1"},
           {"a_i*e", "at character 5"},
           {"a_i[k-0]", "lag 0"},
           {"a_i[k]", "lag 0 ([k])"},
           {"a_i[k+1]", "malformed lag"},
           {"a_i[j-1]", "malformed lag"},
           {"a_i[k-1", "malformed lag: expected ']'"},
           {"a_i[k-1][k-2]", "one lag"},
           {"a_i^", "malformed power"},
           {"a_i^x", "malformed power"},
           {"a_i^0", "power 0"},
           {"a_i^2^3", "one power"},
           {"a_i^99", "above"},
           {"1*a_i", "'1' (the bias) must stand alone"},
           {"a_i*1", "'1' (the bias) must stand alone, not in a product at character 5"},
           {"sign(a_i)^2", "constant 1"},
           {"sign(a_i)*sign(a_i)", "constant 1"},
           {"abs(a_i", "expected ')'"},
           {"abs()", "expected a variable"},
           {"a_i a_p", "expected '*' or the end, found 'a' at character 5"},
           {"a_i^16*a_i", "above 16"},
       }) {
    try {
      (void)parse_term(r.text);
      ADD_FAILURE() << "accepted '" << r.text << "'";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("term '") + r.text + "'"), std::string::npos) << what;
      EXPECT_NE(what.find(r.part), std::string::npos) << r.text << " -> " << what;
    }
  }
}

TEST(Term, RandomTextEitherFailsCleanlyOrHasAStableCanonicalForm) {
  // Property: whatever parses, its canonical text parses to the same term and prints the same.
  const std::vector<std::string> tokens = {"a_i", "a_p", "a_o", "a_x", "w_i", "w_z", "T", "y", "e", "abs(", "sign(",
                                           ")", "*", "^", "2", "3", "0", "[k-", "1", "]", " ", "k", "-", "a_", "["};
  std::mt19937 rng(11);
  int parsed = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    std::string text;
    const int n = std::uniform_int_distribution<int>(1, 9)(rng);
    for (int i = 0; i < n; ++i) text += tokens[std::uniform_int_distribution<std::size_t>(0, tokens.size() - 1)(rng)];
    try {
      const Term t = parse_term(text);
      ++parsed;
      const std::string canonical = t.to_string();
      EXPECT_EQ(parse_term(canonical), t) << text;
      EXPECT_EQ(parse_term(canonical).to_string(), canonical) << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("term '" + text + "'"), std::string::npos) << e.what();
    }
  }
  EXPECT_GT(parsed, 100);   // the generator does reach valid terms
}

TEST(Term, LagsOutputMultiplicationAndVariables) {
  EXPECT_EQ(parse_term("1").max_lag(), 0);
  EXPECT_TRUE(parse_term("1").is_bias());
  EXPECT_EQ(parse_term("a_i*a_p[k-3]*y[k-2]").max_lag(), 3);
  EXPECT_EQ(parse_term("abs(a_i[k-4])").max_lag(), 4);
  EXPECT_TRUE(parse_term("y*T").is_output_multiplied());
  EXPECT_TRUE(parse_term("y*w_i").is_output_multiplied());
  EXPECT_FALSE(parse_term("y[k-1]").is_output_multiplied());
  EXPECT_FALSE(parse_term("a_i*T").is_output_multiplied());
  EXPECT_TRUE(parse_term("e[k-1]").is_noise_term());
  EXPECT_FALSE(parse_term("y[k-1]").is_noise_term());
  EXPECT_EQ(parse_term("T*a_i*abs(a_i)*a_i[k-1]").variables(), (std::vector<Variable>{Variable::Ai, Variable::T}));
  EXPECT_TRUE(parse_term("y*w_i").uses(Variable::Wi));
  EXPECT_FALSE(parse_term("y*w_i").uses(Variable::Ai));
}

TEST(Term, FromFactorsValidatesLikeTheParser) {
  EXPECT_EQ(Term::from_factors({{Variable::Ap, 0, FactorFunction::Plain, 1}, {Variable::Ai, 0, FactorFunction::Plain, 1}})
                .to_string(),
            "a_i*a_p");
  EXPECT_THROW(Term::from_factors({{Variable::E, 0, FactorFunction::Plain, 1}}), InputError);
  EXPECT_THROW(Term::from_factors({{Variable::Y, 0, FactorFunction::Plain, 1}}), InputError);
  EXPECT_THROW(Term::from_factors({{Variable::Ai, -1, FactorFunction::Plain, 1}}), InputError);
  EXPECT_THROW(Term::from_factors({{Variable::Ai, 0, FactorFunction::Plain, 0}}), InputError);
}

TEST(Term, DuplicatesInAListAreNamed) {
  try {
    (void)parse_terms({"a_i", "a_p*a_i", "a_i*a_p"});
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'a_p*a_i' and 'a_i*a_p' are the same term 'a_i*a_p'"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(to_strings(parse_terms({"a_p*a_i", "1"})), (std::vector<std::string>{"a_i*a_p", "1"}));
}

TEST(Term, PhysicalNamesOfAnAccelerometer) {
  const std::vector<std::pair<const char*, const char*>> names = {
      {"1", "bias"},
      {"a_i", "scale factor"},
      {"a_p", "misalignment/cross-axis sensitivity"},
      {"a_o", "misalignment/cross-axis sensitivity"},
      {"a_x", "misalignment/cross-axis sensitivity"},
      {"a_z", "misalignment/cross-axis sensitivity"},
      {"a_i^2", "second-order nonlinearity"},
      {"a_p^2", "second-order nonlinearity"},
      {"a_i*a_p", "cross-coupling (vibropendulous)"},
      {"a_p*a_o", "cross-coupling (vibropendulous)"},
      {"abs(a_i)", "rectification"},
      {"a_i*abs(a_i)", "odd quadratic"},
      {"sign(a_i)", "asymmetry/hysteresis"},
      {"T", "bias temperature coefficient"},
      {"T^2", "bias temperature coefficient"},
      {"a_i*T", "scale-factor temperature coefficient"},
      {"a_i[k-1]", "dynamics"},
      {"a_o^2[k-1]", "dynamics"},
      {"y[k-1]", "dynamics"},
      {"e[k-1]", "coloured noise"},
      {"a_i^3", "higher-order nonlinearity"},
      {"w_i", "rate sensitivity"},
  };
  for (const auto& [term, name] : names) {
    EXPECT_STREQ(physical_name(parse_term(term), SensorKind::Accelerometer), name) << term;
  }
}

TEST(Term, PhysicalNamesOfAGyro) {
  const std::vector<std::pair<const char*, const char*>> names = {
      {"1", "bias"},
      {"w_i", "scale factor"},
      {"w_x", "misalignment/cross-axis sensitivity"},
      {"w_o", "misalignment/cross-axis sensitivity"},
      {"y*w_i", "scale-factor nonlinearity"},
      {"y*T", "scale-factor temperature coefficient"},
      {"T", "bias temperature coefficient"},
      {"T[k-1]", "dynamics"},
      {"a_i", "g-sensitivity"},
      {"a_p", "g-sensitivity"},
      {"a_i*a_p", "g-sensitivity"},
      {"a_o[k-2]", "dynamics"},
      {"e[k-3]", "coloured noise"},
      {"w_i^2", "second-order nonlinearity"},
  };
  for (const auto& [term, name] : names) {
    EXPECT_STREQ(physical_name(parse_term(term), SensorKind::Gyroscope), name) << term;
  }
}

}  // namespace
}  // namespace inertia::ident

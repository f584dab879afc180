// The mounting rules of blocks 5-6 (procedure/mounting_rules.hpp) that the batch pipeline and the
// live solver both apply: IEEE 1293's exclusions, the order of the mountings, the bias handed on.
#include <gtest/gtest.h>

#include <vector>

#include "analyzer/ident/term.hpp"
#include "analyzer/ident/statistics.hpp"
#include "analyzer/procedure/mounting_rules.hpp"

namespace inertia::procedure {
namespace {

using dataset::CaseKind;

MountingKind kind_of(std::initializer_list<CaseKind> cases) {
  MountingKind k;
  for (const CaseKind c : cases) k.add_case(c);
  return k;
}

TEST(MountingRules, AMountingsKindIsWhatItsCasesAre) {
  const MountingKind table = kind_of({CaseKind::RotationTable, CaseKind::Static});
  EXPECT_TRUE(table.rotation_table);
  EXPECT_FALSE(table.shaker_only);
  const MountingKind shaker = kind_of({CaseKind::Shaker, CaseKind::Shaker});
  EXPECT_FALSE(shaker.rotation_table);
  EXPECT_TRUE(shaker.shaker_only);
  EXPECT_FALSE(kind_of({CaseKind::Shaker, CaseKind::Static}).shaker_only);
}

TEST(MountingRules, TheTableLosesTheCrossAxisSquaresTheShakerItsBiasOnlyWhenAnotherMountingSuppliesIt) {
  const Ieee1293Rules rules;
  const MountingKind table = kind_of({CaseKind::RotationTable});
  const MountingKind shaker = kind_of({CaseKind::Shaker});
  const MountingKind poses = kind_of({CaseKind::Static});
  const auto out = [&](const char* term, const MountingKind& k, bool supplied) {
    return ieee_1293_excluded(ident::parse_term(term), k, supplied, rules);
  };
  // 12.3.5.7: a_i^2 + a_p^2 + a_o^2 = g^2 on the table: the cross-axis squares go, a_i^2 stays.
  EXPECT_TRUE(out("a_p^2", table, false));
  EXPECT_TRUE(out("a_o^2", table, false));
  EXPECT_FALSE(out("a_i^2", table, false));
  EXPECT_FALSE(out("a_p*a_o", table, false));
  EXPECT_FALSE(out("1", table, true));
  // Only the plain squares: a filtered or lagged one is another column.
  EXPECT_FALSE(out("a_p", table, false));
  EXPECT_FALSE(out("a_p^2", shaker, false));
  EXPECT_FALSE(out("a_p^2", poses, false));
  // The shaker's bias: out when another mounting supplies it, kept (the rank decides) when none does.
  EXPECT_TRUE(out("1", shaker, true));
  EXPECT_FALSE(out("1", shaker, false));
  EXPECT_FALSE(out("a_i", shaker, true));
  EXPECT_FALSE(out("1", poses, true));
  // Each part can be turned off.
  EXPECT_FALSE(ieee_1293_excluded(ident::parse_term("a_p^2"), table, false, {.rotation_table = false, .shaker = true}));
  EXPECT_FALSE(ieee_1293_excluded(ident::parse_term("1"), shaker, true, {.rotation_table = true, .shaker = false}));
}

TEST(MountingRules, MountingsThatDetermineTheBiasGoFirstAndOnlyTheyHandItToTheShakerOnlyOnes) {
  const Ieee1293Rules rules;
  const std::vector<MountingKind> kinds{kind_of({CaseKind::Shaker}), kind_of({CaseKind::RotationTable}),
                                        kind_of({CaseKind::Shaker}), kind_of({CaseKind::Static, CaseKind::Thermal})};
  EXPECT_EQ(mounting_order(kinds), (std::vector<std::size_t>{1, 3, 0, 2}));
  EXPECT_TRUE(takes_bias(kinds[0], rules));
  EXPECT_FALSE(takes_bias(kinds[1], rules));
  EXPECT_FALSE(takes_bias(kinds[0], {.rotation_table = true, .shaker = false}));
  EXPECT_TRUE(hands_on_bias(kinds[1]));
  EXPECT_TRUE(hands_on_bias(kinds[3]));
  // A shaker-only mounting's own bias (a shaker-only plan) is never handed to another.
  EXPECT_FALSE(hands_on_bias(kinds[0]));
  EXPECT_TRUE(mounting_order({}).empty());
}

TEST(ClusterLevel, AColumnIsBetweenTheClustersWhenLessThanItsShareVariesWithinThem) {
  // Two clusters of 4 rows: (1,1,1,1) and (2,2,2,2) + d (d within-cluster variation).
  const auto share_of = [](double d) {
    const std::vector<double> x{1.0, 1.0, 1.0, 1.0, 2.0 + d, 2.0 - d, 2.0 + d, 2.0 - d};
    double energy = 0.0, s1 = 0.0, s2 = 0.0;
    for (std::size_t k = 0; k < x.size(); ++k) {
      energy += x[k] * x[k];
      (k < 4 ? s1 : s2) += x[k];
    }
    return std::pair{energy, s1 * s1 / 4.0 + s2 * s2 / 4.0};
  };
  // Within energy 4 d^2 of a total 20 + 4 d^2: below the share for d = 0.1 (0.2 %), above for d = 0.3 (1.8 %).
  const auto [e_small, b_small] = share_of(0.1);
  EXPECT_NEAR(e_small - b_small, 4 * 0.01, 1e-12);
  EXPECT_TRUE(ident::cluster_level(e_small, b_small));
  const auto [e_large, b_large] = share_of(0.3);
  EXPECT_FALSE(ident::cluster_level(e_large, b_large));
  EXPECT_FALSE(ident::cluster_level(0.0, 0.0)) << "a zero column is not a term of the clusters";
}

}  // namespace
}  // namespace inertia::procedure

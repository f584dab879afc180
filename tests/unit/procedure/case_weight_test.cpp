// Per-case batch weights (section 3.4): a weight reaches every piece of its case, and a weight for
// a case the dataset does not have is bad input instead of a silently unweighted fit.
#include <gtest/gtest.h>

#include <string>

#include "analyzer/procedure/pipeline.hpp"
#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

/// Cases by name; "NAME<PLAN" is a piece of the plan case PLAN (log_dataset's pieces).
dataset::Dataset cases(std::initializer_list<const char*> names) {
  dataset::Dataset d;
  for (const std::string n : names) {
    dataset::CaseData c;
    const auto at = n.find('<');
    c.name = n.substr(0, at);
    if (at != std::string::npos) c.piece_of = n.substr(at + 1);
    d.cases.push_back(c);
  }
  return d;
}

TEST(CaseWeight, AWeightReachesEveryPieceOfItsCaseAndNothingElse) {
  PipelineOptions o;
  o.case_weights = {{"shaker-ia", 4.0}};
  const dataset::Dataset d = cases({"shaker-ia<shaker-ia", "shaker-ia-seg2<shaker-ia", "shaker-ia-seg12<shaker-ia",
                                    "shaker-ia-seg3", "shaker-ia2", "shaker-pa"});
  EXPECT_EQ(case_weight(o, d.cases[0]), 4.0);
  EXPECT_EQ(case_weight(o, d.cases[1]), 4.0);
  EXPECT_EQ(case_weight(o, d.cases[2]), 4.0);
  // By what the dataset says, not by the name: a case of its own whose name looks like a piece's.
  EXPECT_EQ(case_weight(o, d.cases[3]), 1.0);
  EXPECT_EQ(case_weight(o, d.cases[4]), 1.0);
  EXPECT_EQ(case_weight(o, d.cases[5]), 1.0);
  EXPECT_NO_THROW(check_case_weights(cases({"rotation-table", "shaker-ia-seg2<shaker-ia"}), o));
}

TEST(CaseWeight, AWeightForACaseTheDatasetLacksIsBadInputNamingIt) {
  PipelineOptions o;
  o.case_weights = {{"shaker-ai", 2.0}};
  try {
    check_case_weights(cases({"shaker-ia", "shaker-pa"}), o);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("--weight shaker-ai=2"), std::string::npos) << what;
    EXPECT_NE(what.find("shaker-ia, shaker-pa"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace inertia::procedure

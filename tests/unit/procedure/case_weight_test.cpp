// Per-case batch weights (section 3.4): a weight reaches every piece of its case, and a weight for
// a case the dataset does not have is bad input instead of a silently unweighted fit.
#include <gtest/gtest.h>

#include <string>

#include "analyzer/procedure/pipeline.hpp"
#include "common/input_error.hpp"

namespace inertia::procedure {
namespace {

dataset::Dataset cases(std::initializer_list<const char*> names) {
  dataset::Dataset d;
  for (const char* n : names) {
    dataset::CaseData c;
    c.name = n;
    d.cases.push_back(c);
  }
  return d;
}

TEST(CaseWeight, AWeightReachesEveryPieceOfItsCaseAndNothingElse) {
  PipelineOptions o;
  o.case_weights = {{"shaker-ia", 4.0}};
  EXPECT_EQ(case_weight(o, "shaker-ia"), 4.0);
  EXPECT_EQ(case_weight(o, "shaker-ia-seg2"), 4.0);
  EXPECT_EQ(case_weight(o, "shaker-ia-seg12"), 4.0);
  EXPECT_EQ(case_weight(o, "shaker-ia-segment"), 1.0);
  EXPECT_EQ(case_weight(o, "shaker-ia2"), 1.0);
  EXPECT_EQ(case_weight(o, "shaker-pa"), 1.0);
  EXPECT_NO_THROW(check_case_weights(cases({"rotation-table", "shaker-ia-seg2"}), o));
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

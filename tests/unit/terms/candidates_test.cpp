// Candidate sets of the paper's eqs. 1-6 (analyzer/ident/candidates.hpp), counted by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "common/input_error.hpp"

namespace inertia::ident {
namespace {

using dataset::SensorKind;

std::size_t distinct(const std::vector<Term>& terms) {
  const std::vector<std::string> names = to_strings(terms);
  return std::set<std::string>(names.begin(), names.end()).size();
}

std::size_t count(SensorKind s, ModelFrame f, CandidateOptions o) { return candidate_terms(s, f, o).size(); }

TEST(Candidates, StaticAccelerometerSetsAreEquationsOneAndThree) {
  // Eq. 1 lists 12 inputs and eq. 3 lists 10; the bias K_b is one more.
  const std::vector<std::string> eq1 = {"1",     "a_x",     "a_y",     "a_z",     "a_i^2",     "a_p^2",    "a_o^2",
                                        "a_i*a_p", "a_i*a_o", "a_p*a_o", "sign(a_i)", "abs(a_i)", "a_i*abs(a_i)"};
  const std::vector<std::string> eq3 = {"1",       "a_i",     "a_i^2",   "a_p^2",     "a_o^2",    "a_i*a_p",
                                        "a_i*a_o", "a_p*a_o", "sign(a_i)", "abs(a_i)", "a_i*abs(a_i)"};
  EXPECT_EQ(to_strings(candidate_terms(SensorKind::Accelerometer, ModelFrame::ExternalAndSensor, {})), eq1);
  EXPECT_EQ(to_strings(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, {})), eq3);
}

TEST(Candidates, AccelerometerCountsForOrdersZeroOneTwo) {
  for (int r : {0, 1, 2}) {
    CandidateOptions o;
    o.r = r;
    // bias + 12 (eq. 1) or 10 (eq. 3) inputs at each lag 0..r + r output lags.
    const std::size_t es = 1 + 12 * (r + 1) + r;
    const std::size_t s = 1 + 10 * (r + 1) + r;
    EXPECT_EQ(count(SensorKind::Accelerometer, ModelFrame::ExternalAndSensor, o), es) << "r = " << r;
    EXPECT_EQ(count(SensorKind::Accelerometer, ModelFrame::Sensor, o), s) << "r = " << r;
    EXPECT_EQ(distinct(candidate_terms(SensorKind::Accelerometer, ModelFrame::ExternalAndSensor, o)), es);
    o.include_noise_terms = true;                      // + c_1 v(k-1) .. c_r v(k-r)
    o.include_temperature = true;                      // + T, a_i*T
    EXPECT_EQ(count(SensorKind::Accelerometer, ModelFrame::Sensor, o), s + r + 2) << "r = " << r;
    o.include_sign_abs = false;                        // - 3 inputs at every lag
    EXPECT_EQ(count(SensorKind::Accelerometer, ModelFrame::Sensor, o), s + r + 2 - 3 * (r + 1)) << "r = " << r;
    o.include_bias = false;
    o.include_output_lags = false;
    EXPECT_EQ(count(SensorKind::Accelerometer, ModelFrame::Sensor, o), s + r + 2 - 3 * (r + 1) - 1 - r) << "r = " << r;
  }
  // Order-2 specifics: the lagged inputs and the ARX/MA lags are spelled as the grammar wants.
  CandidateOptions o;
  o.r = 2;
  o.include_noise_terms = true;
  const std::vector<std::string> t = to_strings(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, o));
  for (const char* name : {"a_i[k-2]", "a_o^2[k-1]", "a_i[k-2]*abs(a_i[k-2])", "sign(a_i[k-1])", "y[k-1]", "y[k-2]",
                           "e[k-1]", "e[k-2]"}) {
    EXPECT_NE(std::find(t.begin(), t.end(), name), t.end()) << name;
  }
  EXPECT_EQ(t.back(), "e[k-2]");
}

TEST(Candidates, GyroCountsForEquationsFiveAndSix) {
  for (int r : {0, 1, 2}) {
    CandidateOptions o;
    o.r = r;
    // D_F + (w_x w_y w_z | w_i) + y*w_i + a_i a_p a_o at lags 0..r + y lags 1..r
    const std::size_t eq5 = 1 + 3 + 1 + 3 * (r + 1) + r;
    const std::size_t eq6 = 1 + 1 + 1 + 3 * (r + 1) + r;
    EXPECT_EQ(count(SensorKind::Gyroscope, ModelFrame::ExternalAndSensor, o), eq5) << "r = " << r;
    EXPECT_EQ(count(SensorKind::Gyroscope, ModelFrame::Sensor, o), eq6) << "r = " << r;
    o.include_temperature = true;   // + T, T[k-1], y*T
    o.include_noise_terms = true;   // + e lags
    EXPECT_EQ(count(SensorKind::Gyroscope, ModelFrame::Sensor, o), eq6 + 3 + r) << "r = " << r;
  }
  CandidateOptions o;
  o.include_temperature = true;
  const std::vector<std::string> t = to_strings(candidate_terms(SensorKind::Gyroscope, ModelFrame::ExternalAndSensor, o));
  EXPECT_EQ(t, (std::vector<std::string>{"1", "w_x", "w_y", "w_z", "y*w_i", "a_i", "a_p", "a_o", "T", "T[k-1]", "y*T"}));
}

TEST(Candidates, ExcludeByAnySpellingAndRefuseUnknownExclusions) {
  CandidateOptions o;
  o.exclude = {"abs(a_i)", "a_p*a_i"};
  const std::vector<std::string> t = to_strings(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, o));
  EXPECT_EQ(t.size(), 9u);
  EXPECT_EQ(std::find(t.begin(), t.end(), "a_i*a_p"), t.end());
  EXPECT_EQ(std::find(t.begin(), t.end(), "abs(a_i)"), t.end());
  o.exclude = {"a_i^3"};
  EXPECT_THROW(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, o), InputError);
  o.exclude = {"a_q"};
  EXPECT_THROW(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, o), InputError);
  o.exclude.clear();
  o.r = -1;
  std::string why;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("r = -1"), std::string::npos);
  EXPECT_THROW(candidate_terms(SensorKind::Accelerometer, ModelFrame::Sensor, o), InputError);
}

TEST(Candidates, SensorFrameCounterpartOfTheExternalSetIsTheSensorSet) {
  // Algorithm 2 step 7: eq. 2 -> eq. 4 and eq. 5 -> eq. 6, for every order and option.
  for (int r : {0, 1, 2}) {
    for (bool noise : {false, true}) {
      CandidateOptions o;
      o.r = r;
      o.include_noise_terms = noise;
      o.include_temperature = noise;
      for (SensorKind s : {SensorKind::Accelerometer, SensorKind::Gyroscope}) {
        EXPECT_EQ(to_strings(to_sensor_frame(candidate_terms(s, ModelFrame::ExternalAndSensor, o))),
                  to_strings(candidate_terms(s, ModelFrame::Sensor, o)))
            << "r = " << r;
      }
    }
  }
  // A selected subset: a_x and a_z collapse into a_i at the first one's place; lags are kept.
  EXPECT_EQ(to_strings(to_sensor_frame(parse_terms({"a_z", "1", "a_x", "a_y[k-1]", "a_x*T", "a_p^2"}))),
            (std::vector<std::string>{"a_i", "1", "a_i[k-1]", "a_i*T", "a_p^2"}));
}

}  // namespace
}  // namespace inertia::ident

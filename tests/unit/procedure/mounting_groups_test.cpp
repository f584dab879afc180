// Which cases share a mounting: procedure::group_mountings, the batch's and the live estimator's one rule.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "analyzer/procedure/pipeline.hpp"

namespace inertia::procedure {
namespace {

// procedure::group_mountings: the batch's and the live estimator's one rule for which cases share
// a mounting.
TEST(GroupMountings, LabelsShareUnlabelledStandAloneTumblesAndGyroscopesAreInferred) {
  using K = MountingKey;
  const auto labels = [](const MountingGroups& g) {
    std::vector<std::string> out;
    for (const auto& [label, members] : g) out.push_back(label);
    return out;
  };
  std::vector<std::string> notes;
  // The paper's bench: a table case alone, three shaker orientations on one fixture.
  const std::vector<K> paper = {{"table", "", CaseKind::RotationTable},
                                {"ia", "fixture", CaseKind::Shaker},
                                {"pa", "fixture", CaseKind::Shaker},
                                {"oa", "fixture", CaseKind::Shaker}};
  const MountingGroups g = group_mountings(paper, dataset::SensorKind::Accelerometer, &notes);
  EXPECT_EQ(labels(g), (std::vector<std::string>{"table", "fixture"}));
  EXPECT_EQ(g[1].second, (std::vector<std::size_t>{1, 2, 3}));
  EXPECT_TRUE(notes.empty());
  // A tumble without labels: its poses share "poses", first, and the note says it was inferred.
  const std::vector<K> tumble = {{"table", "", CaseKind::RotationTable}, {"up", "", CaseKind::Static},
                                 {"down", "", CaseKind::Static}, {"hot", "", CaseKind::Thermal}};
  const MountingGroups t = group_mountings(tumble, dataset::SensorKind::Accelerometer, &notes);
  EXPECT_EQ(labels(t), (std::vector<std::string>{"poses", "table"}));
  EXPECT_EQ(t[0].second, (std::vector<std::size_t>{1, 2, 3}));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("inferred: the 3 static poses (up, down, hot)"), std::string::npos) << notes[0];
  // One label anywhere: the file says how the sensor was mounted, nothing is inferred.
  std::vector<K> labelled = tumble;
  labelled[1].label = "cube";
  EXPECT_EQ(labels(group_mountings(labelled, dataset::SensorKind::Accelerometer)),
            (std::vector<std::string>{"table", "cube", "down", "hot"}));
  // A gyroscope: one M_C^S from the rates of every case (paper section 2.2), said when it overrides.
  notes.clear();
  const MountingGroups gyro = group_mountings(paper, dataset::SensorKind::Gyroscope, &notes);
  EXPECT_EQ(labels(gyro), (std::vector<std::string>{"all cases"}));
  EXPECT_EQ(gyro[0].second, (std::vector<std::size_t>{0, 1, 2, 3}));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("mounting labels are not used"), std::string::npos);
}

}  // namespace
}  // namespace inertia::procedure

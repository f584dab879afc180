#include "hal/sim/orientation.hpp"

namespace inertia::sim {

MountingTruth mounting_truth(const config::TestCase& test_case, const config::SensorUnderTest& sensor) {
  MountingTruth m;
  m.nominal_m_ec = test_case.m_ec;
  m.fixture = test_case.fixture_misalignment.dcm();
  m.case_rotation = sensor.case_misalignment.dcm() * test_case.case_misalignment.dcm();
  m.true_m_ec = m.case_rotation * m.nominal_m_ec * m.fixture;
  return m;
}

}  // namespace inertia::sim

#include "hal/sim/orientation.hpp"

#include "hal/sim/random_streams.hpp"

namespace inertia::sim {

MountingTruth mounting_truth(const config::TestCase& test_case, const config::SensorUnderTest& sensor,
                             std::uint64_t placement_seed) {
  MountingTruth m;
  m.nominal_m_ec = config::nominal_m_ec(test_case, sensor);
  m.fixture = test_case.fixture_misalignment.dcm();
  if (test_case.placement_error_rad > 0.0) {
    RandomSource draws(placement_seed);
    Eigen::Vector3d v;
    for (int a = 0; a < 3; ++a) v(a) = test_case.placement_error_rad * draws.normal();
    m.fixture = m.fixture * frames::frame_rotation(v, v.norm());
  }
  // The case's misalignment is the housing's, in the case's (for a unit's member, the unit's)
  // coordinates; the member's own fit in the housing is in its turned case coordinates.
  const frames::Dcm turn = config::unit_axis_frame(sensor.unit_axis);
  m.case_rotation = sensor.case_misalignment.dcm() * turn * test_case.case_misalignment.dcm() * turn.transpose();
  m.true_m_ec = m.case_rotation * m.nominal_m_ec * m.fixture;
  return m;
}

}  // namespace inertia::sim

#pragma once
// The orientation chain of a sensor under test in one test case (paper sections 2.1, 2.3, 3.1):
//
//   F_E --R_F--> F_F (true fixture) --M_nom--> F_Cn (nominal case) --R_C--> F_C --M_C^S--> F_S
//
//   M_true_E^C = R_C * M_nom * R_F,     a_C = M_true_E^C a_E,     M_E^S = M_C^S M_true_E^C
//
// - R_F, fixture misalignment ([[case]] fixture_misalignment): the fixture as mounted on the
//   table/shaker is F_E rotated (right-hand rule) by angle about `axis`, the axis written in F_E.
//   The fixture is remounted for each shaker orientation, so R_F belongs to the case.
// - M_nom, nominal M_E^C: the Fig. 2 slot orientation (config::slot_orientation) or m_ec, turned
//   to the sensor's axis for a unit's member (config::nominal_m_ec); this is what the dataset's
//   m_ec column records (the analyzer knows only the nominal).
// - R_C, case misalignment: the true case frame is the nominal case frame rotated by angle about
//   `axis`, the axis written in nominal case coordinates (the paper's "2 deg about case Y").
//   R_C = R_slot * R_case: [[case]] case_misalignment (this mounting) first, then the sensor's
//   own [[sensor]] case_misalignment (its fit in the slot, or in a unit's housing: the unit's
//   non-orthogonality), both frame rotations. For a unit's member R_case is the housing's,
//   written in unit coordinates, so it enters as T R_case T' with T = unit_axis_frame.
// - R_P, placement error ([[case]] placement_error_deg): a random rotation of this case's
//   placement (rotation vector with independent N(0, sd^2) components in F_E, drawn from the
//   placement seed), composed with R_F: a tumble's pose is never exactly its nominal one.
// - M_C^S, sensor misalignment alpha_p, alpha_o: inside the truth model (m_cs()).
// Every R is frames::frame_rotation(axis, angle), i.e. a DCM from the unrotated to the rotated frame.
#include "common/config/bench_config.hpp"
#include "common/frames.hpp"

#include <cstdint>

namespace inertia::sim {

struct MountingTruth {
  frames::Dcm nominal_m_ec;   // M_nom
  frames::Dcm fixture;        // R_F R_P (placement error included)
  frames::Dcm case_rotation;  // R_C
  frames::Dcm true_m_ec;      // R_C M_nom R_F
};

/// `placement_seed` draws the case's placement error (unused when it is zero).
MountingTruth mounting_truth(const config::TestCase& test_case, const config::SensorUnderTest& sensor,
                             std::uint64_t placement_seed = 0);

}  // namespace inertia::sim

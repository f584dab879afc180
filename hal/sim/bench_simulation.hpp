#pragma once
// The whole simulated bench: for every case of the test plan, the bench motion, the reference
// instruments and every sensor under test through its orientation chain and truth model.
// Deterministic: every draw comes from the bench seed or a sensor's seed (random_streams.hpp).
#include <variant>
#include <vector>

#include "common/config/bench_config.hpp"
#include "hal/sim/bench_motion.hpp"
#include "hal/sim/orientation.hpp"
#include "hal/sim/references.hpp"
#include "hal/sim/sensors/accelerometer_model.hpp"
#include "hal/sim/sensors/fog_model.hpp"

namespace inertia::sim {

using SensorParams = std::variant<AccelerometerParams, FogParams>;

/// Truth parameters of every sensor under test, validated (InputError at the offending entry).
std::vector<SensorParams> sensor_params(const config::BenchConfig& bench);

struct SensorCase {
  MountingTruth mounting;
  frames::Dcm m_cs;           // M_C^S of the truth model
  Columns3 f_e;               // specific force at the sensor's position, F_E, m/s^2; empty when
                              // the sensor sits at the fixture origin (then it is the case's f_e)
  Eigen::VectorXd y;          // sensor output, output unit

  /// The reference specific force this sensor saw.
  [[nodiscard]] const Columns3& reference(const CaseMotion& motion) const {
    return f_e.size() > 0 ? f_e : motion.f_e;
  }
};

struct SimulatedCase {
  CaseMotion motion;
  CaseReferences references;
  std::vector<SensorCase> sensors;   // one per [[sensor]]
};

struct BenchSimulation {
  std::vector<SensorParams> params;  // one per [[sensor]]
  std::vector<SimulatedCase> cases;  // one per [[case]]
};

/// Runs the sensor under test `sensor_index` through case `case_index` (fresh model state and a
/// per-case noise stream derived from the sensor's seed). Not real-time.
SensorCase simulate_sensor(const config::BenchConfig& bench, const SensorParams& params,
                           std::size_t sensor_index, std::size_t case_index, const CaseMotion& motion);

BenchSimulation simulate_bench(const config::BenchConfig& bench);

}  // namespace inertia::sim

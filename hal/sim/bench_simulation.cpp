#include "hal/sim/bench_simulation.hpp"

#include <stdexcept>

#include "common/input_error.hpp"
#include "hal/sim/random_streams.hpp"
#include "hal/sim/sensor_truth.hpp"

namespace inertia::sim {

std::vector<SensorParams> sensor_params(const config::BenchConfig& bench) {
  std::vector<SensorParams> out;
  for (const config::SensorUnderTest& s : bench.sensors) {
    // The truth models check ranges that depend on the sample rate (high-pass corners, Nyquist,
    // stable denominators); building one here turns their complaint into a positioned InputError.
    try {
      if (s.type == config::SensorType::Accelerometer) {
        out.emplace_back(accelerometer_params(s));
        AccelerometerModel probe(std::get<AccelerometerParams>(out.back()), bench.sample_rate_hz, 0);
      } else {
        out.emplace_back(fog_params(s));
        FogModel probe(std::get<FogParams>(out.back()), bench.sample_rate_hz, 0);
      }
    } catch (const std::invalid_argument& e) {
      throw InputError(s.where, "sensor '" + s.name + "' truth: " + e.what());
    }
  }
  return out;
}

SensorCase simulate_sensor(const config::BenchConfig& bench, const SensorParams& params,
                           std::size_t sensor_index, std::size_t case_index, const CaseMotion& motion) {
  const config::SensorUnderTest& sensor = bench.sensors.at(sensor_index);
  const config::TestCase& tc = bench.cases.at(case_index);
  SensorCase out;
  // The placement is the case's, the same for every sensor on the fixture.
  out.mounting = mounting_truth(tc, sensor, derive_seed(bench.seed, {static_cast<std::uint64_t>(Stream::Placement), case_index}));
  const frames::Dcm m_ec = out.mounting.true_m_ec;
  const auto n = static_cast<Eigen::Index>(motion.size());
  const bool lever_arm = !sensor.position_m.isZero();
  if (lever_arm) {
    out.f_e.resize(n, 3);
    for (Eigen::Index k = 0; k < n; ++k) {
      out.f_e.row(k) = specific_force_at(motion.f_e.row(k).transpose(), motion.w_e.row(k).transpose(),
                                         motion.dw_e.row(k).transpose(), sensor.position_m)
                           .transpose();
    }
  }
  // No copy for a sensor at the origin: at 10 kHz the arrays are tens of MB per case.
  const Columns3& f_e = out.reference(motion);
  out.y.resize(n);
  const std::uint64_t seed =
      derive_seed(sensor.seed, {static_cast<std::uint64_t>(Stream::Sensor), case_index});
  const double fs = bench.sample_rate_hz;
  // The sensor's temperature is the fixture's (it sits in the temperature-controlled fixture).
  if (const auto* acc = std::get_if<AccelerometerParams>(&params)) {
    AccelerometerModel model(*acc, fs, seed);
    out.m_cs = model.m_cs();
    for (Eigen::Index k = 0; k < n; ++k) {
      const Eigen::Vector3d a_c = m_ec * f_e.row(k).transpose();
      out.y[k] = model.step(a_c, motion.temp_c[k] - bench.t_ref_c);
    }
  } else {
    FogModel model(std::get<FogParams>(params), fs, seed);
    out.m_cs = model.m_cs();
    for (Eigen::Index k = 0; k < n; ++k) {
      const Eigen::Vector3d a_c = m_ec * f_e.row(k).transpose();
      const Eigen::Vector3d w_c = m_ec * motion.w_e.row(k).transpose();
      out.y[k] = model.step(w_c, a_c, motion.temp_c[k] - bench.t_ref_c);
    }
  }
  return out;
}

BenchSimulation simulate_bench(const config::BenchConfig& bench) {
  BenchSimulation sim;
  sim.params = sensor_params(bench);
  ThermalModel thermal(bench.thermal, bench.sample_rate_hz);
  for (std::size_t c = 0; c < bench.cases.size(); ++c) {
    SimulatedCase sc;
    sc.motion = simulate_motion(bench, c, thermal);
    sc.references = simulate_references(bench, c, sc.motion);
    for (std::size_t s = 0; s < bench.sensors.size(); ++s) {
      sc.sensors.push_back(simulate_sensor(bench, sim.params[s], s, c, sc.motion));
    }
    sim.cases.push_back(std::move(sc));
  }
  return sim;
}

}  // namespace inertia::sim

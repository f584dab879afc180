#include "common/dataset/bench_dataset.hpp"

namespace inertia::dataset {

Dataset bench_sensor_dataset(const config::BenchConfig& bench, std::size_t sensor_index) {
  const config::SensorUnderTest& sensor = bench.sensors.at(sensor_index);
  Dataset ds;
  ds.sensor = sensor.type == config::SensorType::Accelerometer ? SensorKind::Accelerometer : SensorKind::Gyroscope;
  ds.sensor_name = sensor.name;
  ds.serial = sensor.serial;
  ds.part = sensor.part;
  ds.unit = sensor.unit;
  ds.unit_axis = sensor.unit_axis;
  ds.output_unit = sensor.output_unit;
  ds.t_ref = bench.t_ref_c;
  return ds;
}

}  // namespace inertia::dataset

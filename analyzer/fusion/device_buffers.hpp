#pragma once
// The stream assembler's per-device sample buffers (stream_assembler.hpp): which device channels
// the fusion of the sensor under test needs (its output, the monitors, the encoders), each
// device's blocks of those channels from the oldest row not yet final on, the fixture
// temperature's readings, and reading any of them at a row's time: the device's own sample where
// it shares the output's sample instants, a 4-point Lagrange interpolation where its clock
// differs. Also where the output device's next row is, and when a device that stays behind is no
// longer waited for (max_wait_s).
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "analyzer/fusion/channel_ref.hpp"
#include "analyzer/fusion/stream_assembler.hpp"
#include "common/config/bench_config.hpp"
#include "inertia/sample_block_t.hpp"

namespace inertia::fusion {

// What a needed channel is to the fusion of the sensor under test.
enum class ChannelRole { Output, Monitor, LinearEncoder, TableEncoder };

struct ChannelNeed {
  ChannelRole role;
  std::size_t index = 0;   // monitor index
  ChannelRef ref;
};

// One stored block of a device: the needed channels only.
struct StoredBlock {
  std::int64_t seq0 = 0;                        // the device's sample counter at sample 0
  std::int32_t n = 0;
  double t0_ns = 0.0;
  double period_ns = 0.0;
  std::vector<std::vector<double>> values;      // per device-need slot
  std::vector<std::vector<std::uint8_t>> valid;
  [[nodiscard]] double time(std::int64_t s) const { return t0_ns + static_cast<double>(s) * period_ns; }
  [[nodiscard]] double last_ns() const { return time(n - 1); }
};

struct DeviceState {
  std::vector<std::size_t> needs;               // indices into DeviceBuffers::needs
  std::vector<std::int32_t> columns;            // block column of each need, -1 until seen
  std::deque<StoredBlock> blocks;               // in arrival order (ascending time)
  std::optional<std::int64_t> next_seq;         // channel_seq the next block should start at
  double next_ns = std::numeric_limits<double>::quiet_NaN();   // time it should start at
  double newest_ns = -std::numeric_limits<double>::infinity();  // newest sample received
};

struct TemperatureSample {
  double t_ns;
  double value;
};

// Values and validity of one need at one row time.
enum class ReadResult { Ok, Invalid, Missing, NotYet };

struct DeviceBuffers {
  explicit DeviceBuffers(double max_wait_s) : max_wait_s(max_wait_s) {}

  double max_wait_s;                      // AssemblerOptions::max_wait_s
  std::vector<ChannelNeed> needs;         // [0]: the sensor's output
  std::map<std::string, DeviceState> devices;
  std::string output_device;
  std::size_t output_slot = 0;            // the output need's slot in its device
  double nominal_period_ns = 0.0;         // of the bench's sample rate: the output's before its first block
  ChannelRef temp_ref;
  std::vector<TemperatureSample> temps;
  double temp_newest_ns = -std::numeric_limits<double>::infinity();
  bool finishing = false;                 // the stream has ended: nothing more is waited for

  // The output device's next row: block (front of its deque after release) and sample.
  std::size_t cursor_block = 0;
  std::int32_t cursor_sample = 0;

  /// The channels sensor `s` of bench `b` needs, by device.
  void configure(const config::BenchConfig& b, const config::SensorUnderTest& s);
  /// Forgets the configuration (a bench that could not be configured).
  void clear();

  /// Stores the needed channels of a block (and the fixture temperature it carries); a jump of
  /// its device's channel_seq or time is appended to `gaps`. False when the block holds no
  /// samples or no needed device. InputError for a malformed block or a missing channel.
  bool store(const sample_block_t& block, const std::string& where, std::vector<StreamGap>& gaps);

  [[nodiscard]] double output_period_ns() const;
  [[nodiscard]] double output_newest_ns() const;
  /// Past max_wait: a device (or the markers) this far behind the output is not waited for.
  [[nodiscard]] bool given_up(double t_ns) const;
  /// The need's value at time t (ns): the device's sample at that instant, or a 4-point Lagrange
  /// interpolation between its samples around it.
  ReadResult read(std::size_t need, double t, double& value) const;
  /// The last controller reading at or before t (the first one for rows before it); needs one.
  [[nodiscard]] double held_temperature(double t) const;

  /// Drops the output blocks before the cursor, and of the other devices and the temperature
  /// what no row from the cursor on reads.
  void release();

 private:
  void on_temperature(const sample_block_t& block);
};

}  // namespace inertia::fusion

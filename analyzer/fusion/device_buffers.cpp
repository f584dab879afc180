// The stream assembler's per-device sample buffers (device_buffers.hpp): storing the needed
// channels of each block, noting the gaps between a device's blocks, and reading a channel at a
// row's time.
#include "analyzer/fusion/device_buffers.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/input_error.hpp"
#include "common/lcm/sample_block_layout.hpp"

namespace inertia::fusion {

namespace {

// Largest sample index read() converts to an integer: block_shape_error keeps channel_seq below
// 2^62 as well, so seq0 + index stays within int64.
constexpr double kMaxSampleIndex = 0x1p62;

/// Sample `seq` of device `d` (by its sample counter): its block and position, or none.
const StoredBlock* find_sample(const DeviceState& d, std::int64_t seq, std::int32_t& s) {
  for (auto it = d.blocks.rbegin(); it != d.blocks.rend(); ++it) {
    if (seq >= it->seq0 && seq < it->seq0 + it->n) {
      s = static_cast<std::int32_t>(seq - it->seq0);
      return &*it;
    }
    if (it->seq0 + it->n <= seq) break;
  }
  return nullptr;
}

}  // namespace

void DeviceBuffers::configure(const config::BenchConfig& b, const config::SensorUnderTest& s) {
  needs.push_back({ChannelRole::Output, 0, channel_of(s.channel, "accel", s.name)});
  for (std::size_t i = 0; i < b.monitors.size(); ++i)
    needs.push_back({ChannelRole::Monitor, i, channel_of(b.monitors[i].channel, "accel", b.monitors[i].name)});
  if (b.linear_encoder.present)
    needs.push_back({ChannelRole::LinearEncoder, 0, channel_of(b.linear_encoder.channel, "linear_encoder", "position")});
  if (b.table_encoder.present)
    needs.push_back({ChannelRole::TableEncoder, 0, channel_of(b.table_encoder.channel, "table_encoder", "position")});
  for (std::size_t i = 0; i < needs.size(); ++i) {
    DeviceState& d = devices[needs[i].ref.device];
    d.needs.push_back(i);
    d.columns.push_back(-1);
  }
  output_device = needs[0].ref.device;
  const DeviceState& od = devices[output_device];
  output_slot = static_cast<std::size_t>(std::find(od.needs.begin(), od.needs.end(), 0) - od.needs.begin());
  nominal_period_ns = 1e9 / b.sample_rate_hz;
  temp_ref = channel_of(b.thermal.channel, "controller", "temperature");
}

void DeviceBuffers::clear() {
  needs.clear();
  devices.clear();
}

bool DeviceBuffers::store(const sample_block_t& block, const std::string& where, std::vector<StreamGap>& gaps) {
  if (const std::string why = block_shape_error(block); !why.empty())
    throw InputError(fmt::format("{}: device {}: malformed sample block ({})", where, block.device, why));
  if (block.num_samples == 0) return false;
  if (block.device == temp_ref.device) on_temperature(block);
  const auto it = devices.find(block.device);
  if (it == devices.end()) return false;
  DeviceState& d = it->second;
  std::vector<std::int32_t> columns(d.needs.size(), -1);
  for (std::size_t k = 0; k < d.needs.size(); ++k) {
    const std::string& signal = needs[d.needs[k]].ref.signal;
    for (std::int32_t c = 0; c < block.num_channels; ++c)
      if (block.channel_names[static_cast<std::size_t>(c)] == signal) columns[k] = c;
    if (columns[k] < 0)
      throw InputError(where + ": device " + block.device + " has no channel '" + signal + "' (needed as " +
                       needs[d.needs[k]].ref.label() + ")");
  }
  const double period_ns = 1e9 * block.sample_period_s;
  const double t0 = static_cast<double>(block.t0_mono_ns);
  const std::int64_t seq = block.num_channels > 0 ? block.channel_seq[0] : 0;
  if (!std::isnan(d.next_ns)) {
    if (t0 < d.next_ns - 0.5 * period_ns)
      throw InputError(fmt::format("{}: device {} block starts {:.1f} us before the end of its previous block: blocks "
                                   "out of order or overlapping",
                                   where, block.device, (d.next_ns - t0) * 1e-3));
    const double missing = (t0 - d.next_ns) / period_ns;
    if (missing > 0.5 || seq != *d.next_seq)
      gaps.push_back({block.device, where, std::llround(missing), std::max<std::int64_t>(0, seq - *d.next_seq)});
  }
  d.columns = columns;
  d.next_ns = t0 + static_cast<double>(block.num_samples) * period_ns;
  d.next_seq = seq + block.num_samples;
  StoredBlock sb;
  sb.seq0 = seq;
  sb.n = block.num_samples;
  sb.t0_ns = t0;
  sb.period_ns = period_ns;
  for (std::size_t k = 0; k < d.needs.size(); ++k) {
    const auto c = static_cast<std::size_t>(d.columns[k]);
    const auto& v = block.values[c];
    sb.values.emplace_back(v.begin(), v.begin() + block.num_samples);
    std::vector<std::uint8_t> ok(static_cast<std::size_t>(block.num_samples));
    for (std::int32_t s = 0; s < block.num_samples; ++s)
      ok[static_cast<std::size_t>(s)] =
          sample_valid(block, d.columns[k], s) && std::isfinite(v[static_cast<std::size_t>(s)]);
    sb.valid.push_back(std::move(ok));
  }
  d.newest_ns = std::max(d.newest_ns, sb.last_ns());
  d.blocks.push_back(std::move(sb));
  return true;
}

void DeviceBuffers::on_temperature(const sample_block_t& block) {
  for (std::int32_t c = 0; c < block.num_channels; ++c) {
    if (block.channel_names[static_cast<std::size_t>(c)] != temp_ref.signal) continue;
    for (std::int32_t s = 0; s < block.num_samples; ++s) {
      const double v = block.values[static_cast<std::size_t>(c)][static_cast<std::size_t>(s)];
      const double t = static_cast<double>(block.t0_mono_ns) + block.sample_period_s * 1e9 * s;
      temp_newest_ns = std::max(temp_newest_ns, t);
      if (!sample_valid(block, c, s) || !std::isfinite(v)) continue;
      if (!temps.empty() && t < temps.back().t_ns) continue;   // out of order: keep the timeline monotonic
      temps.push_back({t, v});
    }
  }
}

double DeviceBuffers::output_period_ns() const {
  const auto it = devices.find(output_device);
  if (it != devices.end() && !it->second.blocks.empty()) return it->second.blocks.front().period_ns;
  return nominal_period_ns;
}

double DeviceBuffers::output_newest_ns() const {
  const auto it = devices.find(output_device);
  return it == devices.end() ? -std::numeric_limits<double>::infinity() : it->second.newest_ns;
}

bool DeviceBuffers::given_up(double t_ns) const {
  return finishing || output_newest_ns() - t_ns > max_wait_s * 1e9;
}

ReadResult DeviceBuffers::read(std::size_t need, double t, double& value) const {
  const DeviceState& d = devices.at(needs[need].ref.device);
  std::size_t slot = 0;
  while (d.needs[slot] != need) ++slot;
  // The block whose span holds t (or the last one starting before it).
  const StoredBlock* b = nullptr;
  for (auto it = d.blocks.rbegin(); it != d.blocks.rend(); ++it) {
    if (it->t0_ns <= t + 0.5 * it->period_ns) {
      b = &*it;
      break;
    }
  }
  if (b == nullptr) return d.newest_ns < t && !given_up(t) ? ReadResult::NotYet : ReadResult::Missing;
  const double x = (t - b->t0_ns) / b->period_ns;
  // A sample index that no int64 holds (a period of 1e-300 s: the cast below would be undefined;
  // found by fuzz_event_log) lies past every stored sample: as when the next block did not follow on.
  if (!(x < kMaxSampleIndex)) return d.newest_ns < t && !given_up(t) ? ReadResult::NotYet : ReadResult::Missing;
  const double nearest = std::round(x);
  if (std::abs(x - nearest) <= 1e-3) {
    // The device samples at this instant (one clock, as on the simulated benches).
    const auto s = static_cast<std::int64_t>(nearest);
    if (s < b->n) {
      value = b->values[slot][static_cast<std::size_t>(s)];
      return b->valid[slot][static_cast<std::size_t>(s)] ? ReadResult::Ok : ReadResult::Invalid;
    }
    if (d.newest_ns < t && !given_up(t)) return ReadResult::NotYet;
    return ReadResult::Missing;   // past the block, and the next one did not follow on
  }
  // Another clock: Lagrange through the samples at floor(x) - 1 .. floor(x) + 2.
  const std::int64_t base = b->seq0 + static_cast<std::int64_t>(std::floor(x)) - 1;
  const double u = x - std::floor(x) + 1.0;   // position in the 4-point stencil, in (1, 2)
  double sum = 0.0;
  for (int j = 0; j < 4; ++j) {
    std::int32_t s = 0;
    const StoredBlock* sb = find_sample(d, base + j, s);
    if (sb == nullptr) return d.next_seq && base + j >= *d.next_seq && !given_up(t) ? ReadResult::NotYet : ReadResult::Missing;
    if (!sb->valid[slot][static_cast<std::size_t>(s)]) return ReadResult::Invalid;
    double w = 1.0;
    for (int m = 0; m < 4; ++m)
      if (m != j) w *= (u - m) / static_cast<double>(j - m);
    sum += w * sb->values[slot][static_cast<std::size_t>(s)];
  }
  value = sum;
  return ReadResult::Ok;
}

double DeviceBuffers::held_temperature(double t) const {
  // The last controller reading at or before t (the first one for rows before it).
  auto it = std::upper_bound(temps.begin(), temps.end(), t, [](double x, const TemperatureSample& ts) { return x < ts.t_ns; });
  return it == temps.begin() ? temps.front().value : std::prev(it)->value;
}

void DeviceBuffers::release() {
  auto it = devices.find(output_device);
  if (it == devices.end()) return;
  DeviceState& od = it->second;
  // Output blocks before the cursor are read.
  while (cursor_block > 0) {
    od.blocks.pop_front();
    --cursor_block;
  }
  if (od.blocks.empty()) return;
  const StoredBlock& cur = od.blocks.front();
  const double keep_from = cur.time(std::min(cursor_sample, cur.n - 1));
  for (auto& [name, d] : devices) {
    if (name == output_device) continue;
    // Keep two samples before the next row's time for interpolation.
    while (d.blocks.size() > 1 && d.blocks[1].t0_ns + 2.0 * d.blocks[1].period_ns < keep_from &&
           d.blocks.front().last_ns() + 2.0 * d.blocks.front().period_ns < keep_from)
      d.blocks.pop_front();
  }
  if (temps.size() > 2) {
    auto t = std::upper_bound(temps.begin(), temps.end(), keep_from, [](double x, const TemperatureSample& ts) { return x < ts.t_ns; });
    if (t != temps.begin() && std::prev(t) != temps.begin()) temps.erase(temps.begin(), std::prev(t));
  }
}

}  // namespace inertia::fusion

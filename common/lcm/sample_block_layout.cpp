#include "common/lcm/sample_block_layout.hpp"

namespace inertia {

namespace {
std::size_t valid_bytes_for(std::int32_t num_samples) {
  return (static_cast<std::size_t>(num_samples) + 7) / 8;
}
}  // namespace

void shape_sample_block(sample_block_t& block, std::int32_t num_channels, std::int32_t num_samples) {
  const auto channels = static_cast<std::size_t>(num_channels);
  const auto samples = static_cast<std::size_t>(num_samples);
  block.num_channels = num_channels;
  block.num_samples = num_samples;
  block.valid_bytes = static_cast<std::int32_t>(valid_bytes_for(num_samples));
  block.channel_ids.resize(channels);
  block.channel_names.resize(channels);
  block.units.resize(channels);
  block.channel_seq.resize(channels);
  block.values.assign(channels, std::vector<double>(samples, 0.0));
  block.valid.assign(channels, std::vector<std::uint8_t>(valid_bytes_for(num_samples), 0));
}

std::string block_shape_error(const sample_block_t& b) {
  if (b.num_channels < 0 || b.num_samples < 0) return "negative channel or sample count";
  const auto channels = static_cast<std::size_t>(b.num_channels);
  if (b.channel_ids.size() != channels || b.channel_names.size() != channels || b.units.size() != channels ||
      b.channel_seq.size() != channels || b.values.size() != channels || b.valid.size() != channels)
    return "channel arrays of another length than num_channels";
  if (b.valid_bytes < 0 || static_cast<std::size_t>(b.valid_bytes) != valid_bytes_for(b.num_samples))
    return "valid_bytes " + std::to_string(b.valid_bytes) + " for " + std::to_string(b.num_samples) + " samples";
  for (std::size_t c = 0; c < channels; ++c) {
    if (b.values[c].size() != static_cast<std::size_t>(b.num_samples) || b.valid[c].size() != static_cast<std::size_t>(b.valid_bytes))
      return "sample arrays of another length than num_samples";
  }
  if (!(b.sample_period_s > 0.0) || !(b.sample_period_s < 1e6)) return "sample period " + std::to_string(b.sample_period_s) + " s";
  // Clock and counters within [0, 2^62), the block's last sample too: then readers' sums and
  // differences of two of them stay within int64 (fuzz_event_log met a block whose
  // sample times overflowed a conversion to int64).
  if (b.t0_mono_ns < 0 || b.t0_mono_ns >= kMaxStreamCount)
    return "t0_mono_ns " + std::to_string(b.t0_mono_ns) + " outside [0, 2^62)";
  if (!(static_cast<double>(b.t0_mono_ns) + 1e9 * b.sample_period_s * static_cast<double>(b.num_samples) <
        static_cast<double>(kMaxStreamCount)))
    return "the block ends past 2^62 ns";
  for (std::size_t c = 0; c < channels; ++c)
    if (b.channel_seq[c] < 0 || b.channel_seq[c] >= kMaxStreamCount - b.num_samples)
      return "channel_seq " + std::to_string(b.channel_seq[c]) + " outside [0, 2^62)";
  return {};
}

std::size_t udp_payload_size(const sample_block_t& block, std::string_view channel) {
  return channel.size() + 1 + static_cast<std::size_t>(block.getEncodedSize());
}

std::int32_t max_samples_per_block(const sample_block_t& header, std::string_view channel) {
  if (header.num_channels <= 0) return 0;
  sample_block_t empty = header;
  empty.num_samples = 0;
  empty.valid_bytes = 0;
  empty.values.assign(static_cast<std::size_t>(header.num_channels), {});
  empty.valid.assign(static_cast<std::size_t>(header.num_channels), {});
  const std::size_t fixed = udp_payload_size(empty, channel);
  if (fixed >= kLcmShortMessageMaxSize) return 0;

  // Each sample adds one double per channel; each started group of 8 samples one validity
  // byte per channel. Start from the bound without the bitmap and step down until it fits.
  const auto channels = static_cast<std::size_t>(header.num_channels);
  const std::size_t per_sample = channels * sizeof(double);
  std::size_t n = (kLcmShortMessageMaxSize - fixed) / per_sample;
  while (n > 0 && fixed + n * per_sample + channels * valid_bytes_for(static_cast<std::int32_t>(n)) >=
                      kLcmShortMessageMaxSize) {
    --n;
  }
  return static_cast<std::int32_t>(n);
}

}  // namespace inertia

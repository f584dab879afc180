#pragma once
// Seeds and draws of the bench physics. Every random number comes from a seed in the bench file:
// derive_seed() gives each consumer (a random vibration phase, a monitoring accelerometer, a
// sensor in a case) its own stream, so adding a phase or a sensor leaves the others' draws as
// they were. std::mt19937_64 is specified bit-exactly by the standard; std::normal_distribution
// is not (libstdc++ and libc++ differ), so the normal transform is ours (Marsaglia polar).
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <random>

namespace inertia::sim {

/// SplitMix64 finaliser (Steele, Lea, Flood 2014): a well-mixed 64-bit hash.
inline std::uint64_t mix64(std::uint64_t z) noexcept {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// A seed for one consumer, from the config seed and the consumer's path (case index, stream id...).
inline std::uint64_t derive_seed(std::uint64_t seed, std::initializer_list<std::uint64_t> path) noexcept {
  std::uint64_t s = mix64(seed);
  for (const std::uint64_t p : path) s = mix64(s ^ mix64(p + 0x632BE59BD9B4E019ull));
  return s;
}

/// Stream ids for derive_seed (fixed: changing one changes every simulated dataset).
enum class Stream : std::uint64_t { RandomVibration = 1, Monitor = 2, Control = 3, Thermal = 4, Sensor = 5, Placement = 6 };

/// Uniform and standard-normal draws. Real-time safe (no allocation).
class RandomSource {
 public:
  explicit RandomSource(std::uint64_t seed) : engine_(seed) {}
  /// Uniform on [0, 1) with 53 random bits.
  double uniform() noexcept { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double normal() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * f;
    has_spare_ = true;
    return u * f;
  }

 private:
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace inertia::sim

#pragma once
// Deterministic standard-normal draws for the sensor truth models.
// Our own generator (xoshiro256++) and transform (Marsaglia's polar method) rather than
// std::normal_distribution, whose algorithm differs between standard libraries: a seed in a
// bench config must give the same data with libstdc++ and libc++. Both are O(1) and
// allocation-free, cheap enough for one draw per noise component per 10 kHz sample.
#include <cmath>
#include <cstdint>

namespace inertia::sim {

/// SplitMix64 (Steele, Lea, Flood 2014): expands one 64-bit seed into well-mixed words; the
/// seeding recommended by the xoshiro authors.
inline std::uint64_t splitmix64(std::uint64_t& x) noexcept {
  std::uint64_t z = (x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// xoshiro256++ 1.0 (Blackman, Vigna 2019).
class Xoshiro256pp {
 public:
  /// `stream` separates independent sequences drawn from one config seed (white, pink, brown
  /// noise of one sensor), so switching one component off leaves the others' draws unchanged.
  Xoshiro256pp(std::uint64_t seed, std::uint64_t stream) noexcept {
    std::uint64_t x = seed ^ (stream * 0xD1B54A32D192ED03ull);
    for (auto& w : s_) w = splitmix64(x);
  }
  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[0] + s_[3], 23) + s_[0];
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  /// Uniform on [0, 1) with 53 random bits.
  double uniform() noexcept { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  std::uint64_t s_[4];
};

/// Standard normal draws, N(0, 1). Real-time safe.
class GaussianSource {
 public:
  GaussianSource(std::uint64_t seed, std::uint64_t stream) noexcept : rng_(seed, stream) {}
  double next() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * rng_.uniform() - 1.0;
      v = 2.0 * rng_.uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double m = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * m;
    has_spare_ = true;
    return u * m;
  }

 private:
  Xoshiro256pp rng_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace inertia::sim

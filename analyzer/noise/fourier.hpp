#pragma once
// The analyzer's discrete Fourier transforms, by FFTW 3 (libfftw3, Debian's libfftw3-dev).
//
// Chosen by measured speed (docs/validation.md, "The FFT library"): Debian 12 packages FFTW and
// kissfft, not pocketfft; FFTW's real transforms are several times faster than Eigen's bundled
// kissfft at the lengths the sandwich's X'RX uses. FFTW is GPL-2+, so inertia-analyze as built
// is distributed under the GPL's terms (cmake/debian/copyright). The daemon does not link it.
//
// Each object owns its buffers (FFTW-aligned, so that every object of one length runs the same
// plan and gives the same bits) and serves one thread at a time; objects on several threads share
// one plan per length and kind, made once under a lock when a direction is first run (FFTW's
// planner is not thread-safe, its execution is; an estimated plan of a long transform takes
// about as long as running it, and many objects run one direction alone). Plans are made with FFTW_ESTIMATE: a measured plan could differ from run to run
// and move the answer in its last bits.
//
// Conventions (those of Eigen's FFT, which they replace): forward X_k = sum_t x_t e^{-2 pi i k t / L},
// inverse x_t = (1/L) sum_k X_k e^{+2 pi i k t / L}.
#include <Eigen/Dense>

#include <complex>
#include <memory>

namespace inertia::noise {

namespace detail {
/// Frees what fftw_malloc gave.
struct FftwFree {
  void operator()(void* p) const;
};
/// A buffer of `T` from fftw_malloc (FFTW's alignment), zeroed.
template <typename T>
using FftwBuffer = std::unique_ptr<T[], FftwFree>;
/// A transform's two shared plans (fftw_plan, which this header does not name).
struct FftwPlans {
  void* forward = nullptr;
  void* inverse = nullptr;
};
}  // namespace detail

/// The transform of real sequences of length L: L samples <-> the L/2 + 1 bins k = 0 .. L/2 (the
/// rest follow by conjugate symmetry).
class RealFourier {
 public:
  explicit RealFourier(Eigen::Index length);

  [[nodiscard]] Eigen::Index length() const { return length_; }
  [[nodiscard]] Eigen::Index bins() const { return length_ / 2 + 1; }

  /// The L samples, zero until written; forward() leaves them as they are.
  Eigen::Map<Eigen::VectorXd> samples() { return {samples_.get(), length_}; }
  /// The L/2 + 1 bins.
  Eigen::Map<Eigen::VectorXcd> spectrum() { return {spectrum_.get(), bins()}; }

  /// spectrum() = the transform of samples().
  void forward();
  /// samples() = the inverse transform of spectrum(), taken as the half of a conjugate-symmetric
  /// spectrum (the imaginary parts of bins 0 and L/2 are ignored). Overwrites spectrum().
  void inverse();

 private:
  Eigen::Index length_;
  detail::FftwBuffer<double> samples_;
  detail::FftwBuffer<std::complex<double>> spectrum_;
  detail::FftwPlans plans_;
};

/// The transform of complex sequences of length L, in place on values().
class ComplexFourier {
 public:
  explicit ComplexFourier(Eigen::Index length);

  [[nodiscard]] Eigen::Index length() const { return length_; }
  Eigen::Map<Eigen::VectorXcd> values() { return {values_.get(), length_}; }

  /// values() = its forward transform.
  void forward();
  /// values() = its inverse transform (scaled by 1/L).
  void inverse();

 private:
  Eigen::Index length_;
  detail::FftwBuffer<std::complex<double>> values_;
  detail::FftwPlans plans_;
};

}  // namespace inertia::noise

#include "analyzer/noise/fourier.hpp"

#include <fftw3.h>

#include <map>
#include <mutex>
#include <new>
#include <stdexcept>
#include <tuple>

namespace inertia::noise {
namespace {

enum class Kind { RealForward, RealInverse, ComplexForward, ComplexInverse };

/// One plan per kind and length for the process, made on first use under the lock. The plans
/// live as long as the process (FFTW's own cache of twiddles with them). `real` and `complex` are
/// the caller's own buffers (fftw_malloc'd, so of the alignment every later buffer has; one and
/// the same for an in-place transform): FFTW_ESTIMATE plans without touching them, so planning
/// takes no memory of its own beside FFTW's.
fftw_plan plan_for(Kind kind, Eigen::Index length, double* real, fftw_complex* complex) {
  static std::mutex lock;
  static std::map<std::pair<Kind, Eigen::Index>, fftw_plan> plans;
  const std::scoped_lock guard(lock);
  auto found = plans.find({kind, length});
  if (found != plans.end()) return found->second;
  const int n = static_cast<int>(length);
  fftw_plan plan = nullptr;
  switch (kind) {
    case Kind::RealForward: plan = fftw_plan_dft_r2c_1d(n, real, complex, FFTW_ESTIMATE); break;
    case Kind::RealInverse: plan = fftw_plan_dft_c2r_1d(n, complex, real, FFTW_ESTIMATE); break;
    case Kind::ComplexForward: plan = fftw_plan_dft_1d(n, complex, complex, FFTW_FORWARD, FFTW_ESTIMATE); break;
    case Kind::ComplexInverse: plan = fftw_plan_dft_1d(n, complex, complex, FFTW_BACKWARD, FFTW_ESTIMATE); break;
  }
  if (plan == nullptr) throw std::runtime_error("FFTW made no plan for a transform of this length");
  plans.emplace(std::pair{kind, length}, plan);
  return plan;
}

template <typename T>
T* aligned_zeros(Eigen::Index count) {
  void* p = fftw_malloc(sizeof(T) * static_cast<std::size_t>(count));
  if (p == nullptr) throw std::bad_alloc();
  T* out = static_cast<T*>(p);
  for (Eigen::Index i = 0; i < count; ++i) new (out + i) T{};
  return out;
}

void check_length(Eigen::Index length) {
  if (length < 1 || length > Eigen::Index{1} << 30) throw std::invalid_argument("Fourier transform: length out of range");
}

fftw_complex* as_fftw(std::complex<double>* p) { return reinterpret_cast<fftw_complex*>(p); }   // same layout, by both standards

}  // namespace

void detail::FftwFree::operator()(void* p) const { fftw_free(p); }

RealFourier::RealFourier(Eigen::Index length) : length_(length) {
  check_length(length);
  samples_.reset(aligned_zeros<double>(length));
  spectrum_.reset(aligned_zeros<std::complex<double>>(bins()));
}

void RealFourier::forward() {
  if (plans_.forward == nullptr) plans_.forward = plan_for(Kind::RealForward, length_, samples_.get(), as_fftw(spectrum_.get()));
  fftw_execute_dft_r2c(static_cast<fftw_plan>(plans_.forward), samples_.get(), as_fftw(spectrum_.get()));
}

void RealFourier::inverse() {
  if (plans_.inverse == nullptr) plans_.inverse = plan_for(Kind::RealInverse, length_, samples_.get(), as_fftw(spectrum_.get()));
  spectrum_[0].imag(0.0);
  if (length_ % 2 == 0) spectrum_[static_cast<std::size_t>(length_ / 2)].imag(0.0);
  fftw_execute_dft_c2r(static_cast<fftw_plan>(plans_.inverse), as_fftw(spectrum_.get()), samples_.get());
  samples() *= 1.0 / static_cast<double>(length_);
}

ComplexFourier::ComplexFourier(Eigen::Index length) : length_(length) {
  check_length(length);
  values_.reset(aligned_zeros<std::complex<double>>(length));
}

void ComplexFourier::forward() {
  if (plans_.forward == nullptr) plans_.forward = plan_for(Kind::ComplexForward, length_, nullptr, as_fftw(values_.get()));
  fftw_execute_dft(static_cast<fftw_plan>(plans_.forward), as_fftw(values_.get()), as_fftw(values_.get()));
}

void ComplexFourier::inverse() {
  if (plans_.inverse == nullptr) plans_.inverse = plan_for(Kind::ComplexInverse, length_, nullptr, as_fftw(values_.get()));
  fftw_execute_dft(static_cast<fftw_plan>(plans_.inverse), as_fftw(values_.get()), as_fftw(values_.get()));
  values() *= 1.0 / static_cast<double>(length_);
}

}  // namespace inertia::noise

// The analyzer's Fourier transforms (analyzer/noise/fourier.hpp) against the DFT's definition, and
// shared plans giving the same bits on every thread.
#include "analyzer/noise/fourier.hpp"

#include <gtest/gtest.h>

#include <complex>
#include <numbers>
#include <random>
#include <thread>
#include <vector>

namespace inertia::noise {
namespace {

using Complex = std::complex<double>;

/// X_k = sum_t x_t e^{-2 pi i k t / L}, term by term.
Eigen::VectorXcd dft(const Eigen::VectorXcd& x, double sign = -1.0) {
  const Eigen::Index n = x.size();
  Eigen::VectorXcd out = Eigen::VectorXcd::Zero(n);
  for (Eigen::Index k = 0; k < n; ++k)
    for (Eigen::Index t = 0; t < n; ++t)
      out(k) += x(t) * std::polar(1.0, sign * 2.0 * std::numbers::pi * static_cast<double>((k * t) % n) / static_cast<double>(n));
  return out;
}

Eigen::VectorXd gaussian(Eigen::Index n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Eigen::VectorXd x(n);
  for (Eigen::Index i = 0; i < n; ++i) x(i) = g(rng);
  return x;
}

TEST(Fourier, RealTransformIsTheDefinitionsHalfAndTheInverseUndoesIt) {
  for (const Eigen::Index n : {1, 2, 7, 16, 60, 97, 256}) {
    const Eigen::VectorXd x = gaussian(n, static_cast<unsigned>(n));
    RealFourier fourier(n);
    ASSERT_EQ(fourier.bins(), n / 2 + 1);
    fourier.samples() = x;
    fourier.forward();
    EXPECT_EQ(fourier.samples(), x) << "forward keeps its input";
    const Eigen::VectorXcd expected = dft(x.cast<Complex>()).head(n / 2 + 1);
    const double scale = std::sqrt(static_cast<double>(n)) * x.norm();   // |X_k| <= sqrt(n) |x|
    EXPECT_LT((fourier.spectrum() - expected).cwiseAbs().maxCoeff(), 1e-14 * scale) << "n = " << n;
    fourier.samples().setZero();
    fourier.inverse();
    EXPECT_LT((fourier.samples() - x).cwiseAbs().maxCoeff(), 1e-14 * (1.0 + x.cwiseAbs().maxCoeff()) * std::log2(2.0 * n)) << "n = " << n;
  }
}

TEST(Fourier, RealInverseTakesTheSpectrumAsConjugateSymmetric) {
  // A spectrum with imaginary parts at DC and Nyquist: they cannot belong to a real sequence,
  // and the inverse is that of the symmetric spectrum without them.
  const Eigen::Index n = 8;
  RealFourier fourier(n);
  Eigen::VectorXcd half(5);
  half << Complex(1.0, 3.0), Complex(0.5, -0.25), Complex(-2.0, 1.0), Complex(0.0, 0.75), Complex(4.0, -1.0);
  Eigen::VectorXcd full(n);
  full(0) = half(0).real();
  full(4) = half(4).real();
  for (Eigen::Index k = 1; k < 4; ++k) {
    full(k) = half(k);
    full(n - k) = std::conj(half(k));
  }
  const Eigen::VectorXcd expected = dft(full, +1.0) / static_cast<double>(n);
  fourier.spectrum() = half;
  fourier.inverse();
  EXPECT_LT((fourier.samples().cast<Complex>() - expected).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT(expected.imag().cwiseAbs().maxCoeff(), 1e-14);
}

TEST(Fourier, ComplexTransformIsTheDefinitionAndTheInverseUndoesIt) {
  for (const Eigen::Index n : {1, 5, 32, 100}) {
    Eigen::VectorXcd x(n);
    const Eigen::VectorXd re = gaussian(n, 11), im = gaussian(n, 12);
    x.real() = re;
    x.imag() = im;
    ComplexFourier fourier(n);
    fourier.values() = x;
    fourier.forward();
    const double scale = std::sqrt(static_cast<double>(n)) * x.norm();
    EXPECT_LT((fourier.values() - dft(x)).cwiseAbs().maxCoeff(), 1e-14 * scale) << "n = " << n;
    fourier.inverse();
    EXPECT_LT((fourier.values() - x).cwiseAbs().maxCoeff(), 1e-14 * (1.0 + x.cwiseAbs().maxCoeff()) * std::log2(2.0 * n)) << "n = " << n;
  }
}

TEST(Fourier, ObjectsOnSeveralThreadsShareThePlanAndGiveTheSameBits) {
  const Eigen::Index n = 1 << 12;
  const Eigen::VectorXd x = gaussian(n, 3);
  RealFourier serial(n);
  serial.samples() = x;
  serial.forward();
  const Eigen::VectorXcd expected = serial.spectrum();
  std::vector<Eigen::VectorXcd> results(4);
  std::vector<std::thread> threads;
  for (std::size_t i = 0; i < results.size(); ++i)
    threads.emplace_back([&, i] {
      for (int repeat = 0; repeat < 20; ++repeat) {
        RealFourier fourier(n + static_cast<Eigen::Index>(repeat % 2));   // two lengths planned at once
        if (fourier.length() != n) continue;
        fourier.samples() = x;
        fourier.forward();
        results[i] = fourier.spectrum();
      }
    });
  for (std::thread& t : threads) t.join();
  for (const Eigen::VectorXcd& r : results) EXPECT_EQ(r, expected);
}

TEST(Fourier, ALengthOutOfRangeIsRefused) {
  EXPECT_THROW(RealFourier(0), std::invalid_argument);
  EXPECT_THROW(ComplexFourier(-4), std::invalid_argument);
}

}  // namespace
}  // namespace inertia::noise

#pragma once
// Allan variance of a sensor's output at rest (IEEE Std 952 Annex C, IEEE Std 1293): the
// overlapping estimator at octave averaging times, and the modified variance where it helps
// (it tells white phase-like noise, the quantization Q, from white rate noise, N).
//
// Streaming octave averaging, O(1) time per sample and memory independent of the record length:
//  - level 0 keeps the newest 3 * 2^K samples (K = exact_octaves) and gathers a block of 4 * 2^K
//    more; then it integrates all of them into the phase x (x(p) = the sum of the first p samples,
//    less a centre), and every new point p completes, for every m = 1, 2, 4 .. 2^K, one second
//    difference
//        d = x(p) - 2 x(p-m) + x(p-2m) = (sum of the newest m samples) - (sum of the m before):
//    the fully overlapping estimator, exact. Each octave is then a pass over contiguous arrays
//    (vectorized), not per-sample updates of per-octave running sums, which were bound by their
//    loads and stores;
//  - the modified variance's sum of m consecutive d is the same second difference of the sums of
//    m consecutive phase points, which octave m takes from octave m/2's at one addition a point;
//  - rounding cannot grow with the record: the phase is integrated afresh every block about the
//    previous block's mean, so its size is that of the noise over one buffer, and the record's
//    first sample is taken off every sample, so the averages of the levels below keep the noise's
//    digits rather than the offset's;
//  - level j >= 1 holds the averages of 2^j consecutive samples (pairs of level j-1), in blocks
//    the same way, and gives m = 2^(K+j): the overlapping estimator on the averaged series,
//    stride 2^j samples instead of 1 (the "octave decimation" of long-term stability software).
//    The stride changes the estimate's degrees of freedom little once 2^K >> 1 and is reported.
// With K = 10: level 0 and the scratch 224 kB, then 32 kB a level; 24 h at 10 kHz (8.6e8
// samples): 18 levels beyond level 0, 0.8 MB.
//
// Units: y in the output unit (e.g. mA, deg/s); tau in s; variances in y's unit squared.
#include <Eigen/Dense>

#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

namespace inertia::noise {

struct AllanPoint {
  double tau = 0.0;                  // averaging time, s
  std::int64_t m = 0;                // in samples of tau0
  double avar = 0.0;                 // overlapping Allan variance
  double mvar = std::numeric_limits<double>::quiet_NaN();   // modified Allan variance (level 0 only)
  std::int64_t terms = 0;            // second differences in avar
  std::int64_t mod_terms = 0;        // sums of m second differences in mvar
  /// Per stretch pooled into this point: N of the edf formulas (phase points at the estimate's
  /// stride) and m in samples of the stride; the edf of independent stretches add.
  std::vector<double> phase_points;
  double m_at_stride = 0.0;
  std::int64_t stride = 1;           // 1: fully overlapping; 2^j: on the 2^j-averaged series
};

class AllanAccumulator {
 public:
  explicit AllanAccumulator(double tau0_s, int exact_octaves = 10);
  ~AllanAccumulator();
  AllanAccumulator(AllanAccumulator&&) noexcept;
  AllanAccumulator& operator=(AllanAccumulator&&) noexcept;

  void push(double y);
  void push(const Eigen::Ref<const Eigen::VectorXd>& y);

  /// Every octave with at least one term (avar), in ascending tau. Samples pushed since the last
  /// full block count too.
  [[nodiscard]] std::vector<AllanPoint> points() const;
  [[nodiscard]] std::int64_t samples() const;
  [[nodiscard]] double tau0() const { return tau0_; }
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  struct Level;
  struct Scratch {   // a block's phase, and the sums of m and of 2m consecutive phase points
    Eigen::ArrayXd phase, sums, wider_sums;
  };
  AllanAccumulator(const AllanAccumulator&);   // points() of a part-filled block: on a copy
  void process(std::size_t level);   // the level's new samples into its sums and the next level
  void flush();                      // every level's part-filled block processed

  double tau0_;
  int exact_octaves_;
  std::optional<double> offset_;   // the first sample, taken off every sample
  std::vector<Level> levels_;
  Scratch scratch_;
};

/// The points of separate stretches (a log with gaps, several dwells) pooled: at each tau the
/// second differences of every stretch averaged together (each stretch's terms weigh one), the
/// phase points summed for the degrees of freedom. Stretches must share tau0.
std::vector<AllanPoint> pool(const std::vector<std::vector<AllanPoint>>& stretches);

/// The overlapping Allan variance at averaging factor m written out (O(N m)): the reference the
/// streaming estimator is tested against.
double allan_variance_direct(const Eigen::Ref<const Eigen::VectorXd>& y, std::int64_t m);
/// The modified Allan variance written out (O(N m)).
double modified_allan_variance_direct(const Eigen::Ref<const Eigen::VectorXd>& y, std::int64_t m);

/// The edf of a (pooled) point for noise exponent alpha: the sum over its stretches.
double point_edf(const AllanPoint& p, int alpha);

/// The interval holding the true variance with probability `level`, for an estimate with `edf`
/// degrees of freedom (chi-square: edf * estimate / true ~ chi2(edf); NIST SP 1065 eq. 45).
std::pair<double, double> variance_interval(double estimate, double edf, double level = 0.95);

/// Equivalent degrees of freedom of the overlapping Allan variance (NIST SP 1065, table 5, after
/// Stein), `phase_points` N, averaging factor m, for power-law frequency noise S_y ~ f^alpha:
/// alpha 2 white PM (quantization), 0 white FM (N), -1 flicker FM (B), -2 random-walk FM (K).
/// Other alpha (a rate ramp): the random-walk formula (the most conservative of them).
double overlapping_edf(double phase_points, double m, int alpha);

}  // namespace inertia::noise

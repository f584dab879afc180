// Our half of the SysIdentPy comparison (tests/bench/peer/sysidentpy_compare.py). Reads the
// candidate matrix SysIdentPy built (raw little-endian: int64 rows, int64 cols, then the columns
// one after another, then y; all float64) and runs on exactly those columns:
//   frols  - the ERR ranking stopped at N_TERMS, then least squares on the chosen columns:
//            the same procedure as SysIdentPy's FROLS with a fixed n_terms;
//   select - the whole selection engine (section 2.7.2: ERR ranking, t-tests with Bonferroni,
//            AIC, residual-mean test), which decides the number of terms itself.
// Times are the median of --repeat runs, file reading excluded. One line per method:
//   <method> columns=i,j,k theta=a,b,c seconds=s
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "analyzer/ident/err.hpp"
#include "analyzer/ident/selection.hpp"
#include "analyzer/ident/uls_batch.hpp"

namespace {

using Eigen::Index;
using namespace inertia::ident;

struct Problem {
  Eigen::MatrixXd phi;
  Eigen::VectorXd y;
};

Problem read_problem(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::int64_t rows = 0, cols = 0;
  in.read(reinterpret_cast<char*>(&rows), sizeof rows);
  in.read(reinterpret_cast<char*>(&cols), sizeof cols);
  if (!in || rows <= 0 || cols <= 0) throw std::runtime_error(path + ": bad header");
  Problem p{Eigen::MatrixXd(rows, cols), Eigen::VectorXd(rows)};
  in.read(reinterpret_cast<char*>(p.phi.data()), static_cast<std::streamsize>(sizeof(double) * rows * cols));
  in.read(reinterpret_cast<char*>(p.y.data()), static_cast<std::streamsize>(sizeof(double) * rows));
  if (!in) throw std::runtime_error(path + ": shorter than its header says");
  return p;
}

template <class F>
double median_seconds(int repeat, F&& run) {
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    const auto start = std::chrono::steady_clock::now();
    run();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: peer_frols_compare PROBLEM.bin N_TERMS [REPEAT]\n");
    return 2;
  }
  try {
    const Problem p = read_problem(argv[1]);
    const Index n_terms = std::stol(argv[2]);
    const int repeat = argc > 3 ? std::max(1, std::atoi(argv[3])) : 5;
    std::vector<std::string> labels;
    for (Index j = 0; j < p.phi.cols(); ++j) labels.push_back(fmt::format("c{}", j));

    std::vector<Index> chosen;
    Eigen::VectorXd theta;
    const double frols_s = median_seconds(repeat, [&] {
      ErrOptions eo;
      eo.max_terms = n_terms;
      // The ranking forms only the chosen columns' inner products (one memory-bound pass per
      // term, as FROLS's own loop), then least squares on the k chosen columns by column-scaled
      // normal equations as in solve_uls.
      const ErrRanking r = err_rank(p.phi, p.y, eo);
      chosen.assign(r.order.begin(), r.order.end());
      const auto k = static_cast<Index>(chosen.size());
      const auto column = [&](Index a) { return p.phi.col(chosen[std::size_t(a)]); };
      Eigen::MatrixXd gk(k, k);
      Eigen::VectorXd ck(k), scale(k);
      for (Index a = 0; a < k; ++a) scale(a) = 1.0 / column(a).norm();
      for (Index a = 0; a < k; ++a) {
        ck(a) = scale(a) * column(a).dot(p.y);
        for (Index b = 0; b <= a; ++b) gk(a, b) = gk(b, a) = scale(a) * scale(b) * column(a).dot(column(b));
      }
      theta = scale.asDiagonal() * gk.ldlt().solve(ck);
    });
    fmt::print("frols columns={} theta={} seconds={:.6g}\n", fmt::join(chosen, ","), fmt::join(theta, ","), frols_s);

    SelectionResult best;
    const double select_s = median_seconds(repeat, [&] {
      const SelectionProblem problem(p.phi, p.y, labels);
      best = select_model(problem, SelectionOptions{});
    });
    const CandidateModel& m = best.best_model();
    fmt::print("select columns={} theta={} seconds={:.6g}\n", fmt::join(m.columns, ","), fmt::join(m.fit.theta, ","),
               select_s);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "peer_frols_compare: %s\n", e.what());
    return 2;
  }
}

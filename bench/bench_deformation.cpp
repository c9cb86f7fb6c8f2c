// Cost of one evaluation of the elastic deformation W = K * P (called several
// times per multigrid cycle on every level, so per time step many times).
#include <benchmark/benchmark.h>

#include <cmath>

#include "elastic/Deformation.hpp"

namespace {

using namespace ehlsim;

constexpr double kHalfWidth = 1.5;  // default domain (model.md)

// Hertz-like pressure: zero on a good part of the domain, as in a real run
// (the FFT does not care; the direct sum skips all-zero rows).
Field hertz_field(const Grid2D& g) {
  Field P(g);
  for (int j = 0; j < g.n; ++j)
    for (int i = 0; i < g.n; ++i) {
      const double r2 = g.x(i) * g.x(i) + g.y(j) * g.y(j);
      P(i, j) = r2 < 1.0 ? std::sqrt(1.0 - r2) : 0.0;
    }
  return P;
}

template <class Operator>
void run(benchmark::State& state, Operator& op, const Grid2D& g) {
  const Field P = hertz_field(g);
  Field W(g);
  for (auto _ : state) {
    op.apply(P, W);
    benchmark::DoNotOptimize(W.data());
    benchmark::ClobberMemory();
  }
  state.counters["points"] = static_cast<double>(g.size());
}

void BM_FftDeformation(benchmark::State& state) {
  const Grid2D g(static_cast<int>(state.range(0)), kHalfWidth);
  FftDeformation op(g, FftPlanning::Measure);
  state.counters["m"] = op.padded_size();
  run(state, op, g);
}

void BM_FftDeformationEstimate(benchmark::State& state) {
  const Grid2D g(static_cast<int>(state.range(0)), kHalfWidth);
  FftDeformation op(g, FftPlanning::Estimate);
  run(state, op, g);
}

// The quadrant of a problem even in X and Y (the argument is the full grid's n).
void BM_MirroredFftDeformation(benchmark::State& state) {
  const Grid2D g = Grid2D(static_cast<int>(state.range(0)), kHalfWidth).quadrant();
  FftDeformation op(g, FftPlanning::Estimate);
  run(state, op, g);
}

void BM_DirectDeformation(benchmark::State& state) {
  const Grid2D g(static_cast<int>(state.range(0)), kHalfWidth);
  DirectDeformation op(g);
  run(state, op, g);
}

// Set-up cost: kernel table, kernel transform and FFTW planning.
void BM_FftDeformationSetup(benchmark::State& state) {
  const Grid2D g(static_cast<int>(state.range(0)), kHalfWidth);
  for (auto _ : state) {
    FftDeformation op(g, FftPlanning::Measure);  // FFTW reuses its in-process wisdom
    benchmark::DoNotOptimize(&op);
  }
}

}  // namespace

BENCHMARK(BM_FftDeformation)
    ->Arg(129)
    ->Arg(257)
    ->Arg(513)
    ->Arg(1025)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FftDeformationEstimate)
    ->Arg(129)
    ->Arg(257)
    ->Arg(513)
    ->Arg(1025)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MirroredFftDeformation)
    ->Arg(129)
    ->Arg(257)
    ->Arg(513)
    ->Arg(1025)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DirectDeformation)->Arg(33)->Arg(65)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FftDeformationSetup)->Arg(257)->Arg(1025)->Unit(benchmark::kMillisecond);

// Time of the runtime's real-time calls against the number of GPR training points m: the paper
// campaign's calibrated model (seed 1) with its GPR replaced by one of m points (its trained
// inputs resampled with a jitter of 0.3 length units, random targets, its hyperparameters,
// conditioned again), at m = 100, 300, 1000, 3000. Poses: 64 of the campaign's validation rows;
// the inverse from seeds 2° off, as stepcal-bench.
//
//   build/bin/stepcal-bench-gpr-size [--benchmark_repetitions=N]
//
// Reports the mean time per call (µs); the inverse also its mean Newton steps.
#include <benchmark/benchmark.h>

#include <map>
#include <random>

#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"
#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace {

using namespace stepcal;

constexpr double kSeedOffsetRad = 2.0 * kRadPerDeg;
constexpr int kPoses = 64;

struct Setup {
  CalibratedModel model;
  std::vector<const Measurement*> rows;
  Campaign campaign;
};

const Setup& paper() {
  static const Setup setup = [] {
    Setup s;
    twin::TwinOptions options;
    options.protocol = "paper";
    options.seed = 1;
    s.campaign = twin::simulateCampaign(options, nullptr);
    s.model = trainer::modelFromOutcome(s.campaign, trainer::calibrateCampaign(s.campaign));
    for (const Measurement& row : s.campaign.rows) {
      if (row.set == RowSet::kValidation && static_cast<int>(s.rows.size()) < kPoses) {
        s.rows.push_back(&row);
      }
    }
    return s;
  }();
  return setup;
}

/// The paper model with a GPR of m training points (built once per m).
const runtime::RuntimeModel& modelWithPoints(int m) {
  static std::map<int, std::unique_ptr<const runtime::RuntimeModel>> models;
  auto& slot = models[m];
  if (!slot) {
    CalibratedModel model = paper().model;
    GprParameters g = *model.gpr;
    std::mt19937_64 rng(static_cast<uint64_t>(m));
    std::normal_distribution<double> jitter(0.0, 0.3), target(0.0, 1.0);
    const Eigen::MatrixXd trained = g.inputs_normalised;
    g.inputs_normalised.resize(m, trained.cols());
    g.targets_standardised.resize(m, g.alpha.cols());
    for (int i = 0; i < m; ++i) {
      for (Eigen::Index d = 0; d < trained.cols(); ++d) {
        g.inputs_normalised(i, d) = trained(i % trained.rows(), d) + jitter(rng) * g.length_scales(d);
      }
      for (Eigen::Index o = 0; o < g.alpha.cols(); ++o) g.targets_standardised(i, o) = target(rng);
    }
    model.gpr = GprPredictor::conditioned(g).parameters();
    slot = runtime::RuntimeModel::fromModel(std::move(model), static_cast<uint64_t>(m));
  }
  return *slot;
}

void BM_Forward(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const runtime::RuntimeModel& model = modelWithPoints(m);
  runtime::Workspace ws = runtime::makeWorkspace(model);
  size_t i = 0;
  for (auto _ : state) {
    const Measurement& row = *paper().rows[i++ % paper().rows.size()];
    const runtime::ForwardResult r = runtime::correctForward(
        model, ws, row.q_rad, row.wrenchOrZero(), runtime::kUnknownTemperature_c);
    benchmark::DoNotOptimize(r.X_TrackerTip);
  }
}

void BM_Inverse(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const runtime::RuntimeModel& model = modelWithPoints(m);
  runtime::Workspace ws = runtime::makeWorkspace(model);
  struct Problem {
    Pose target;
    JointVector seed;
    Vec6 wrench;
  };
  std::vector<Problem> problems;
  for (const Measurement* row : paper().rows) {
    Problem p;
    p.wrench = row->wrenchOrZero();
    p.target = runtime::correctForward(model, ws, row->q_rad, p.wrench,
                                       runtime::kUnknownTemperature_c)
                   .X_TrackerTip;
    p.seed = row->q_rad;
    for (Eigen::Index j = 0; j < p.seed.size(); ++j) p.seed(j) += j % 2 ? -kSeedOffsetRad : kSeedOffsetRad;
    problems.push_back(p);
  }
  size_t i = 0;
  long iterations = 0;
  for (auto _ : state) {
    const Problem& p = problems[i++ % problems.size()];
    const runtime::InverseResult r = runtime::solveInverse(
        model, ws, p.target, p.wrench, runtime::kUnknownTemperature_c, p.seed,
        runtime::Clock::now() + std::chrono::seconds(1));
    iterations += r.iterations;
    benchmark::DoNotOptimize(r.q_target_rad);
  }
  state.counters["iterations"] =
      benchmark::Counter(static_cast<double>(iterations), benchmark::Counter::kAvgIterations);
}

}  // namespace

BENCHMARK(BM_Forward)->Arg(100)->Arg(300)->Arg(1000)->Arg(3000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Inverse)->Arg(100)->Arg(300)->Arg(1000)->Arg(3000)->Unit(benchmark::kMicrosecond);
BENCHMARK_MAIN();

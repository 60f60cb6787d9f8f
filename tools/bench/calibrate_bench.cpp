// Wall time of the whole offline calibration of the paper's campaign (1070 rows: step 1, step 2,
// two GPR fits with hyperparameter search and 10-fold CV), and of its parts.
//
//   build/bin/stepcal-bench-calibrate
//
// Reports mean, median, stddev, min and max over 10 repetitions, in milliseconds.
#include <benchmark/benchmark.h>

#include <algorithm>

#include "stepcal/trainer/pipeline.hpp"
#include "stepcal/twin/twin.hpp"

namespace {

using namespace stepcal;

const Campaign& paperCampaign() {
  static const Campaign campaign = [] {
    twin::TwinOptions options;
    options.protocol = "paper";
    options.seed = 1;
    return twin::simulateCampaign(options, nullptr);
  }();
  return campaign;
}

void BM_CalibratePaperCampaign(benchmark::State& state) {
  const Campaign& campaign = paperCampaign();
  double gpr_seconds = 0.0;
  for (auto _ : state) {
    const trainer::CalibrationOutcome outcome = trainer::calibrateCampaign(campaign);
    gpr_seconds += outcome.seconds_gpr;
    benchmark::DoNotOptimize(outcome.accuracy.data());
  }
  state.counters["gpr_s"] = benchmark::Counter(gpr_seconds, benchmark::Counter::kAvgIterations);
}
// One GPR fit at the paper's size: 300 points, 12 inputs, 6 outputs, on the POE residual.
void BM_GprFitPaperSize(benchmark::State& state) {
  const Campaign& campaign = paperCampaign();
  const std::vector<const Measurement*> rows = campaign.rowsIn(RowSet::kResidual);
  Eigen::MatrixXd X(static_cast<Eigen::Index>(rows.size()), 12), Y(X.rows(), 6);
  for (Eigen::Index i = 0; i < X.rows(); ++i) {
    X.row(i) = trainer::gprInput(*rows[static_cast<size_t>(i)]).transpose();
    // A smooth, load-dependent target like the POE residual: the deflection's first order.
    Y.row(i) = X.row(i).tail<6>() * 1e-6;
  }
  for (auto _ : state) {
    const trainer::GaussianProcess gp = trainer::GaussianProcess::fit(X, Y);
    benchmark::DoNotOptimize(gp.alpha().data());
  }
}
double minimum(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
double maximum(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

// One run per repetition (a calibration takes about a second), 10 repetitions reported as
// mean, median, stddev, min and max.
void registerRepeated(const char* name, void (*function)(benchmark::State&)) {
  benchmark::RegisterBenchmark(name, function)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime()
      ->Iterations(1)
      ->Repetitions(10)
      ->ComputeStatistics("min", minimum)
      ->ComputeStatistics("max", maximum)
      ->ReportAggregatesOnly(true);
}

}  // namespace

int main(int argc, char** argv) {
  registerRepeated("BM_CalibratePaperCampaign", BM_CalibratePaperCampaign);
  registerRepeated("BM_GprFitPaperSize", BM_GprFitPaperSize);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

// The C++ API's answers on a campaign, for tests/python/test_stepcal.py to compare the bindings
// with: for every validation row (file order), correctForward at its joints and measured wrench,
// and solveInverse to its measured pose from a seed 2° off its joints (alternating sign; no
// deadline), one line each, every double with 17 significant digits:
//   F status x y z qw qx qy qz std1..std6
//   I status q1..qn iterations
//   runtime_reference MODEL CAMPAIGN_DIR
#include <cmath>
#include <cstdio>

#include "stepcal/common/campaign.hpp"
#include "stepcal/common/units.hpp"
#include "stepcal/runtime/corrector.hpp"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: runtime_reference MODEL CAMPAIGN_DIR\n");
    return 2;
  }
  using namespace stepcal;
  const auto model = runtime::RuntimeModel::load(argv[1]);
  const Campaign campaign = readCampaign(argv[2]);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  int index = 0;
  for (const Measurement* row : campaign.rowsIn(RowSet::kValidation)) {
    const double temp_c = row->temp_c ? *row->temp_c : runtime::kUnknownTemperature_c;
    const runtime::ForwardResult f =
        runtime::correctForward(*model, ws, row->q_rad, row->wrenchOrZero(), temp_c);
    const Eigen::Quaterniond q(f.X_TrackerTip.linear());
    const Vec3 p = f.X_TrackerTip.translation();
    std::printf("F %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g", int(f.status), p.x(), p.y(),
                p.z(), q.w(), q.x(), q.y(), q.z());
    for (int k = 0; k < 6; ++k) std::printf(" %.17g", f.gpr_std(k));
    std::printf("\n");
    const double offset_rad = (index++ % 2 == 0 ? 2.0 : -2.0) * kRadPerDeg;
    const JointVector seed = row->q_rad.array() + offset_rad;
    const runtime::InverseResult r =
        runtime::solveInverse(*model, ws, row->X_TrackerTip(), row->wrenchOrZero(), temp_c, seed,
                              runtime::Clock::time_point::max());
    std::printf("I %d", int(r.status));
    for (int k = 0; k < r.q_target_rad.size(); ++k) std::printf(" %.17g", r.q_target_rad(k));
    std::printf(" %d\n", r.iterations);
  }
  return 0;
}

// The consumer of tests/system/install_consumer.sh: one forward correction with a model file, at a
// measured campaign row, checked against the pose the tracker measured there.
//
//   consumer MODEL q1 … q6 (rad) fx fy fz mx my mz (N, N·m) x y z (m)
//
// Exit status 0 when the call is OK and lands within 0.5 mm of the measured position (the twin's
// campaigns validate at ~0.02 mm; the nominal robot is millimetres off), 1 otherwise, 2 on bad
// arguments.
#include <cstdio>
#include <cstdlib>

#include <stepcal/runtime/corrector.hpp>

int main(int argc, char** argv) {
  if (argc != 17) {
    std::fprintf(stderr, "usage: consumer MODEL q1..q6 fx fy fz mx my mz x y z\n");
    return 2;
  }
  using namespace stepcal;
  const auto model = runtime::RuntimeModel::load(argv[1]);
  runtime::Workspace ws = runtime::makeWorkspace(*model);
  JointVector q_rad(6);
  Vec6 wrench_Sensor;
  Vec3 p_measured_m;
  for (int i = 0; i < 6; ++i) q_rad(i) = std::atof(argv[2 + i]);
  for (int i = 0; i < 6; ++i) wrench_Sensor(i) = std::atof(argv[8 + i]);
  for (int i = 0; i < 3; ++i) p_measured_m(i) = std::atof(argv[14 + i]);
  const runtime::ForwardResult r =
      runtime::correctForward(*model, ws, q_rad, wrench_Sensor, runtime::kUnknownTemperature_c);
  const double error_m = (r.X_TrackerTip.translation() - p_measured_m).norm();
  std::printf("consumer: correctForward %s, %.4f mm from the measured position\n",
              runtime::toString(r.status), error_m * 1e3);
  return r.status == runtime::Status::kOk && error_m < 0.5e-3 ? 0 : 1;
}

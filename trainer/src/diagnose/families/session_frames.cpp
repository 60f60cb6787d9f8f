// session_frames: a later campaign's own station and tool (families.hpp). Fitted with the
// campaigns, not screened: only its fit here.
#include "families.hpp"

namespace stepcal::trainer::diagnosis {

const KindFit& sessionFramesFit() {
  static const KindFit fit = [] {
    KindFit f{MechanismKind::kSessionFrames};
    f.typical_step = [](const Mechanism&, int) { return 1e-5; };  // m or rad of a station or tool
    return f;
  }();
  return fit;
}

}  // namespace stepcal::trainer::diagnosis

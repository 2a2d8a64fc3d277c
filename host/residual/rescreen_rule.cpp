// When the residual loop screens the dictionary again (see rescreen_rule.hpp).
#include "host/residual/rescreen_rule.hpp"

namespace btsm::residual {

ScreenAgain screen_again(const BaseMove& m, double far_below_ratio) {
  if (!m.replaced) return ScreenAgain::No;
  if (m.repolished_rms_k <= far_below_ratio * m.base_fit_rms_k) return ScreenAgain::FarBelow;
  if (m.base_fit_restarted) return ScreenAgain::AfterRestartedBase;
  return ScreenAgain::No;
}

}  // namespace btsm::residual

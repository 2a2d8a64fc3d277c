#pragma once
// When the residual loop screens the effect dictionary a second time (stage 6b' of
// residual_loop.hpp): the screening is a linearisation about the base fit, and when the base turns
// out to have sat in a wrong basin, it ran about the wrong model (what it proposed, and where, may
// be wrong). The re-polish (the base alone refitted from the best joint refit's base values, kept
// when better) is what shows that, in either of two ways:
//  - the re-polished base has at most `far_below_ratio` of the base fit's rms (one distorted probe
//    can drag the staged fit into such a basin);
//  - the base fit's final stage was itself kept from a restart into another basin
//    (thermal::FitResult::final_start: the staged final stage ended far above the noise floor and
//    another start reached half its rms or less), and the re-polish then replaced that base too.
//    That landscape has several basins; the restart made part of the move the first rule measures,
//    so the re-polish alone need not halve the rms again, and still the base the screening ran
//    about is not the one every candidate is judged against.
//    Effect-suite seed 31, temperature_dependent_heat rising_01: staged 1.221 K, restarted
//    0.412 K, re-polished 0.290 K (0.70x): not screened again by the first rule, `partial`
//    coupled_heat; screened again, the effect is named at its node.

namespace btsm::residual {

struct BaseMove {
  double base_fit_rms_k = 0;        // K, the base fit's rms on the fit recordings (after any restart of its final stage)
  double repolished_rms_k = 0;      // K, the re-polished base's rms on the same recordings
  bool replaced = false;            // the re-polished base replaced the base fit
  bool base_fit_restarted = false;  // the base fit's final stage was kept from a restart into another basin
};

enum class ScreenAgain {
  No,
  FarBelow,            // the re-polished base has at most far_below_ratio of the base fit's rms
  AfterRestartedBase,  // the base fit came from a restart into another basin and the re-polish replaced it
};

ScreenAgain screen_again(const BaseMove& m, double far_below_ratio = 0.5);

}  // namespace btsm::residual

#pragma once
// Statistics of a body's lift-coefficient history over the averaging window: the amplitude of
// its oscillation and the shedding period (Strouhal number St = D / (U period)).
//
// The force of a penalized body on an adaptive grid jitters from step to step (grid changes,
// acoustic waves), so two robust estimates are used: the amplitude is that of the equivalent
// sinusoid, sqrt(2) rms(Cl - mean), and a period is counted at an upward crossing of the mean
// only after the signal has dropped below mean - rms / 2 since the last counted crossing
// (hysteresis): jitter about the mean near a crossing is not taken for extra periods.
#include <optional>
#include <span>

namespace grainwave::fluid {

struct LiftStatistics {
  double mean = 0;
  double amplitude = 0;   ///< sqrt(2) rms(Cl - mean)
  double half_range = 0;  ///< (max - min) / 2 of the samples, jitter included
  /// Mean time between counted crossings: only when the lift oscillates (amplitude above
  /// min_amplitude) and at least 2 periods were seen.
  std::optional<double> period;
  long periods = 0;
};

/// Statistics of samples lift[k] at increasing times[k] (equal lengths); a lift whose amplitude
/// is at most min_amplitude is steady (its jitter has no period).
LiftStatistics lift_statistics(std::span<const double> times, std::span<const double> lift, double min_amplitude);

}  // namespace grainwave::fluid

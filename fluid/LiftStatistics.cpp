#include "fluid/LiftStatistics.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace grainwave::fluid {

LiftStatistics lift_statistics(std::span<const double> times, std::span<const double> lift, double min_amplitude) {
  LiftStatistics s;
  const std::size_t n = std::min(times.size(), lift.size());
  if (n == 0) return s;
  const auto [low, high] = std::minmax_element(lift.begin(), lift.begin() + static_cast<std::ptrdiff_t>(n));
  s.half_range = 0.5 * (*high - *low);
  for (std::size_t i = 0; i < n; ++i) s.mean += lift[i] / static_cast<double>(n);
  double variance = 0;
  for (std::size_t i = 0; i < n; ++i) variance += (lift[i] - s.mean) * (lift[i] - s.mean) / static_cast<double>(n);
  const double rms = std::sqrt(variance);
  s.amplitude = std::sqrt(2.0) * rms;
  if (!(s.amplitude > min_amplitude)) return s;
  std::vector<double> crossings;
  bool armed = false;
  for (std::size_t i = 1; i < n; ++i) {
    armed = armed || lift[i] < s.mean - 0.5 * rms;
    if (armed && lift[i - 1] < s.mean && lift[i] >= s.mean) {
      crossings.push_back(times[i - 1] + (s.mean - lift[i - 1]) / (lift[i] - lift[i - 1]) * (times[i] - times[i - 1]));
      armed = false;
    }
  }
  if (crossings.size() >= 3) {
    s.periods = static_cast<long>(crossings.size() - 1);
    s.period = (crossings.back() - crossings.front()) / static_cast<double>(s.periods);
  }
  return s;
}

}  // namespace grainwave::fluid

#pragma once
// Polydisperse particle sizes (002 §3.4 and Table 3.1): diameters drawn from a Gaussian of mean
// D and standard deviation σ cut at ±2σ (D = 115.5 ± 4.75 µm for the curtain beads, 3 mm ± 2.13 %
// for the channel). Values outside the cut are drawn again, so the distribution is the
// truncated Gaussian rather than one with spikes at the cut.
#include <random>

namespace grainwave::particles::dem {

class TruncatedGaussianDiameter {
 public:
  TruncatedGaussianDiameter(double mean, double standard_deviation)
      : mean_(mean), sigma_(standard_deviation) {}

  template <class Engine>
  double operator()(Engine& engine) const {
    if (sigma_ <= 0.0) return mean_;
    std::normal_distribution<double> normal(0.0, 1.0);
    double z = normal(engine);
    while (z < -2.0 || z > 2.0) z = normal(engine);
    return mean_ + sigma_ * z;
  }
  double largest() const { return mean_ + 2.0 * sigma_; }
  double smallest() const { return mean_ - 2.0 * sigma_; }

 private:
  double mean_, sigma_;
};

}  // namespace grainwave::particles::dem

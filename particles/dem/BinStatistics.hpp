#pragma once
// Time-averaged statistics of a granular flow in rectangular bins of the x–y plane, averaged
// over the depth z (002 §3.3.3, Figs 3.6 and 3.10–3.15). Each sample adds, per bin b with
// centres of N_b particles inside,
//   Σ V_p (solid volume, the particle counted whole in the bin of its centre), Σ u, Σ v, Σ u², Σ v²
// and the time averages are
//   β = Σ_samples Σ V_p / (S V_bin),  ⟨u⟩ = Σu / Σ N_b,  u′ = sqrt(Σu²/ΣN_b − ⟨u⟩²)  (same for v),
// with S the number of samples. The velocities are either the instantaneous ones or, as in the
// experiments' particle tracking at 30 fps, the displacement over one camera interval divided by
// that interval (a particle counts only when it was present at both ends of the interval).
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace grainwave::particles::dem {

class BinStatistics {
 public:
  struct Layout {
    std::array<double, 2> lo{0, 0}, hi{1, 1};  ///< x–y extent of the bins
    std::array<long, 2> count{1, 1};           ///< bins along x and y
    double depth = 1.0;                        ///< z extent the bins average over (1 in 2D)
  };
  BinStatistics() = default;
  explicit BinStatistics(const Layout& layout);

  /// Adds one sample. `velocity` holds one velocity per slot of `store` (instantaneous or from
  /// displacements); slots with `use[i] == 0` are skipped.
  void add_sample(const ParticleStore& store, int dimension, const std::vector<Vec3>& velocity,
                  const std::vector<std::uint8_t>& use);

  const Layout& layout() const { return layout_; }
  long samples() const { return samples_; }
  std::size_t bins() const { return count_.size(); }
  double bin_centre(int axis, long index) const;

  // Time averages per bin (index = iy * nx + ix); zero where no particle was seen.
  double beta(std::size_t b) const;
  double mean_u(std::size_t b) const;
  double mean_v(std::size_t b) const;
  double rms_u(std::size_t b) const;
  double rms_v(std::size_t b) const;
  double particle_count(std::size_t b) const { return count_[b]; }

  /// "x,y,beta,u_mean,v_mean,u_rms,v_rms,count" rows.
  std::string csv() const;

  /// Raw accumulators (6 per bin) and the sample count, for checkpoints.
  std::vector<double> raw() const;
  void restore(long samples, const std::vector<double>& raw);

 private:
  Layout layout_;
  long samples_ = 0;
  std::vector<double> count_, volume_, su_, sv_, suu_, svv_;
};

/// Volume of a sphere (3D) or area of a disk (2D, unit depth) of radius r.
double particle_volume(int dimension, double r);

}  // namespace grainwave::particles::dem

#pragma once
// Verlet neighbour list with a skin (the standard companion of linked cells, e.g. Allen &
// Tildesley): pairs closer than r_i + r_j + skin are collected with LinkedCells and reused until
// some particle has moved more than skin/2 since the build, so no pair can come into contact
// unseen. This removes the cell sort and most distance tests from steps between rebuilds. The
// list is also rebuilt when the slots hold different particles (ids compared), so adding,
// removing or reordering particles can never use a stale list.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/dem/LinkedCells.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace grainwave::particles::dem {

class VerletList {
 public:
  /// True when build() is needed before the next search.
  bool stale(const ParticleStore& store, const Domain& domain) const;
  /// Collects the pairs within r_i + r_j + skin; cells must be at least 2 r_max + skin wide.
  void build(const ParticleStore& store, const Domain& domain, double cell_width, double skin);

  /// Calls f(i, j, d, |d|²) for every listed pair that overlaps now (d = x_j − x_i, minimum image).
  template <class PairFunction>
  void for_each_touching_pair(const ParticleStore& store, PairFunction&& f) const {
    const Vec3* x = store.position.data();
    const double* r = store.radius.data();
    for (const auto& [i, j] : pairs_) {
      Vec3 d = x[j] - x[i];
      for (int k = 0; k < 3; ++k) {
        if (d[k] > half_period_[k]) d[k] -= period_[k];
        else if (d[k] < -half_period_[k]) d[k] += period_[k];
      }
      const double reach = r[i] + r[j];
      const double distance2 = d.squaredNorm();
      if (distance2 < reach * reach) f(i, j, d, distance2);
    }
  }

  std::size_t pair_count() const { return pairs_.size(); }
  long builds() const { return builds_; }

 private:
  LinkedCells cells_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs_;
  std::vector<Vec3> reference_;
  std::vector<std::int64_t> ids_;
  double skin_ = -1.0;
  Vec3 period_ = Vec3::Zero();
  Vec3 half_period_ = Vec3::Zero();
  long builds_ = 0;
};

}  // namespace grainwave::particles::dem

#pragma once
// Verlet neighbour list with a skin (the standard companion of linked cells, e.g. Allen &
// Tildesley): pairs closer than r_i + r_j + skin are collected with LinkedCells and reused until
// some particle has moved more than skin/2 since the build, so no pair can come into contact
// unseen. This removes the cell sort and most distance tests from steps between rebuilds.
//
// Two ways to decide when to rebuild:
//   stale()        at each evaluation, from the positions of that moment (the list manages
//                  itself; also rebuilt when the slots hold different particles, ids compared,
//                  so adding, removing or reordering particles never uses a stale list);
//   stale_ahead()  once per step, before it, from the positions the step will evaluate at (the
//                  caller's prediction). A domain-decomposed run needs this: ghosts and
//                  migration may only change between steps, and every rank must rebuild at the
//                  same steps as the serial run for the forces to stay bitwise equal.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/dem/LinkedCells.hpp"

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace grainwave::particles::dem {

class VerletList {
 public:
  /// What stale_ahead() found.
  static constexpr long kValid = -1;
  static constexpr long kOtherSlots = -2;  ///< never built, or the slots hold other particles
  static constexpr std::size_t kAllOwned = static_cast<std::size_t>(-1);

  /// True when build() is needed before the next search.
  bool stale(const ParticleStore& store, const Domain& domain) const;
  /// kValid if the list serves every evaluation of the coming step: the first `owned` slots hold
  /// the particles they held at the build, and each of them, at its position now and at
  /// position + ahead[i], lies within skin/2 of where it was at the build. Otherwise
  /// kOtherSlots or the first slot that moves too far. Displacements are minimum images across
  /// the periodic axes of the build's domain.
  long stale_ahead(const ParticleStore& store, std::size_t owned, std::span<const Vec3> ahead) const;
  /// Collects the pairs within r_i + r_j + skin; cells must be at least 2 r_max + skin wide.
  /// `grid_particles` and `visit_order` as in LinkedCells::build (a decomposed run's rank
  /// passes them to list the pairs in the serial order); the first `owned` slots are the
  /// rank's own, the rest ghosts. Pairs that can never interact are left out: two ghosts
  /// (another rank's pair) and two fixed particles.
  void build(const ParticleStore& store, const Domain& domain, double cell_width, double skin,
             std::size_t grid_particles = 0, const std::vector<std::uint32_t>* visit_order = nullptr,
             std::size_t owned = kAllOwned);
  /// The next stale()/stale_ahead() asks for a build.
  void invalidate() { skin_ = -1.0; }

  /// Calls f(i, j, d, |d|², k) for every listed pair that overlaps now (d = x_j − x_i, minimum
  /// image; k the pair's index in the list, fixed until the next build).
  template <class PairFunction>
  void for_each_touching_pair(const ParticleStore& store, PairFunction&& f) const {
    const Vec3* x = store.position.data();
    const double* r = store.radius.data();
    const auto count = static_cast<std::uint32_t>(pairs_.size());
    for (std::uint32_t k = 0; k < count; ++k) {
      const auto [i, j_and_flag] = pairs_[k];
      const std::uint32_t j = j_and_flag & kSlotMask;
      Vec3 d = x[j] - x[i];
      // Only a pair flagged at the build can need its image (see pairs_); for the others the
      // minimum image would return d itself, so the result is the same to the bit.
      if (j_and_flag & kMayWrap) d = minimum_image(d);
      const double reach = r[i] + r[j];
      const double distance2 = d.squaredNorm();
      if (distance2 < reach * reach) f(i, j, d, distance2, k);
    }
  }

  /// A separation wrapped to its minimum image across the periodic axes of the build's domain.
  Vec3 minimum_image(const Vec3& d) const { return image_(d); }

  /// Built, and its first `owned` slots hold the particles they held at the build.
  bool holds(const ParticleStore& store, std::size_t owned) const;
  /// Positions at the build, per slot.
  const std::vector<Vec3>& reference() const { return reference_; }

  std::size_t pair_count() const { return pairs_.size(); }
  /// The slots (i, j) of listed pair k.
  std::pair<std::uint32_t, std::uint32_t> pair(std::size_t k) const {
    return {pairs_[k].first, pairs_[k].second & kSlotMask};
  }
  long builds() const { return builds_; }
  double skin() const { return skin_; }

 private:
  /// The second slot of a pair carries kMayWrap when its separation may need the minimum image
  /// during the list's life. A pair goes without it when, on every periodic axis, both
  /// particles were at least `skin` inside the box at the build and their separation was at
  /// least `skin` short of half the period. Until the list is stale each particle stays within
  /// skin/2 of where it was (stale(), stale_ahead()), so neither is wrapped and the separation
  /// stays under half the period: its minimum image is itself. This saves the image of most
  /// pairs (about a quarter of the listed-pair loop's instructions on the dense bench bed).
  static constexpr std::uint32_t kMayWrap = 1u << 31;
  static constexpr std::uint32_t kSlotMask = kMayWrap - 1;
  LinkedCells cells_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs_;
  std::vector<Vec3> reference_;
  std::vector<std::int64_t> ids_;
  std::size_t owned_ = 0;
  double skin_ = -1.0;
  Domain::MinimumImage image_;  ///< the build's domain's
  long builds_ = 0;
};

}  // namespace grainwave::particles::dem

#include "particles/dem/VerletList.hpp"

#include <algorithm>
#include <limits>

namespace grainwave::particles::dem {

bool VerletList::stale(const ParticleStore& store, const Domain& domain) const {
  const std::size_t n = store.size();
  if (skin_ < 0.0 || n != ids_.size()) return true;
  if (!std::equal(ids_.begin(), ids_.end(), store.id.begin())) return true;
  const double limit2 = 0.25 * skin_ * skin_;
  for (std::size_t i = 0; i < n; ++i)
    if (domain.separation(reference_[i], store.position[i]).squaredNorm() > limit2) return true;
  return false;
}

bool VerletList::holds(const ParticleStore& store, std::size_t owned) const {
  return skin_ >= 0.0 && owned == owned_ && owned <= store.size() &&
         std::equal(ids_.begin(), ids_.begin() + static_cast<std::ptrdiff_t>(owned), store.id.begin());
}

long VerletList::stale_ahead(const ParticleStore& store, std::size_t owned, std::span<const Vec3> ahead) const {
  if (!holds(store, owned) || ahead.size() < owned) return kOtherSlots;
  // A hair inside skin/2: the step's own arithmetic may land its positions an ulp away from
  // the caller's prediction.
  const double half = 0.5 * skin_ * (1.0 - 1e-9);
  const double limit2 = half * half;
  auto moved2 = [this](const Vec3& from, const Vec3& to) { return minimum_image(to - from).squaredNorm(); };
  // Every step asks this of every particle, and almost always the answer is no: chunks are
  // tested without an early exit, and only a chunk with a particle beyond the limit is searched
  // again for the first one.
  constexpr std::size_t kChunk = 512;
  const Vec3* x = store.position.data();
  for (std::size_t begin = 0; begin < owned; begin += kChunk) {
    const std::size_t end = std::min(owned, begin + kChunk);
    int beyond = 0;
    for (std::size_t i = begin; i < end; ++i) {
      const Vec3 next = x[i] + ahead[i];
      beyond |= static_cast<int>(moved2(reference_[i], x[i]) > limit2) |
                static_cast<int>(moved2(reference_[i], next) > limit2);
    }
    if (!beyond) continue;
    for (std::size_t i = begin; i < end; ++i)
      if (moved2(reference_[i], x[i]) > limit2 || moved2(reference_[i], x[i] + ahead[i]) > limit2)
        return static_cast<long>(i);
  }
  return kValid;
}

void VerletList::build(const ParticleStore& store, const Domain& domain, double cell_width,
                       double skin, std::size_t grid_particles,
                       const std::vector<std::uint32_t>* visit_order, std::size_t owned) {
  skin_ = skin;
  ++builds_;
  for (int k = 0; k < 3; ++k) {
    const bool wraps = k < domain.dimension && domain.periodic(k);
    period_[k] = wraps ? domain.hi[k] - domain.lo[k] : 0.0;
    half_period_[k] = wraps ? 0.5 * period_[k] : std::numeric_limits<double>::infinity();
  }
  reference_.assign(store.position.begin(), store.position.end());
  ids_.assign(store.id.begin(), store.id.end());
  owned_ = std::min(owned, store.size());
  pairs_.clear();
  cells_.build(store, domain, cell_width, grid_particles, visit_order);
  const auto first_ghost = static_cast<std::uint32_t>(owned_);
  cells_.for_each_pair_within(skin, [&](std::uint32_t i, std::uint32_t j, const Vec3&, double) {
    if ((i >= first_ghost && j >= first_ghost) || (store.is_fixed(i) && store.is_fixed(j))) return;
    pairs_.emplace_back(i, j);
  });
}

}  // namespace grainwave::particles::dem

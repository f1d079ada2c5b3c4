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

void VerletList::build(const ParticleStore& store, const Domain& domain, double cell_width,
                       double skin) {
  skin_ = skin;
  ++builds_;
  for (int k = 0; k < 3; ++k) {
    const bool wraps = k < domain.dimension && domain.periodic(k);
    period_[k] = wraps ? domain.hi[k] - domain.lo[k] : 0.0;
    half_period_[k] = wraps ? 0.5 * period_[k] : std::numeric_limits<double>::infinity();
  }
  reference_.assign(store.position.begin(), store.position.end());
  ids_.assign(store.id.begin(), store.id.end());
  pairs_.clear();
  cells_.build(store, domain, cell_width);
  cells_.for_each_pair_within(skin, [&](std::uint32_t i, std::uint32_t j, const Vec3&, double) {
    pairs_.emplace_back(i, j);
  });
}

}  // namespace grainwave::particles::dem

#include "particles/dem/VerletList.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

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
  // Every step asks this of every particle, and almost always the answer is no. The minimum
  // image is taken only for a particle beyond the limit without it (one that wrapped since the
  // build): no component of the image is longer than the plain difference's, and rounding is
  // monotone, so within the limit without it means within it with it.
  const Vec3* x = store.position.data();
  for (std::size_t i = 0; i < owned; ++i) {
    const Vec3 now = x[i] - reference_[i];
    const Vec3 next = (x[i] + ahead[i]) - reference_[i];
    if (now.squaredNorm() > limit2 || next.squaredNorm() > limit2) [[unlikely]] {
      if (minimum_image(now).squaredNorm() > limit2 || minimum_image(next).squaredNorm() > limit2)
        return static_cast<long>(i);
    }
  }
  return kValid;
}

void VerletList::build(const ParticleStore& store, const Domain& domain, double cell_width,
                       double skin, std::size_t grid_particles,
                       const std::vector<std::uint32_t>* visit_order, std::size_t owned) {
  skin_ = skin;
  ++builds_;
  image_ = domain.minimum_image();
  reference_.assign(store.position.begin(), store.position.end());
  ids_.assign(store.id.begin(), store.id.end());
  owned_ = std::min(owned, store.size());
  pairs_.clear();
  if (store.size() > kSlotMask)
    throw std::length_error("VerletList: more than 2^31 - 1 slots (the top bit of a pair flags its image)");
  cells_.build(store, domain, cell_width, grid_particles, visit_order);
  // Per periodic axis, where a particle must lie for its coming motion never to wrap it.
  Vec3 inner_lo = Vec3::Constant(-std::numeric_limits<double>::infinity());
  Vec3 inner_hi = Vec3::Constant(std::numeric_limits<double>::infinity());
  for (int k = 0; k < 3; ++k)
    if (image_.period[static_cast<std::size_t>(k)] > 0.0) {
      inner_lo[k] = domain.lo[k] + skin;
      inner_hi[k] = domain.hi[k] - skin;
    }
  auto stays_inside = [&](const Vec3& x) {
    return (x.array() >= inner_lo.array()).all() && (x.array() <= inner_hi.array()).all();
  };
  const Vec3 separation_limit = Vec3(image_.half[0], image_.half[1], image_.half[2]) -
                                Vec3::Constant(skin);  // infinite where not periodic
  const auto first_ghost = static_cast<std::uint32_t>(owned_);
  cells_.for_each_pair_within(skin, [&](std::uint32_t i, std::uint32_t j, const Vec3&, double) {
    if ((i >= first_ghost && j >= first_ghost) || (store.is_fixed(i) && store.is_fixed(j))) return;
    const Vec3& xi = reference_[i];
    const Vec3& xj = reference_[j];
    const bool image_free = stays_inside(xi) && stays_inside(xj) &&
                            ((xj - xi).cwiseAbs().array() <= separation_limit.array()).all();
    pairs_.emplace_back(i, image_free ? j : (j | kMayWrap));
  });
  if (pairs_.size() >= 0xffffffffu) throw std::length_error("VerletList: 2^32 - 1 pairs or more (pairs are indexed by 32 bits)");
}

}  // namespace grainwave::particles::dem

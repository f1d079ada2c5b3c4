#include "particles/dem/ContactForceField.hpp"

#include "core/Error.hpp"
#include "particles/dem/ContactLanes.hpp"
#include "particles/dem/CoulombSpring.hpp"
#include "particles/dem/HertzNormal.hpp"
#include "particles/dem/LinearSpringDashpot.hpp"
#include "particles/dem/Mindlin.hpp"
#include "particles/dem/StaticFriction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace grainwave::particles::dem {

ContactForceField::ContactForceField(ContactModel model, const Domain& domain,
                                     ContactForceSettings settings)
    : model_(std::move(model)), domain_(domain), settings_(std::move(settings)) {
  if (!model_.normal || !model_.tangential)
    throw InputError({"contact model", 0}, "law", "needs both a normal and a tangential law");
  plane_walls_ = walls_from_domain(domain_);
}

template <bool kWithEffectiveRadius>
[[gnu::always_inline]] inline bool ContactForceField::particle_contact(const ParticleStore& store, std::uint32_t i, std::uint32_t j,
                                         const Vec3& d, double distance2, Contact& c) const {
  const double inverse_mass_sum = inverse_mass_[i] + inverse_mass_[j];
  if (inverse_mass_sum == 0.0 || distance2 == 0.0) return false;  // fixed pairs never interact
  if (has_ghosts_ && i >= owned_end_ && j >= owned_end_) return false;  // another rank's pair
  const double distance = std::sqrt(distance2);
  const double ri = store.radius[i], rj = store.radius[j];
  c.i = i;
  c.partner = j;
  c.is_wall = false;
  c.normal = d * (1.0 / distance);
  c.overlap = ri + rj - distance;
  const Vec3 spin = ri * store.angular_velocity[i] + rj * store.angular_velocity[j];
  c.relative_velocity = (store.velocity[j] - store.velocity[i]) - spin.cross(c.normal);
  c.effective_mass = 1.0 / inverse_mass_sum;
  c.effective_radius = kWithEffectiveRadius ? effective_radius(ri, rj) : std::numeric_limits<double>::quiet_NaN();
  c.history = nullptr;
  return true;
}

void ContactForceField::wall_contact(const ParticleStore& store, std::size_t i, std::size_t wall_index,
                                     const Vec3& wall_velocity, const Vec3& normal, double overlap,
                                     Contact& c) const {
  c.i = static_cast<std::uint32_t>(i);
  c.partner = static_cast<std::uint32_t>(wall_index);
  c.list_index = Contact::kNotListed;
  c.is_wall = true;
  c.normal = normal;
  c.overlap = overlap;
  c.relative_velocity = (wall_velocity - store.velocity[i]) -
                        (store.radius[i] * store.angular_velocity[i]).cross(normal);
  c.effective_mass = store.mass[i];
  c.effective_radius = store.radius[i];
  c.history = nullptr;
}

void ContactForceField::external_forces(const ParticleStore& store) {
  const std::size_t n = store.size();
  force_.resize(n);
  torque_.resize(n);
  // Through local pointers (Eigen's vector stores may alias anything: the compiler would load
  // every address again after each).
  Vec3* const force = force_.data();
  Vec3* const torque = torque_.data();
  for (std::size_t i = owned_end_; i < n; ++i) {  // ghosts: their owner sums their forces
    force[i].setZero();
    torque[i].setZero();
  }
  const Vec3 gravity = settings_.gravity;
  const std::span<const RecyclingDragZone> zones(settings_.drag_zones);
  const Vec3* const external_force = store.force.data();
  const Vec3* const external_torque = store.torque.data();
  const double* const mass = store.mass.data();
  for (std::size_t i = 0; i < owned_end_; ++i) {
    force[i] = external_force[i] + mass[i] * gravity;
    torque[i] = external_torque[i];
    for (const RecyclingDragZone& zone : zones)
      if (zone.contains(store.position[i]))
        force[i] += recycling_drag(zone.coefficient_per_mass, mass[i], store.velocity[i]);
  }
}

[[gnu::always_inline]] inline void ContactForceField::apply(const ParticleStore& store, const Contact& c) {
  const Vec3 on_i = c.tangential_force - c.normal_force * c.normal;
  const Vec3 lever_cross_ft = c.normal.cross(c.tangential_force);
  force_[c.i] += on_i;
  torque_[c.i] += store.radius[c.i] * lever_cross_ft;
  if (!c.is_wall) {
    force_[c.partner] -= on_i;
    torque_[c.partner] += store.radius[c.partner] * lever_cross_ft;
  }
}

[[gnu::always_inline]] inline void ContactForceField::note_depth(const ParticleStore& store, const Contact& c) {
  // A pair of an owned particle and a ghost is found on both ranks: the rank owning the smaller
  // id counts it, so the counts of all ranks add up to the serial count.
  if (!has_ghosts_ || c.is_wall || (c.i < owned_end_ && c.partner < owned_end_)) {
    ++contact_count_;
  } else {
    const bool i_owned = c.i < owned_end_;
    const std::int64_t owned_id = store.id[i_owned ? c.i : c.partner];
    const std::int64_t ghost_id = store.id[i_owned ? c.partner : c.i];
    if (owned_id < ghost_id) ++contact_count_;
  }
  // Compared without a division per contact (the quotient is formed only for a new deepest).
  const double r = c.is_wall ? store.radius[c.i] : std::min(store.radius[c.i], store.radius[c.partner]);
  if (c.overlap > deepest_.overlap_over_radius * r) {
    const double depth = c.overlap / r;
    if (depth > deepest_.overlap_over_radius)
      deepest_ = DeepestContact{depth, c.i, c.partner, c.is_wall, store.id[c.i]};
  }
}

// Flattened: the pair test, the contact's geometry and the caller's force law become one loop
// body, so the contact's fields stay in registers and consecutive contacts' long-latency
// chains (square roots, divisions) overlap (12 % fewer instructions for the dense bed). Not
// under AddressSanitizer, whose instrumentation of the flattened bodies takes the compiler
// many minutes; the arithmetic, and so every result, is the same either way.
#if defined(__SANITIZE_ADDRESS__)
#define GRAINWAVE_FLATTEN
#else
#define GRAINWAVE_FLATTEN [[gnu::flatten]]
#endif
template <bool kWithEffectiveRadius, class ContactFunction>
GRAINWAVE_FLATTEN void ContactForceField::for_each_contact(const ParticleStore& store, ContactFunction&& f) {
  Contact c;
  auto pair = [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2,
                  std::uint32_t list_index = Contact::kNotListed) {
    if (!particle_contact<kWithEffectiveRadius>(store, i, j, d, distance2, c)) return;
    c.list_index = list_index;
    f(c);
  };
  if (use_list_) verlet_.for_each_touching_pair(store, pair);
  else cells_.for_each_touching_pair(pair);
  for_each_wall_contact(store, c, f);
}

bool ContactForceField::refresh_wall_candidates(const ParticleStore& store) {
  if (!use_list_) return false;
  const std::size_t walls = plane_walls_.size() + finite_walls_.size();
  if (wall_candidates_build_ == verlet_.builds() && wall_candidates_owned_ == owned_end_ &&
      wall_candidates_walls_ == walls)
    return true;
  const double skin = verlet_.skin();
  const std::size_t n = owned_end_;
  // Particles within the skin of a periodic face may wrap to the far side: candidates of every
  // wall (a wall has no periodic image; the particle's position is what it is tested at).
  std::vector<char> near_periodic_face(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < domain_.dimension; ++k) {
      const double x = store.position[i][k];
      if (domain_.periodic(k) && (x - domain_.lo[k] <= skin || domain_.hi[k] - x <= skin)) near_periodic_face[i] = 1;
    }
  wall_candidates_.clear();
  wall_begin_.assign(1, 0);
  // Fixed particles too: one may be released before the next build (the visit skips it while
  // it is fixed).
  auto take_where = [&](auto&& near_wall) {
    for (std::size_t i = 0; i < n; ++i)
      if (near_periodic_face[i] || near_wall(i)) wall_candidates_.push_back(static_cast<std::uint32_t>(i));
    wall_begin_.push_back(wall_candidates_.size());
  };
  for (const PlaneWall& wall : plane_walls_)
    take_where([&](std::size_t i) { return wall.distance(store.position[i]) - store.radius[i] <= skin; });
  for (const FiniteWall& wall : finite_walls_)
    take_where([&](std::size_t i) {
      const double reach = store.radius[i] + skin;
      return (wall.closest_point(store.position[i]) - store.position[i]).squaredNorm() <= reach * reach;
    });
  wall_candidates_build_ = verlet_.builds();
  wall_candidates_owned_ = owned_end_;
  wall_candidates_walls_ = walls;
  return true;
}

template <class ContactFunction>
void ContactForceField::for_each_wall_contact(const ParticleStore& store, Contact& c, ContactFunction&& f) {
  const std::size_t n = owned_end_;  // walls act on owned particles only
  const bool listed = refresh_wall_candidates(store);
  // Every particle in slot order, or the wall's candidates (ascending slots, so the contacts
  // come in the same order and every force sums alike).
  auto for_each_particle_near = [&](std::size_t wall, auto&& visit) {
    if (listed) {
      for (std::size_t k = wall_begin_[wall]; k < wall_begin_[wall + 1]; ++k) visit(wall_candidates_[k]);
    } else {
      for (std::size_t i = 0; i < n; ++i) visit(i);
    }
  };
  for (std::size_t w = 0; w < plane_walls_.size(); ++w) {
    const PlaneWall& wall = plane_walls_[w];
    if (!wall.enabled) continue;
    for_each_particle_near(w, [&](std::size_t i) {
      if (store.is_fixed(i)) return;
      const double overlap = store.radius[i] - wall.distance(store.position[i]);
      if (overlap <= 0.0) return;
      wall_contact(store, i, w, wall.velocity, -wall.normal, overlap, c);
      f(c);
    });
  }
  for (std::size_t w = 0; w < finite_walls_.size(); ++w) {
    const FiniteWall& wall = finite_walls_[w];
    if (!wall.enabled) continue;
    for_each_particle_near(plane_walls_.size() + w, [&](std::size_t i) {
      if (store.is_fixed(i)) return;
      const Vec3 p = wall.closest_point(store.position[i]);
      const Vec3 d = p - store.position[i];
      const double distance2 = d.squaredNorm();
      const double r = store.radius[i];
      if (distance2 >= r * r || distance2 == 0.0) return;
      const double distance = std::sqrt(distance2);
      wall_contact(store, i, plane_walls_.size() + w, wall.velocity, d / distance, r - distance, c);
      f(c);
    });
  }
}

// Inlined into the batched pass's walk, whose pointers would otherwise all be loaded again
// after the call.
[[gnu::always_inline]] inline ContactHistoryEntry* ContactForceField::touch_listed_history(std::int64_t a, std::int64_t b,
                                                                                     std::uint32_t list_index) {
  return list_index < history_.pinned_count() ? history_.touch_pinned(list_index, a, b) : history_.touch(a, b);
}

void ContactForceField::touch_history(const ParticleStore& store, Contact& c) {
  if (!c.is_wall && store.id[c.i] > store.id[c.partner]) {
    // Canonical orientation (see the header): the same contact seen from the other side.
    std::swap(c.i, c.partner);
    c.normal = -c.normal;
    c.relative_velocity = -c.relative_velocity;
  }
  const std::int64_t other = c.is_wall ? ContactHistory::wall_key(c.partner) : store.id[c.partner];
  c.history = touch_listed_history(store.id[c.i], other, c.list_index);
}

template <class TangentialLanes>
void ContactForceField::add_listed_pairs_linear(const ParticleStore& store, const LinearSpringDashpot& normal,
                                                const TangentialLanes& tangential) {
  using namespace lanes;
  constexpr bool keeps_history = TangentialLanes::kKeepsHistory;
  const int width = lane_width_for(TangentialLanes::kPreferredWidth);
  const LaneInputs in{store.velocity.data(), store.angular_velocity.data(), store.radius.data(),
                      inverse_mass_.data(), normal.stiffness(), normal.damping_factor()};
  const double* radius = store.radius.data();
  PairBatch b;
  auto flush = [&] {
    // Pad with copies of the first contact (kSize is a multiple of every width: a full batch
    // needs none, which the bound says to the compiler).
    for (int k = b.count; k % width != 0 && k < PairBatch::kSize; ++k) {
      b.i[k] = b.i[0];
      b.j[k] = b.j[0];
      b.dx[k] = b.dx[0];
      b.dy[k] = b.dy[0];
      b.dz[k] = b.dz[0];
      b.distance2[k] = b.distance2[0];
      if constexpr (keeps_history) {
        b.orientation[k] = b.orientation[0];
        b.entry[k] = &b.pad_entry;  // not the first contact's: it may have been advanced already
      }
    }
    batch_lane_forces(width, b, (b.count + width - 1) / width * width, in, tangential);
    Contact c;  // for note_depth
    c.is_wall = false;
    // apply() coefficient by coefficient: the same sums, but as plain double stores, which the
    // compiler knows cannot move the arrays (Eigen's vector stores may alias anything, so after
    // each one every pointer in reach was loaded again).
    Vec3* const force = force_.data();
    Vec3* const torque = torque_.data();
    for (int k = 0; k < b.count; ++k) {
      std::uint32_t i = b.i[k], j = b.j[k];
      if constexpr (keeps_history)
        if (b.orientation[k] < 0.0) std::swap(i, j);
      const double on_i[3] = {b.fx[k], b.fy[k], b.fz[k]};
      const double lever[3] = {b.lx[k], b.ly[k], b.lz[k]};
      const double ri = radius[i], rj = radius[j];
      for (int a = 0; a < 3; ++a) {
        force[i][a] += on_i[a];
        torque[i][a] += ri * lever[a];
        force[j][a] -= on_i[a];
        torque[j][a] += rj * lever[a];
      }
      c.i = i;
      c.partner = j;
      c.overlap = b.overlap[k];
      note_depth(store, c);
    }
    b.count = 0;
  };
  const double* inverse_mass = inverse_mass_.data();
  const std::int64_t* id = store.id.data();
  verlet_.for_each_touching_pair(store, [&](std::uint32_t i, std::uint32_t j, const Vec3& d, double distance2,
                                            std::uint32_t list_index) {
    // The pairs particle_contact turns away (the list holds no pair of two ghosts).
    if (inverse_mass[i] + inverse_mass[j] == 0.0 || distance2 == 0.0) return;
    if constexpr (keeps_history) {
      // Entries move when room is made: the batch's entries are used up first.
      if (history_.nearly_full()) {
        if (b.count > 0) flush();
        history_.make_room();
      }
    }
    const int k = b.count++;
    b.i[k] = i;
    b.j[k] = j;
    b.dx[k] = d.x();
    b.dy[k] = d.y();
    b.dz[k] = d.z();
    b.distance2[k] = distance2;
    if constexpr (keeps_history) {
      const bool reversed = id[i] > id[j];
      b.orientation[k] = reversed ? -1.0 : 1.0;
      const std::int64_t first = reversed ? id[j] : id[i], second = reversed ? id[i] : id[j];
      b.entry[k] = touch_listed_history(first, second, list_index);
    }
    if (b.count == PairBatch::kSize) flush();
  });
  if (b.count > 0) flush();
}

template <class Normal, class Tangential>
void ContactForceField::evaluate_fused(const ParticleStore& store, const Normal& normal,
                                       const Tangential& tangential, HistoryStage stage, double dt) {
  // The batched path adds the external forces first and then the contacts in list order, which
  // is the order they are found in: the same sums in the same order here. A history law's
  // entry is looked up and advanced where the contact is found; each contact uses its entry
  // at once, so room can be made between contacts (entries move, none is held).
  constexpr bool keeps_history = !std::is_same_v<Tangential, StaticFriction>;
  if constexpr (keeps_history) history_.prepare();
  external_forces(store);
  auto contact_forces = [&](Contact& c) {
    if constexpr (keeps_history) {
      if (history_.nearly_full()) history_.make_room();
      touch_history(store, c);
    }
    c.normal_force = normal.force(c);
    if constexpr (keeps_history) advance_history(tangential, c, stage, dt);
    else c.tangential_force = tangential.force(c);
    note_depth(store, c);
    apply(store, c);
  };
  if constexpr (std::is_same_v<Normal, LinearSpringDashpot> &&
                (std::is_same_v<Tangential, StaticFriction> || std::is_same_v<Tangential, CoulombSpring>)) {
    if (use_list_ && settings_.batched && (!keeps_history || stage == HistoryStage::kSingle)) {
      if constexpr (keeps_history) add_listed_pairs_linear(store, normal, lanes::CoulombSpringLanes(tangential, dt));
      else add_listed_pairs_linear(store, normal, lanes::StaticFrictionLanes(tangential));
      Contact c;
      for_each_wall_contact(store, c, contact_forces);
      return;
    }
  }
  constexpr bool reads_radius = Normal::kReadsEffectiveRadius || Tangential::kReadsEffectiveRadius;
  for_each_contact<reads_radius>(store, contact_forces);
}

template <class Normal>
bool ContactForceField::try_fused(const ParticleStore& store, const Normal& normal, HistoryStage stage,
                                  double dt) {
  const TangentialLaw* law = model_.tangential.get();
  if (const auto* friction = dynamic_cast<const StaticFriction*>(law)) {
    evaluate_fused(store, normal, *friction, stage, dt);
    return true;
  }
  if (const auto* spring = dynamic_cast<const CoulombSpring*>(law)) {
    evaluate_fused(store, normal, *spring, stage, dt);
    return true;
  }
  if (const auto* mindlin = dynamic_cast<const Mindlin*>(law)) {
    evaluate_fused(store, normal, *mindlin, stage, dt);
    return true;
  }
  return false;
}

bool lane_width_supported(int width) { return lanes::lane_width_supported(width); }

int ContactForceField::lane_width() const {
  const bool history = dynamic_cast<const CoulombSpring*>(model_.tangential.get()) != nullptr;
  return lane_width_for(history ? lanes::CoulombSpringLanes::kPreferredWidth
                                : lanes::StaticFrictionLanes::kPreferredWidth);
}

int ContactForceField::lane_width_for(int preferred) const {
  const int asked = settings_.lane_width;
  if (asked == 0) return lanes::supported_width_up_to(preferred);
  if (!lanes::lane_width_supported(asked))
    throw std::invalid_argument("ContactForceField: lane_width " + std::to_string(asked) +
                                " is not one this CPU runs (2, or 4 with AVX2, or 8 with AVX-512F)");
  return asked;
}

void ContactForceField::prepare_slots(const ParticleStore& store) {
  const std::size_t n = store.size();
  inverse_mass_.resize(n);
  for (std::size_t i = 0; i < n; ++i) inverse_mass_[i] = store.inverse_mass(i);
  owned_end_ = store.owned_size();
  has_ghosts_ = owned_end_ < n;
}

void ContactForceField::merge_visit_order(const ParticleStore& store) {
  const std::size_t n = store.size();
  if (has_ghosts_) {
    // Both ranges are in id order (SlabDecomposition keeps them so): merge them by id.
    visit_order_.resize(n);
    std::uint32_t a = 0, b = static_cast<std::uint32_t>(owned_end_);
    const auto owned = static_cast<std::uint32_t>(owned_end_), all = static_cast<std::uint32_t>(n);
    for (std::size_t k = 0; k < n; ++k)
      visit_order_[k] = (b == all || (a < owned && store.id[a] < store.id[b])) ? a++ : b++;
  }
}

double ContactForceField::search_cell_width(const ParticleStore& store, double skin) const {
  double cell_width = settings_.cell_width;
  if (cell_width <= 0.0) {
    double largest = 0.0;
    for (double r : store.radius) largest = std::max(largest, r);
    cell_width = 2.0 * largest;
  }
  return cell_width + skin;
}

long ContactForceField::list_stale_ahead(const ParticleStore& store, std::span<const Vec3> ahead) const {
  return verlet_.stale_ahead(store, store.owned_size(), ahead);
}

void ContactForceField::build_list(const ParticleStore& store) {
  prepare_slots(store);
  merge_visit_order(store);
  const double skin = std::max(settings_.verlet_skin, 0.0);
  verlet_.build(store, domain_, search_cell_width(store, skin), skin, settings_.grid_particles,
                has_ghosts_ ? &visit_order_ : nullptr, owned_end_);
}

void ContactForceField::evaluate(const ParticleStore& store, HistoryStage stage, double dt) {
  const std::size_t n = store.size();
  if (stage != HistoryStage::kCorrect) history_.begin_step();

  contacts_.clear();
  contact_count_ = 0;
  deepest_ = DeepestContact{};
  prepare_slots(store);
  if (n > 0) {
    // A self-managed list would see renewed ghosts at every evaluation: with ghosts, only a
    // caller-managed list stays valid.
    const double skin = std::max(settings_.verlet_skin, 0.0);
    use_list_ = skin > 0.0 && (settings_.verlet_managed || !has_ghosts_);
    if (use_list_ && settings_.verlet_managed) {
      if (verlet_.skin() < 0.0)
        throw std::logic_error("ContactForceField: a managed Verlet list evaluated before build_list");
    } else if (!use_list_) {
      merge_visit_order(store);
      cells_.build(store, domain_, search_cell_width(store, 0.0), settings_.grid_particles,
                   has_ghosts_ ? &visit_order_ : nullptr);
    } else if (verlet_.stale(store, domain_)) {
      verlet_.build(store, domain_, search_cell_width(store, skin), skin);
    }
    if (use_list_ && model_.tangential->needs_history() &&
        (pinned_build_ != verlet_.builds() || pinned_generation_ != history_.pin_generation())) {
      pin_keys_.resize(verlet_.pair_count());
      for (std::size_t k = 0; k < pin_keys_.size(); ++k) {
        const auto [i, j] = verlet_.pair(k);
        pin_keys_[k] = {store.id[i], store.id[j]};
      }
      history_.pin(pin_keys_);
      pinned_build_ = verlet_.builds();
      pinned_generation_ = history_.pin_generation();
    }
    if (settings_.fused) {
      if (const auto* law = dynamic_cast<const LinearSpringDashpot*>(model_.normal.get());
          law && try_fused(store, *law, stage, dt))
        return;
      if (const auto* law = dynamic_cast<const HertzNormal*>(model_.normal.get());
          law && try_fused(store, *law, stage, dt))
        return;
    }
    for_each_contact(store, [&](const Contact& c) { contacts_.push_back(c); });
  }

  if (model_.tangential->needs_history()) {
    history_.prepare();
    for (std::size_t k = 0; k < contacts_.size(); ++k) {
      if (history_.nearly_full()) {
        history_.make_room();  // entries moved: look up the contacts done so far again
        k = 0;
      }
      touch_history(store, contacts_[k]);
    }
  }
  model_.normal->evaluate(contacts_);
  model_.tangential->evaluate(contacts_, stage, dt);

  external_forces(store);
  for (const Contact& c : contacts_) {
    note_depth(store, c);
    apply(store, c);
  }
}

}  // namespace grainwave::particles::dem

#include "particles/dem/SlabDecomposition.hpp"

#include "core/Error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace grainwave::particles::dem {

namespace {
// One particle on the wire: x, v, ω, external force and torque (3 each), r, m, I, id, flags.
// Ids and flags are integers below 2^53, exact in a double.
constexpr std::size_t kParticleDoubles = 20;
// One history entry: first, second, last_step, is_new, displacement (3), stage velocity (3).
constexpr std::size_t kEntryDoubles = 10;

void pack_particle(const ParticleStore& s, std::size_t i, std::vector<double>& out) {
  const Vec3* vectors[] = {&s.position[i], &s.velocity[i], &s.angular_velocity[i], &s.force[i],
                           &s.torque[i]};
  for (const Vec3* v : vectors) out.insert(out.end(), {v->x(), v->y(), v->z()});
  out.insert(out.end(), {s.radius[i], s.mass[i], s.inertia[i], static_cast<double>(s.id[i]),
                         static_cast<double>(s.flags[i])});
}

/// Appends the particle packed at p; returns its slot.
std::size_t unpack_particle(const double* p, std::uint32_t extra_flags, ParticleStore& s) {
  auto vec = [p](int k) { return Vec3(p[3 * k], p[3 * k + 1], p[3 * k + 2]); };
  const std::size_t slot =
      s.add(static_cast<std::int64_t>(p[18]), vec(0), vec(1), vec(2), p[15], p[16], p[17],
            static_cast<std::uint32_t>(p[19]) | extra_flags);
  s.force.back() = vec(3);
  s.torque.back() = vec(4);
  return slot;
}

void pack_entry(const ContactHistoryEntry& e, std::vector<double>& out) {
  out.insert(out.end(), {static_cast<double>(e.first), static_cast<double>(e.second),
                         static_cast<double>(e.last_step), e.is_new ? 1.0 : 0.0,
                         e.displacement.x(), e.displacement.y(), e.displacement.z(),
                         e.stage_velocity.x(), e.stage_velocity.y(), e.stage_velocity.z()});
}

ContactHistoryEntry unpack_entry(const double* p) {
  ContactHistoryEntry e;
  e.first = static_cast<std::int64_t>(p[0]);
  e.second = static_cast<std::int64_t>(p[1]);
  e.last_step = static_cast<std::int64_t>(p[2]);
  e.is_new = p[3] != 0.0;
  e.displacement = Vec3(p[4], p[5], p[6]);
  e.stage_velocity = Vec3(p[7], p[8], p[9]);
  return e;
}
}  // namespace

SlabDecomposition::SlabDecomposition(const Domain& domain, int axis, std::vector<double> cuts,
                                     double reach, MPI_Comm comm)
    : domain_(domain), axis_(axis), cuts_(std::move(cuts)), reach_(reach), comm_(comm) {
  ranks_ = mpi::size(comm);
  rank_ = mpi::rank(comm);
  if (cuts_.size() != static_cast<std::size_t>(ranks_) + 1)
    throw std::logic_error("SlabDecomposition: one slab per rank");
  exchange_ = std::make_unique<mpi::Exchange>(comm);
}

namespace {
std::vector<double> moving_coordinates(const ParticleStore& store, int axis) {
  std::vector<double> s;  // the moving particles carry the work
  for (std::size_t i = 0; i < store.size(); ++i)
    if (!store.is_fixed(i) && (store.flags[i] & kGhost) == 0) s.push_back(store.position[i][axis]);
  return s;
}
}  // namespace

std::vector<double> SlabDecomposition::balanced_cuts(const Domain& domain, int axis,
                                                     const ParticleStore& store, int ranks) {
  return balanced_cuts(domain, axis, moving_coordinates(store, axis), ranks);
}

std::vector<double> SlabDecomposition::rebalanced_cuts(const ParticleStore& store) const {
  if (ranks_ == 1) return cuts_;
  // Wrapped into the box, so that a centre a hair outside a periodic face counts in its slab.
  std::vector<double> mine;
  for (std::size_t i = 0; i < store.size(); ++i)
    if (!store.is_fixed(i) && (store.flags[i] & kGhost) == 0) {
      Vec3 x = store.position[i];
      domain_.wrap(x);
      mine.push_back(x[axis_]);
    }
  return balanced_cuts(domain_, axis_, mpi::all_gather(mine, comm_), ranks_);
}

void SlabDecomposition::set_cuts(std::vector<double> cuts) {
  if (cuts.size() != cuts_.size()) throw std::logic_error("SlabDecomposition: one slab per rank");
  cuts_ = std::move(cuts);
}

std::vector<double> SlabDecomposition::balanced_cuts(const Domain& domain, int axis,
                                                     std::vector<double> s, int ranks) {
  std::sort(s.begin(), s.end());
  std::vector<double> cuts{domain.lo[axis]};
  for (int r = 1; r < ranks; ++r) {
    double cut = domain.lo[axis] + (domain.hi[axis] - domain.lo[axis]) * r / ranks;
    if (!s.empty()) {
      const std::size_t k = s.size() * static_cast<std::size_t>(r) / static_cast<std::size_t>(ranks);
      // Halfway between the neighbours of the quantile, so no centre sits on a cut.
      cut = k == 0 ? s[0] : 0.5 * (s[k - 1] + s[std::min(k, s.size() - 1)]);
    }
    cuts.push_back(std::clamp(cut, cuts.back(), domain.hi[axis]));
  }
  cuts.push_back(domain.hi[axis]);
  return cuts;
}

int SlabDecomposition::owner(const Vec3& x) const {
  if (ranks_ == 1) return 0;
  Vec3 wrapped = x;
  domain_.wrap(wrapped);
  const double s = wrapped[axis_];
  const auto upper = std::upper_bound(cuts_.begin() + 1, cuts_.end() - 1, s);
  return static_cast<int>(upper - (cuts_.begin() + 1));
}

double SlabDecomposition::distance_to_slab(double s, int r) const {
  const double a = cuts_[static_cast<std::size_t>(r)], b = cuts_[static_cast<std::size_t>(r) + 1];
  auto distance = [&](double y) { return y < a ? a - y : (y > b ? y - b : 0.0); };
  double d = distance(s);
  if (domain_.periodic(axis_)) {
    const double period = domain_.hi[axis_] - domain_.lo[axis_];
    d = std::min({d, distance(s - period), distance(s + period)});
  }
  return d;
}

void SlabDecomposition::keep_owned(ParticleStore& store) const {
  if (ranks_ == 1) return;
  std::vector<std::uint8_t> keep(store.size());
  for (std::size_t i = 0; i < store.size(); ++i) keep[i] = owner(store.position[i]) == rank_ ? 1 : 0;
  store.keep_where(keep);
}

void SlabDecomposition::strip_ghosts(ParticleStore& store) {
  store.truncate(store.owned_size());
}

void SlabDecomposition::exchange_ghosts(ParticleStore& store) {
  if (ranks_ == 1) return;
  strip_ghosts(store);
  const std::size_t owned = store.size();
  const double a = cuts_[static_cast<std::size_t>(rank_)];
  const double b = cuts_[static_cast<std::size_t>(rank_) + 1];
  exchange_->clear();
  sent_.resize(static_cast<std::size_t>(ranks_));
  for (auto& slots : sent_) slots.clear();
  for (std::size_t i = 0; i < owned; ++i) {
    const double s = store.position[i][axis_];
    // Every other slab lies outside [a, b): a centre deeper than reach is nobody's ghost.
    if (s - a >= reach_ && b - s >= reach_) continue;
    for (int r = 0; r < ranks_; ++r)
      if (r != rank_ && distance_to_slab(s, r) < reach_) {
        pack_particle(store, i, exchange_->outgoing(r));
        sent_[static_cast<std::size_t>(r)].push_back(static_cast<std::uint32_t>(i));
      }
  }
  exchange_->exchange();
  const auto& in = exchange_->incoming();
  const std::size_t arrived = in.size() / kParticleDoubles;
  for (std::size_t k = 0; k < arrived; ++k) unpack_particle(&in[k * kParticleDoubles], kGhost, store);
  ghost_of_arrival_.resize(arrived);
  std::iota(ghost_of_arrival_.begin(), ghost_of_arrival_.end(), 0u);
  // Each sender packs in id order; with more than one sender the ghosts are merged by id.
  if (!std::is_sorted(store.id.begin() + static_cast<std::ptrdiff_t>(owned), store.id.end())) {
    order_.resize(store.size());
    std::iota(order_.begin(), order_.end(), 0u);
    std::sort(order_.begin() + static_cast<std::ptrdiff_t>(owned), order_.end(),
              [&](std::uint32_t x, std::uint32_t y) { return store.id[x] < store.id[y]; });
    store.permute(order_);
    for (std::size_t g = 0; g < arrived; ++g)
      ghost_of_arrival_[order_[owned + g] - owned] = static_cast<std::uint32_t>(g);
  }
  ghosts_.clear();
  for (std::size_t g = owned; g < store.size(); ++g) ghosts_.append_from(store, g);
}

void SlabDecomposition::refresh_ghosts(ParticleStore& store) {
  if (ranks_ == 1) return;
  constexpr std::size_t kStateDoubles = 9;  // x, v, ω
  exchange_->clear();
  for (int r = 0; r < ranks_; ++r) {
    auto& out = exchange_->outgoing(r);
    for (const std::uint32_t i : sent_[static_cast<std::size_t>(r)])
      for (const Vec3* v : {&store.position[i], &store.velocity[i], &store.angular_velocity[i]})
        out.insert(out.end(), {v->x(), v->y(), v->z()});
  }
  exchange_->exchange();
  const auto& in = exchange_->incoming();
  if (in.size() != ghost_of_arrival_.size() * kStateDoubles)
    throw std::logic_error("SlabDecomposition: ghost refresh does not match the last exchange");
  for (std::size_t k = 0; k < ghost_of_arrival_.size(); ++k) {
    const double* p = &in[k * kStateDoubles];
    const std::size_t g = ghost_of_arrival_[k];
    ghosts_.position[g] = Vec3(p[0], p[1], p[2]);
    ghosts_.velocity[g] = Vec3(p[3], p[4], p[5]);
    ghosts_.angular_velocity[g] = Vec3(p[6], p[7], p[8]);
  }
  const std::size_t owned = store.owned_size();
  if (owned == store.size()) {
    for (std::size_t g = 0; g < ghosts_.size(); ++g) store.append_from(ghosts_, g);
    return;
  }
  if (store.size() - owned != ghosts_.size())
    throw std::logic_error("SlabDecomposition: the store holds other ghosts than the last exchange");
  for (std::size_t g = 0; g < ghosts_.size(); ++g) {
    store.position[owned + g] = ghosts_.position[g];
    store.velocity[owned + g] = ghosts_.velocity[g];
    store.angular_velocity[owned + g] = ghosts_.angular_velocity[g];
  }
}

std::size_t SlabDecomposition::migrate(ParticleStore& store, std::vector<Vec3>* force,
                                       std::vector<Vec3>* torque, ContactHistory* history) {
  if (ranks_ == 1) return 0;
  const std::size_t n = store.size();
  const bool with_forces = force && torque && force->size() == n && torque->size() == n;
  exchange_->clear();
  leaving_.clear();
  leaving_ids_.clear();
  // Centres inside the slab stay (a periodic axis keeps them wrapped into the box).
  const double a = cuts_[static_cast<std::size_t>(rank_)];
  const double b = cuts_[static_cast<std::size_t>(rank_) + 1];
  for (std::size_t i = 0; i < n; ++i) {
    const double s = store.position[i][axis_];
    if (s >= a && s < b) continue;
    const int r = owner(store.position[i]);
    if (r == rank_) continue;
    leaving_.push_back({i, r});
    leaving_ids_.push_back(store.id[i]);
  }
  // Each destination's buffer: particle count, the particles (with the integrator's force and
  // torque), entry count, the history entries of those particles.
  particle_count_.assign(static_cast<std::size_t>(ranks_), 0);
  auto& particle_count = particle_count_;
  for (int r = 0; r < ranks_; ++r) exchange_->outgoing(r).push_back(0.0);
  for (const auto& [i, r] : leaving_) {
    auto& out = exchange_->outgoing(r);
    pack_particle(store, i, out);
    const Vec3 f = with_forces ? (*force)[i] : Vec3::Zero();
    const Vec3 t = with_forces ? (*torque)[i] : Vec3::Zero();
    out.insert(out.end(), {f.x(), f.y(), f.z(), t.x(), t.y(), t.z()});
    ++particle_count[static_cast<std::size_t>(r)];
  }
  entries_.clear();
  if (history && !leaving_ids_.empty()) {
    std::sort(leaving_ids_.begin(), leaving_ids_.end());
    history->live_entries_of(leaving_ids_, entries_);
  }
  for (int r = 0; r < ranks_; ++r) {
    auto& out = exchange_->outgoing(r);
    out[0] = static_cast<double>(particle_count[static_cast<std::size_t>(r)]);
    // Every entry goes to every rank that receives a particle (a pair's two particles may
    // leave for different ranks); adopt() ignores what a rank does not need or has.
    const std::size_t entries = particle_count[static_cast<std::size_t>(r)] > 0 ? entries_.size() : 0;
    out.push_back(static_cast<double>(entries));
    for (std::size_t k = 0; k < entries; ++k) pack_entry(entries_[k], out);
  }
  exchange_->exchange();

  if (!leaving_.empty()) {
    keep_.assign(n, 1);
    for (const auto& leaver : leaving_) keep_[leaver.first] = 0;
    store.keep_where(keep_);
    if (with_forces) {
      keep_slots(*force, keep_);
      keep_slots(*torque, keep_);
    }
  }
  const std::size_t stayed = store.size();
  const auto& in = exchange_->incoming();
  std::size_t p = 0;
  while (p < in.size()) {
    const auto particles = static_cast<std::size_t>(in[p++]);
    for (std::size_t k = 0; k < particles; ++k) {
      unpack_particle(&in[p], 0, store);
      p += kParticleDoubles;
      if (with_forces) {
        force->emplace_back(in[p], in[p + 1], in[p + 2]);
        torque->emplace_back(in[p + 3], in[p + 4], in[p + 5]);
      }
      p += 6;
    }
    const auto entries = static_cast<std::size_t>(in[p++]);
    for (std::size_t k = 0; k < entries; ++k, p += kEntryDoubles)
      if (history) history->adopt(unpack_entry(&in[p]));
  }
  const std::size_t arrived = store.size() - stayed;
  if (arrived == 0) return 0;
  // Merge the arrivals (sorted among themselves first) into the id order of those that stayed.
  // (A merge by hand: std::inplace_merge's temporary buffer trips AddressSanitizer's
  // new/free pairing check with this libstdc++.)
  arrivals_.resize(arrived);
  std::iota(arrivals_.begin(), arrivals_.end(), static_cast<std::uint32_t>(stayed));
  auto by_id = [&](std::uint32_t x, std::uint32_t y) { return store.id[x] < store.id[y]; };
  std::sort(arrivals_.begin(), arrivals_.end(), by_id);
  order_.resize(store.size());
  std::uint32_t next_stayed = 0;
  std::size_t next_arrival = 0;
  for (std::size_t k = 0; k < order_.size(); ++k) {
    const bool take_arrival =
        next_arrival < arrived && (next_stayed == stayed || by_id(arrivals_[next_arrival], next_stayed));
    order_[k] = take_arrival ? arrivals_[next_arrival++] : next_stayed++;
  }
  store.permute(order_);
  if (with_forces) {
    permute_slots(*force, order_);
    permute_slots(*torque, order_);
  }
  return arrived;
}

}  // namespace grainwave::particles::dem

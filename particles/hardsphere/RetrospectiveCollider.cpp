#include "particles/hardsphere/RetrospectiveCollider.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <stdexcept>

#include "core/Error.hpp"
#include "particles/hardsphere/CollisionTime.hpp"

namespace grainwave::particles::hardsphere {

namespace {

/// Unit normal from a particle towards wall face (axis, side).
Vec3 wall_normal(int axis, int side) {
  Vec3 n = Vec3::Zero();
  n[axis] = side == 0 ? -1.0 : 1.0;
  return n;
}

Body body_of(const ParticleStore& store, std::size_t i) {
  Body b;
  b.velocity = store.velocity[i];
  b.angular_velocity = store.angular_velocity[i];
  b.inverse_mass = store.inverse_mass(i);
  b.inverse_inertia = store.inverse_inertia(i);
  b.radius = store.radius[i];
  return b;
}

/// Calls visit(axis, side) for every wall face of the domain.
template <class Visit>
void for_each_wall(const Domain& domain, Visit&& visit) {
  for (int k = 0; k < domain.dimension; ++k) {
    for (int side = 0; side < 2; ++side) {
      if (domain.face[static_cast<std::size_t>(k)][static_cast<std::size_t>(side)] == FaceKind::kWall)
        visit(k, side);
    }
  }
}

}  // namespace

RetrospectiveCollider::RetrospectiveCollider(RetrospectiveSettings settings)
    : settings_(settings) {
  validate(settings_.law, "hardsphere");
  walls_.reserve(6);
}

void RetrospectiveCollider::push_event(const Event& e) {
  heap_.push_back(e);
  std::push_heap(heap_.begin(), heap_.end(), std::greater<Event>());
}

void RetrospectiveCollider::advance_to(ParticleStore& store, int i, double t) {
  const auto k = static_cast<std::size_t>(i);
  const double tau = t - anchor_time_[k];
  if (tau == 0.0) return;
  store.position[k] += store.velocity[k] * tau + 0.5 * acceleration_[k] * tau * tau;
  store.velocity[k] += acceleration_[k] * tau;
  store.angular_velocity[k] += angular_acceleration_[k] * tau;
  anchor_time_[k] = t;
}

void RetrospectiveCollider::find_candidates(const ParticleStore& store, const Domain& domain,
                                            double margin) {
  const std::size_t n = store.size();
  candidate_pairs_.clear();
  if (candidate_pairs_.capacity() < 8 * n) candidate_pairs_.reserve(16 * n);  // grows rarely
  cells_.build(store.position);
  // Domain::separation with the box hoisted and the minimum image as masked adds (h = +inf on
  // axes that are not periodic): the same numbers, without its per-axis branches in this loop.
  std::array<double, 3> length{}, half{};
  for (int k = 0; k < 3; ++k) {
    const auto axis = static_cast<std::size_t>(k);
    const bool periodic = k < domain.dimension && domain.periodic(k);
    length[axis] = periodic ? domain.hi[k] - domain.lo[k] : 0.0;
    half[axis] = periodic ? 0.5 * length[axis] : std::numeric_limits<double>::infinity();
  }
  const Vec3* position = store.position.data();
  const double* radius = store.radius.data();
  const double twice_margin = 2.0 * margin;
  cells_.for_each_pair([&](int i, int j) {
    const auto a = static_cast<std::size_t>(i), b = static_cast<std::size_t>(j);
    double distance2 = 0.0;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const auto k = static_cast<int>(axis);
      double d = position[b][k] - position[a][k];
      d -= d > half[axis] ? length[axis] : 0.0;
      d += d < -half[axis] ? length[axis] : 0.0;
      distance2 += d * d;
    }
    const double reach = radius[a] + radius[b] + twice_margin;
    if (distance2 < reach * reach && !(store.is_fixed(a) && store.is_fixed(b)))
      candidate_pairs_.emplace_back(i, j);
  });
  // Compressed adjacency: candidates of particle i are candidate_list_[start[i] .. start[i+1]).
  candidate_start_.assign(n + 1, 0);
  for (const auto& [i, j] : candidate_pairs_) {
    ++candidate_start_[static_cast<std::size_t>(i) + 1];
    ++candidate_start_[static_cast<std::size_t>(j) + 1];
  }
  for (std::size_t i = 0; i < n; ++i) candidate_start_[i + 1] += candidate_start_[i];
  candidate_fill_.assign(candidate_start_.begin(), candidate_start_.end() - 1);
  candidate_list_.resize(static_cast<std::size_t>(candidate_start_[n]));
  for (const auto& [i, j] : candidate_pairs_) {
    candidate_list_[static_cast<std::size_t>(candidate_fill_[static_cast<std::size_t>(i)]++)] = j;
    candidate_list_[static_cast<std::size_t>(candidate_fill_[static_cast<std::size_t>(j)]++)] = i;
  }
}

void RetrospectiveCollider::predict(const ParticleStore& store, const Domain& domain, int i,
                                    double now, double h, bool higher_only, StepStats& stats) {
  const auto a = static_cast<std::size_t>(i);
  const double window = h - now;
  const double tau_a = now - anchor_time_[a];
  const Vec3 xa = store.position[a] + store.velocity[a] * tau_a + 0.5 * acceleration_[a] * tau_a * tau_a;
  const Vec3 va = store.velocity[a] + acceleration_[a] * tau_a;
  for (int c = candidate_start_[a]; c < candidate_start_[a + 1]; ++c) {
    const int j = candidate_list_[static_cast<std::size_t>(c)];
    if (higher_only && j < i) continue;  // the pair is predicted from its other member
    const auto b = static_cast<std::size_t>(j);
    const double tau_b = now - anchor_time_[b];
    const Vec3 xb = store.position[b] + store.velocity[b] * tau_b + 0.5 * acceleration_[b] * tau_b * tau_b;
    const Vec3 u = store.velocity[b] + acceleration_[b] * tau_b - va;
    const Vec3 relative_acceleration = acceleration_[b] - acceleration_[a];
    const Vec3 d = domain.separation(xa, xb);
    const double sigma = store.radius[a] + store.radius[b];
    // Cheap rejection: the gap cannot close within the window.
    const double reach = (u.norm() + 0.5 * relative_acceleration.norm() * window) * window;
    if (d.squaredNorm() > (sigma + reach) * (sigma + reach)) continue;
    ++stats.predictions;
    std::optional<double> t;
    if (relative_acceleration.isZero(0.0)) {
      t = ballistic_contact_time(d, u, sigma);
      if (t && *t > window) t.reset();
    } else {
      t = first_contact_time(d, u, relative_acceleration, sigma, window);
    }
    if (t) push_event(Event{now + *t, i, j, counter_[a], counter_[b]});
  }
  if (store.is_fixed(a)) return;
  for (std::size_t f = 0; f < walls_.size(); ++f) {
    const Wall& wall = walls_[f];
    const double sign = wall.side == 0 ? 1.0 : -1.0;  // inward normal along the axis
    const double gap = sign * (xa[wall.axis] - wall.plane);
    const std::optional<double> t = wall_contact_time(
        gap, sign * va[wall.axis], sign * acceleration_[a][wall.axis], store.radius[a], window);
    if (t) {
      const int face = 2 * wall.axis + wall.side;
      push_event(Event{now + *t, i, -1 - face, counter_[a], 0});
    }
  }
}

bool RetrospectiveCollider::try_substep(ParticleStore& store, const Domain& domain, double h,
                                        double t_offset, StepStats& stats) {
  const std::size_t n = store.size();
  for (std::size_t i = 0; i < n; ++i) domain.wrap(store.position[i]);
  std::copy(store.position.begin(), store.position.end(), start_position_.begin());
  std::copy(store.velocity.begin(), store.velocity.end(), start_velocity_.begin());
  std::copy(store.angular_velocity.begin(), store.angular_velocity.end(), start_spin_.begin());
  std::fill(anchor_time_.begin(), anchor_time_.end(), 0.0);
  std::fill(counter_.begin(), counter_.end(), 0u);
  heap_.clear();

  find_candidates(store, domain, margin_);
  // Generous calendar capacity, so that the event loop itself does not reallocate once warm.
  const std::size_t expected_events = 4 * (candidate_pairs_.size() + n * (walls_.size() + 1));
  if (heap_.capacity() < expected_events) heap_.reserve(2 * expected_events);
  for (std::size_t i = 0; i < n; ++i) predict(store, domain, static_cast<int>(i), 0.0, h, true, stats);

  const long collisions_before = stats.collisions, walls_before = stats.wall_hits;
  const std::size_t log_before = log_ ? log_->size() : 0;
  auto abandon = [&]() {
    std::copy(start_position_.begin(), start_position_.begin() + static_cast<long>(n), store.position.begin());
    std::copy(start_velocity_.begin(), start_velocity_.begin() + static_cast<long>(n), store.velocity.begin());
    std::copy(start_spin_.begin(), start_spin_.begin() + static_cast<long>(n), store.angular_velocity.begin());
    stats.collisions = collisions_before;
    stats.wall_hits = walls_before;
    if (log_) log_->resize(log_before);
    return false;
  };
  auto within_margin = [&](std::size_t i, double t) {
    const double rest = h - t;
    const double bound = (store.position[i] - start_position_[i]).norm() +
                         store.velocity[i].norm() * rest + 0.5 * acceleration_[i].norm() * rest * rest;
    return bound <= margin_;
  };

  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), std::greater<Event>());
    const Event e = heap_.back();
    heap_.pop_back();
    const auto a = static_cast<std::size_t>(e.a);
    const bool wall = e.b < 0;
    const auto b = static_cast<std::size_t>(wall ? 0 : e.b);
    if (counter_[a] != e.count_a || (!wall && counter_[b] != e.count_b)) continue;  // stale

    advance_to(store, e.a, e.time);
    Body body_a = body_of(store, a);
    Body body_b;  // a wall: zero inverse mass, inertia and radius, at rest
    Vec3 n_ab;
    if (wall) {
      const int face = -1 - e.b;
      n_ab = wall_normal(face / 2, face % 2);
    } else {
      advance_to(store, e.b, e.time);
      body_b = body_of(store, b);
      n_ab = domain.separation(store.position[a], store.position[b]).normalized();
    }
    const CollisionImpulse impulse = collide(body_a, body_b, n_ab, settings_.law);
    if (!impulse.approaching) {
      // Touching without approaching: harmless if the forces do not press the pair together;
      // otherwise it is a resting contact, which no impulse (and no subdivision) can resolve.
      const Vec3 relative_acceleration = acceleration_[a] - (wall ? Vec3::Zero().eval() : acceleration_[b]);
      if (n_ab.dot(relative_acceleration) > 0.0) {
        throw NumericalFailure("hard spheres in resting contact under forces pressing them together "
                               "(resting contacts need a soft-sphere model)",
                               "RetrospectiveCollider", t_offset + e.time, -1);
      }
      continue;
    }
    store.velocity[a] = body_a.velocity;
    store.angular_velocity[a] = body_a.angular_velocity;
    ++counter_[a];
    if (wall) {
      ++stats.wall_hits;
    } else {
      store.velocity[b] = body_b.velocity;
      store.angular_velocity[b] = body_b.angular_velocity;
      ++counter_[b];
      ++stats.collisions;
    }
    if (log_) log_->push_back(CollisionRecord{t_offset + e.time, store.id[a], wall ? e.b : store.id[b]});

    const auto cap = static_cast<std::uint32_t>(settings_.max_collisions_per_particle);
    if (counter_[a] > cap || (!wall && counter_[b] > cap)) return abandon();
    if (!within_margin(a, e.time) || (!wall && !within_margin(b, e.time))) return abandon();
    predict(store, domain, e.a, e.time, h, false, stats);
    if (!wall) predict(store, domain, e.b, e.time, h, false, stats);
  }
  for (std::size_t i = 0; i < n; ++i) advance_to(store, static_cast<int>(i), h);
  return true;
}

StepStats RetrospectiveCollider::step(ParticleStore& store, const Domain& domain, double dt) {
  StepStats stats;
  const std::size_t n = store.size();
  walls_.clear();
  for_each_wall(domain, [&](int axis, int side) {
    walls_.push_back(Wall{axis, side, side == 0 ? domain.lo[axis] : domain.hi[axis]});
  });
  start_position_.resize(n);
  start_velocity_.resize(n);
  start_spin_.resize(n);
  acceleration_.resize(n);
  angular_acceleration_.resize(n);
  anchor_time_.resize(n);
  counter_.resize(n);

  double max_radius = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    acceleration_[i] = store.force[i] * store.inverse_mass(i);
    angular_acceleration_[i] = store.torque[i] * store.inverse_inertia(i);
    max_radius = std::max(max_radius, store.radius[i]);
  }
  double shortest_periodic = std::numeric_limits<double>::infinity();
  for (int k = 0; k < domain.dimension; ++k) {
    if (domain.periodic(k)) shortest_periodic = std::min(shortest_periodic, domain.hi[k] - domain.lo[k]);
  }
  if (n > 0 && shortest_periodic < 4.0 * max_radius) {
    throw std::invalid_argument("RetrospectiveCollider: a periodic box must span two diameters");
  }

  double remaining = dt, h = dt, t_offset = 0.0;
  const double smallest = dt * std::ldexp(1.0, -settings_.max_subdivisions);
  while (remaining > 1e-14 * dt && n > 0) {
    h = std::min(h, remaining);
    double fastest = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      fastest = std::max(fastest, store.velocity[i].norm() * h + 0.5 * acceleration_[i].norm() * h * h);
    }
    margin_ = settings_.margin_factor * fastest + 1e-12 * max_radius;
    // Keep the search local (margin within a radius) and the minimum image unambiguous.
    const double cutoff = 2.0 * max_radius + 2.0 * margin_;
    if ((margin_ > max_radius || 2.0 * cutoff > shortest_periodic) && h > smallest) {
      h *= 0.5;
      continue;
    }
    if (cutoff > configured_cutoff_ || cutoff < 0.5 * configured_cutoff_) {
      configured_cutoff_ = std::min(1.2 * cutoff, 0.5 * shortest_periodic);
      configured_cutoff_ = std::max(configured_cutoff_, cutoff);
      cells_.configure(domain, configured_cutoff_);
    }
    if (try_substep(store, domain, h, t_offset, stats)) {
      remaining -= h;
      t_offset += h;
      ++stats.substeps;
      h = std::min(2.0 * h, dt);
    } else {
      ++stats.restarts;
      h *= 0.5;
      if (h < smallest) {
        throw NumericalFailure("hard-sphere collisions did not resolve after " +
                                   std::to_string(settings_.max_subdivisions) + " step halvings",
                               "RetrospectiveCollider", t_offset, -1);
      }
    }
  }
  // Periodic wrap and removal through open faces.
  for (std::size_t i = store.size(); i-- > 0;) {
    domain.wrap(store.position[i]);
    bool leaves = false;
    for (int k = 0; k < domain.dimension; ++k) {
      const auto& face = domain.face[static_cast<std::size_t>(k)];
      leaves |= face[0] == FaceKind::kOpen && store.position[i][k] < domain.lo[k];
      leaves |= face[1] == FaceKind::kOpen && store.position[i][k] > domain.hi[k];
    }
    if (leaves) {
      store.remove(i);
      ++stats.removed;
    }
  }
  return stats;
}

double max_relative_overlap(const ParticleStore& store, const Domain& domain, CellList& cells) {
  double max_radius = 0.0;
  for (double r : store.radius) max_radius = std::max(max_radius, r);
  if (store.empty()) return 0.0;
  cells.configure(domain, 2.0 * max_radius);
  cells.build(store.position);
  double worst = 0.0;
  const Domain::MinimumImage image = domain.minimum_image();  // the box read once, not per pair
  cells.for_each_pair([&](int i, int j) {
    const auto a = static_cast<std::size_t>(i), b = static_cast<std::size_t>(j);
    const double contact = store.radius[a] + store.radius[b];
    const double squared = image(store.position[b] - store.position[a]).squaredNorm();
    // Most pairs in reach are apart: no square root for them. The skip changes nothing: the
    // square root is correctly rounded and monotone, and the rounded root of the rounded
    // contact * contact is contact itself, so from there on the overlap below is <= 0.
    if (squared >= contact * contact) return;
    const double overlap = contact - std::sqrt(squared);
    worst = std::max(worst, overlap / std::min(store.radius[a], store.radius[b]));
  });
  for_each_wall(domain, [&](int axis, int side) {
    for (std::size_t i = 0; i < store.size(); ++i) {
      const double gap = side == 0 ? store.position[i][axis] - domain.lo[axis]
                                   : domain.hi[axis] - store.position[i][axis];
      worst = std::max(worst, (store.radius[i] - gap) / store.radius[i]);
    }
  });
  return worst;
}

}  // namespace grainwave::particles::hardsphere

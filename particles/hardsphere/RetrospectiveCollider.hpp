#pragma once
// Hard-sphere stepping over a fixed time step with retrospective collision handling
// (Goetsch 2015, 002 §2.3.3, after Allen & Tildesley §4.3; conservation check of 002 App. A).
//
// Each particle flies freely under its constant force and torque (002 Eqs 2.11–2.13):
//   x(t) = x0 + v0 t + F t^2 / (2m),  v(t) = v0 + F t / m,  w(t) = w0 + T t / I.
// The step is taken, and then repaired: every pair that could touch inside it (centres closer
// than r_i + r_j + 2 s at the start, s bounding any particle's displacement in the step, found
// with a CellList) gets its first contact time from the quartic Eq. 2.26 (CollisionTime.hpp), and
// the contacts are resolved in time order: the pair is rewound to its contact time, receives the
// impulse of CollisionImpulse.hpp, and both partners are re-predicted to the end of the step and
// re-checked against their candidates. Stale predictions are recognised by per-particle collision
// counters. A step in which a particle would leave its search margin s, or collide implausibly
// often (a collision chain), is restored and subdivided into halves. Wall faces are infinite-mass
// partners, periodic faces wrap, and particles whose centre leaves through an open face are removed.
// Hard spheres cannot rest on each other: a contact with zero approach speed under forces that
// press it shut, or inelastic collapse (endless collisions), ends in grainwave::NumericalFailure.
#include <cstdint>
#include <utility>
#include <vector>

#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/hardsphere/CellList.hpp"
#include "particles/hardsphere/CollisionImpulse.hpp"
#include "particles/hardsphere/CollisionRecord.hpp"

namespace grainwave::particles::hardsphere {

struct RetrospectiveSettings {
  CollisionLaw law{};
  /// Collisions one particle may undergo in one (sub)step before the step is subdivided.
  int max_collisions_per_particle = 500;
  /// Halvings of the step allowed before giving up with a NumericalFailure.
  int max_subdivisions = 30;
  /// Margin factor on the free-flight displacement bound (collisions may speed particles up).
  double margin_factor = 1.5;
};

struct StepStats {
  long collisions = 0;      ///< particle–particle impulses applied
  long wall_hits = 0;       ///< particle–wall impulses applied
  long removed = 0;         ///< particles that left through open faces
  long substeps = 0;        ///< substeps completed (1 when no subdivision was needed)
  long restarts = 0;        ///< substeps abandoned and subdivided
  long predictions = 0;     ///< contact-time solves
};

class RetrospectiveCollider {
 public:
  explicit RetrospectiveCollider(RetrospectiveSettings settings = {});

  /// Advances every particle by dt, resolving all collisions inside the step. Throws
  /// grainwave::NumericalFailure if the collisions cannot be resolved (e.g. inelastic collapse).
  StepStats step(ParticleStore& store, const Domain& domain, double dt);

  /// When set, every impulse is appended (time-ordered within a step). Pass nullptr to stop.
  void record_collisions(std::vector<CollisionRecord>* log) { log_ = log; }
  const RetrospectiveSettings& settings() const { return settings_; }

 private:
  struct Event {
    double time;
    int a;
    int b;  ///< particle index, or -1 - face for a wall
    std::uint32_t count_a;
    std::uint32_t count_b;
    bool operator>(const Event& other) const { return time > other.time; }
  };
  struct Wall {
    int axis;
    int side;  ///< 0 low face, 1 high face
    double plane;
  };

  bool try_substep(ParticleStore& store, const Domain& domain, double h, double t_offset,
                   StepStats& stats);
  void find_candidates(const ParticleStore& store, const Domain& domain, double margin);
  void predict(const ParticleStore& store, const Domain& domain, int i, double now, double h,
               bool higher_only, StepStats& stats);
  void advance_to(ParticleStore& store, int i, double t);
  void push_event(const Event& e);

  RetrospectiveSettings settings_;
  std::vector<CollisionRecord>* log_ = nullptr;
  CellList cells_;
  std::vector<Wall> walls_;
  // Per-particle scratch, reused between steps.
  std::vector<Vec3> start_position_, start_velocity_, start_spin_;
  std::vector<Vec3> acceleration_, angular_acceleration_;
  std::vector<double> anchor_time_;
  std::vector<std::uint32_t> counter_;
  std::vector<int> candidate_start_, candidate_list_, candidate_fill_;
  std::vector<std::pair<int, int>> candidate_pairs_;
  std::vector<Event> heap_;
  double margin_ = 0.0;            ///< bound on any particle's displacement in the substep
  double configured_cutoff_ = 0.0;  ///< cell size the cell list was last laid out for
};

/// Deepest overlap in the store relative to the smaller radius of the pair (walls included),
/// 0 when nothing overlaps. Uses `cells` as scratch.
double max_relative_overlap(const ParticleStore& store, const Domain& domain, CellList& cells);

}  // namespace grainwave::particles::hardsphere

#pragma once
// Event-driven hard spheres for equal accelerations (none, or gravity alone): 002 §2.3.3 notes
// that then Eq. 2.26 reduces to a quadratic and the system can be advanced collision by
// collision (Alder & Wainwright; Rapaport, "The Art of Molecular Dynamics Simulation", ch. 14;
// Lubachevsky 1991 for lazy per-particle clocks).
//
// Relative motion of any two particles is uniform, so a pair's contact time is the closed-form
// smaller root of |d + u t| = sigma (CollisionTime.hpp). Each particle keeps its own clock: its
// state is stored at the time of its last event and extrapolated with Eqs 2.11–2.13 when needed.
// Events live in one calendar (binary heap): pair collisions, wall collisions and cell crossings,
// cells at least one largest diameter wide. A particle predicts only up to its next cell crossing,
// where it re-predicts against the cells that have become adjacent; every contact is still found,
// because the partners are adjacent from the later of their last events on. A collision bumps both
// particles' counters, which marks all their older events stale. Impulses: CollisionImpulse.hpp.
#include <cstdint>
#include <vector>

#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/hardsphere/CollisionImpulse.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace grainwave::particles::hardsphere {

struct EventDrivenSettings {
  CollisionLaw law{};
};

struct EventStats {
  long collisions = 0;
  long wall_hits = 0;
  long cell_crossings = 0;
  long stale_events = 0;
  long predictions = 0;  ///< particles re-predicted
  long pair_checks = 0;  ///< partner candidates examined while predicting
};

class EventDrivenCollider {
 public:
  explicit EventDrivenCollider(EventDrivenSettings settings = {});

  /// Takes over the store at time `start_time`: checks that every particle has the same
  /// acceleration F/m (throws std::invalid_argument otherwise, or for open faces), bins the
  /// particles and schedules the first events.
  void initialize(ParticleStore& store, const Domain& domain, double start_time = 0.0);

  /// Processes every event up to `target` and leaves all particles synchronised at `target`
  /// (positions wrapped into the box) and written back to the store. The store must be the one
  /// passed to initialize(); after changing it from outside (particles, velocities, forces),
  /// call initialize() again.
  EventStats advance_to(ParticleStore& store, const Domain& domain, double target);

  double time() const { return now_; }
  /// When set, every impulse is appended with its absolute time. Pass nullptr to stop.
  void record_collisions(std::vector<CollisionRecord>* log) { log_ = log; }

 private:
  enum : int { kCrossing = -1000 };  ///< b = kCrossing - (2 axis + direction); walls: -1 - face
  struct Event {
    double time;
    int a;
    int b;
    std::uint32_t count_a;
    std::uint32_t count_b;
    bool operator>(const Event& other) const { return time > other.time; }
  };

  /// Compact per-particle flight state (one cache line): what the pair scan reads.
  struct Flight {
    Vec3 position;
    double clock;  ///< time at which position and velocity are valid
    Vec3 velocity;
    double radius;
  };

  void sync(ParticleStore& store, int i, double t);
  /// Schedules particle i's next events up to its next cell crossing.
  void predict(const ParticleStore& store, const Domain& domain, int i, bool higher_only);
  void schedule_all(const ParticleStore& store, const Domain& domain);
  void push(const Event& e);
  int cell_index(const std::array<int, 3>& c) const;
  /// Time from now until particle i leaves its cell and across which face; +inf if never.
  double next_crossing(const ParticleStore& store, int i, int* face) const;

  EventDrivenSettings settings_;
  std::vector<CollisionRecord>* log_ = nullptr;
  Vec3 acceleration_ = Vec3::Zero();
  double now_ = 0.0;
  int dimension_ = 3;
  Vec3 lo_ = Vec3::Zero();
  Vec3 length_ = Vec3::Ones();
  std::array<double, 3> cell_size_{1, 1, 1};
  std::array<int, 3> cells_{1, 1, 1};
  std::array<bool, 3> periodic_{true, true, true};
  std::array<std::array<bool, 2>, 3> wall_{};
  std::vector<Flight> flight_;                  ///< authoritative x, v while events are pending
  std::vector<std::uint32_t> counter_;          ///< collisions so far (stale-event test)
  std::vector<std::array<int, 3>> cell_of_;     ///< current cell of each particle
  std::vector<double> horizon_;                 ///< absolute time of its next cell crossing
  std::vector<int> head_, next_, prev_;         ///< doubly linked particles per cell
  std::vector<int> stencil_start_, stencil_;    ///< adjacent cells of each cell (CSR)
  std::vector<Vec3> angular_acceleration_;
  std::vector<Event> heap_;
  long predictions_ = 0, pair_checks_ = 0;
};

}  // namespace grainwave::particles::hardsphere

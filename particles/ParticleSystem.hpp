#pragma once
// Particles on their own: free flight under constant body forces (002 Eqs 2.9-2.13),
//   x(t+dt) = x + v dt + F/(2m) dt^2,  v(t+dt) = v + F/m dt,  omega(t+dt) = omega + T/I dt,
// colliding as hard spheres (002 §2.3, particles/hardsphere/) in a box whose faces are periodic,
// walls or open (particles leaving an open face are removed and counted). Built from the scene's
// [particles] section (and [[particle]] entries).
//
// Collisions are resolved retrospectively after each step (any forces), or event-driven when
// every particle has the same acceleration (none, or gravity); `collisions = "auto"` chooses.
// The event-driven calendar is rebuilt at the start of every step, so the state at a step
// boundary is the whole state and a restart continues bit for bit.
//
// Distribution over MPI ranks: without collisions every rank keeps a contiguous slice of the
// global initial list. The colliders are serial, so with collisions every rank holds all
// particles and computes the same steps (replicated; rank 0 writes): results are identical on
// any number of ranks but do not speed up. Output is ordered by particle id, so files do not
// depend on the number of ranks.
#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"
#include "io/Xdmf.hpp"
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/hardsphere/CellList.hpp"
#include "particles/hardsphere/CollisionImpulse.hpp"
#include "particles/hardsphere/EventDrivenCollider.hpp"
#include "particles/hardsphere/RetrospectiveCollider.hpp"

namespace grainwave::particles {

enum class CollisionMode { kNone, kRetrospective, kEventDriven };

class ParticleSystem : public io::System {
 public:
  static void declare(SceneSchema& schema);
  explicit ParticleSystem(const Scene& scene);

  std::string describe() const override;
  double max_stable_dt() const override;
  void advance(double t, double dt) override;
  std::optional<std::string> check_state() const override;
  void save_good_state() override;
  void restore_good_state() override;
  std::vector<io::OutputGrid> write_output(io::Hdf5File& file, const std::string& file_name) override;
  void write_checkpoint(io::Hdf5Group& group) override;
  void read_checkpoint(const io::Hdf5Group& group) override;
  void report(io::Json& counts, io::Json& metrics, double step_wall_s, long steps) const override;
  std::size_t memory_bytes() const override;
  std::string progress_note() const override;

  const ParticleStore& store() const { return store_; }
  const Domain& domain() const { return domain_; }

  CollisionMode mode() const { return mode_; }

  /// Global totals (collective): translational + rotational kinetic energy, translational
  /// only, linear momentum, angular momentum about the origin (002 Eqs A.1-A.3).
  double kinetic_energy() const;
  double translational_energy() const;
  Vec3 linear_momentum() const;
  Vec3 angular_momentum() const;

 private:
  /// Counters that advance with the state (kept with it for failure and restart).
  struct Tally {
    std::int64_t removed = 0;      ///< particles that left through open faces
    std::int64_t collisions = 0;   ///< particle-particle impulses
    std::int64_t wall_hits = 0;
    std::int64_t crossings = 0;    ///< periodic-boundary crossings
    double time = 0;               ///< simulated time since the start
    double max_overlap = 0;        ///< deepest overlap seen after a step, over the radius
    std::int64_t measured_collisions = 0;  ///< collisions after particles.statistics_start
    double measured_time = 0;
  };

  void place_initial_particles(const Scene& scene);
  void free_flight(double dt);
  void apply_boundaries();
  void record_totals(long step_collisions, long boundary_collisions);
  /// The event-driven collider's schedule into a checkpoint's particles group, and back.
  void write_event_schedule(io::Hdf5Group& particles) const;
  void read_event_schedule(const io::Hdf5Group& particles);
  std::int64_t global_count() const;
  double total(double local) const;  ///< sum over ranks, unless replicated

  Domain domain_;
  Vec3 gravity_ = Vec3::Zero();
  ParticleStore store_, good_;
  Tally tally_, good_tally_;
  std::int64_t initial_count_ = 0;
  double initial_energy_ = 0, initial_translational_energy_ = 0;
  Vec3 initial_momentum_ = Vec3::Zero();

  CollisionMode mode_ = CollisionMode::kNone;
  bool replicated_ = false;
  hardsphere::CollisionLaw law_;
  std::unique_ptr<hardsphere::RetrospectiveCollider> retrospective_;
  std::unique_ptr<hardsphere::EventDrivenCollider> event_driven_;
  mutable hardsphere::CellList overlap_cells_;
  /// The deepest overlap over the radius of the state the last step left (check_state reads it
  /// instead of searching again); empty where the state came from elsewhere.
  std::optional<double> step_overlap_;
  /// Whether the event-driven collider holds the store's state as its last advance_to() left it
  /// (its pending events then go on at the next step).
  bool events_continue_ = false;
  /// The event schedule a checkpoint held, for the first step after a restart.
  std::optional<hardsphere::EventSchedule> resume_schedule_;
  double overlap_tolerance_ = 1e-10;

  /// Per-step totals for the time series file (totals.csv) and the Haff's-law check.
  std::string totals_csv_;
  std::vector<std::pair<double, double>> temperature_history_;  ///< (t, translational K)
  std::string collisions_csv_;  ///< every impulse, when particles.record_collisions is set
  bool record_collisions_ = false;
  std::vector<hardsphere::CollisionRecord> step_log_;
  double statistics_start_ = 0;
  std::vector<Vec3> scratch_position_;      ///< positions before the step (periodic crossings)
  std::vector<std::int64_t> scratch_ids_;
  std::vector<std::int64_t> scratch_slot_of_id_;
};

}  // namespace grainwave::particles

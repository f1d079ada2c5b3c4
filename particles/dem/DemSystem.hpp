#pragma once
// The soft-sphere DEM as a runnable system (002 ch. 3): particles in a box whose faces are
// periodic, walls or open, with gravity, extra walls ([[dem_wall]]: planes and hopper segments,
// smooth or rough, one of them possibly the removable gate), the contact laws of
// particles/dem/ContactLaw chosen by name, velocity Verlet or the RK2 of 002 §3.2.3 at
// Δt = τ/N (τ of Eq. 3.17, or its Hertz equivalent, for the stiffest, lightest pair), and the
// periodic-recycling drag zone of Eq. 3.18.
//
// Life of a run:
//   placement   "collision": two particles (or one and a wall) meeting head on, to measure the
//               restitution and contact duration of the laws; "lattice" / "random" (RSA):
//               `count` particles of Gaussian diameters cut at ±2σ in the fill box;
//   settling    while the gate is closed, a viscous damping −c m v raises the dissipation until
//               t ≥ settle_time and the rms speed is below settle_speed (kinetic energy below
//               ½ M v_s²); then the gate wall is switched off ("opened") and the damping stops;
//   flow        mass flow rate through a horizontal plane, bin statistics ([dem_statistics]),
//               curtain-state file ([dem_curtain]); particles leaving an open face are removed.
//
// Neighbour search (dem.neighbour_skin): a Verlet list with a skin of 0.1 largest diameters
// by default. Before each step the list is checked against the positions the step will
// evaluate the forces at (the integrator predicts them), and rebuilt only when some particle
// would be more than half the skin from where the list saw it; so the decision is taken
// between steps, the same on every rank and in every run. With slabs, particles migrate and
// ghosts are exchanged only at these rebuilds (the ghost band is a skin wider); in between the
// ghosts' positions and velocities are refreshed before each evaluation. A checkpoint stores
// where the particles were at the last build, so a restart rebuilds that very list. 0 searches
// the cells at every evaluation instead (ghosts exchanged before each, migration after each
// step).
//
// MPI (dem.decomposition): "slabs" (the default) cuts the box into slabs along
// dem.decomposition_axis, balanced by particle count at the start, each rank stepping the
// particles it owns with ghost copies of its neighbours' (particles/dem/SlabDecomposition);
// "replicated" has every rank hold and step all particles. Either way the contact forces, and
// so the trajectories, are bitwise those of one rank (ContactForceField explains why); sums
// over particles (energy, mass through the flow plane, bin statistics) are added per rank and
// then over ranks, so they agree with one rank to round-off. The collision placement always
// runs replicated. Output and checkpoints hold every particle once, rank by rank (the `id`
// dataset names them); a checkpoint restarts on any number of ranks, bit for bit on the number
// that wrote it. The owned particles are kept in id order (removals compact them stably,
// arrivals are merged in) so that a restart from a checkpoint — which holds the contact history
// and the integrator's forces — continues bit for bit.
#include "core/Parameters.hpp"
#include "core/Scene.hpp"
#include "io/System.hpp"
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/dem/BinStatistics.hpp"
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"
#include "particles/dem/SlabDecomposition.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace grainwave::particles::dem {

class DemSystem : public io::System {
 public:
  static void declare(SceneSchema& schema);
  explicit DemSystem(const Scene& scene);

  std::string describe() const override;
  double max_stable_dt() const override { return dt_; }
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

 private:
  enum class Placement { kCollision, kLattice, kRandom };

  /// Everything that advances with the state besides the store (kept for failure and restart).
  struct Tally {
    double time = 0;                 ///< simulated time since the start
    std::int64_t settling = 0;       ///< 1 while the gate is closed / the fill settles
    double opened_at = -1;           ///< time the gate opened (-1: not yet)
    std::int64_t removed = 0;        ///< particles that left through open faces
    double removed_mass = 0;
    double flow_mass = 0;            ///< net mass through the flow plane in the window
    double flow_time = 0;            ///< time measured in the window
    double flow_mass_total = 0;      ///< net mass through the plane since the gate opened
    double next_flow_record = 0;     ///< time of the next flow.csv row
    // Collision probe (placement "collision").
    std::int64_t in_contact = 0;
    std::int64_t collisions = 0;
    double contact_start = 0;
    double approach_speed = 0;
    double first_duration = -1;
    double first_restitution = -1;
    double previous_gap = 0;         ///< signed surface gap at the previous step end
    double previous_rate = 0;        ///< its rate of change (normal relative speed) then
    double previous_acceleration = 0;  ///< and the rate's rate (from the contact forces)
    double earlier_acceleration = 0;   ///< the same one step before
    double particle_steps = 0;       ///< Σ over steps of the moving particles (throughput)
    double next_sample = 0;          ///< statistics: time of the next sample
    double last_sample = -1;         ///< statistics: time of the last sample (-1: none)
    double beta_volume = 0;          ///< statistics: Σ V_p in the β window
    std::int64_t beta_samples = 0;
    std::int64_t steps_since_balance = 0;  ///< domain decomposition: steps since the cuts were set
  };

  void read_contact_model(const SceneSection& s);
  void build_walls(const Scene& scene);
  void place_particles(const Scene& scene);
  void place_collision_pair(const SceneSection& s);
  void apply_settling_forces();
  void finish_settling_if_done();
  void remove_leaving_particles();
  void measure_flow(double dt);
  void record_flow();
  void probe_collision(double dt);
  void sample_statistics();
  double surface_gap() const;
  /// Normal relative speed and acceleration of the colliding pair (or particle and nearest wall).
  std::pair<double, double> gap_rate_and_acceleration() const;
  /// On this rank.
  double mobile_kinetic_energy() const;
  std::int64_t mobile_count() const;
  /// Over all ranks (collective when distributed).
  double global_sum(double local) const;
  std::int64_t global_sum(std::int64_t local) const;
  /// The bin statistics of all ranks added up (collective when distributed).
  BinStatistics global_bins() const;
  /// After a step: particles that left the slab go to their new owner (collective).
  void migrate_particles();
  /// With a Verlet list (dem.neighbour_skin > 0), before a step: the forces of velocity Verlet
  /// if it has none, then a rebuild of the list unless it serves every evaluation of the step
  /// (positions predicted by the integrator). The decision is the same on every rank and in
  /// every run, so the rebuilds, and with them the pair order, are those of the serial run.
  /// `refresh` brings the ghosts up to date before an evaluation.
  void prepare_neighbour_list(double dt, const BeforeEvaluation& refresh);
  /// Re-cut (when due), migration and ghost exchange when distributed, then the list built;
  /// after a restart, at the checkpoint's reference positions (collective when distributed).
  void rebuild_neighbour_list();
  /// Per-rank parts of the tally (sums over this rank's particles), for checkpoints.
  std::vector<double> tally_partials() const;
  void set_tally_partials(const std::vector<double>& partials);
  void write_curtain_state(const std::filesystem::path& folder) const;

  // Configuration.
  const Scene& scene_;
  Domain domain_;
  Vec3 gravity_ = Vec3::Zero();
  double density_ = 2500;
  ContactModel model_;
  std::string normal_name_, tangential_name_;
  double restitution_target_ = 1;
  bool runge_kutta_ = false;
  int steps_per_collision_ = 50;
  double dt_ = 0;
  Placement placement_ = Placement::kRandom;
  bool wall_partner_ = false;
  double settle_time_ = 0, settle_speed_ = 0, settle_damping_ = 0;
  double flow_plane_ = 0, flow_start_ = 0, flow_end_ = 0;
  bool measure_flow_ = false;
  double flow_record_interval_ = 0;
  std::string flow_csv_, good_flow_csv_;  ///< t, drained mass, mass above the plane, fill top
  std::optional<std::array<double, 2>> packing_window_;
  std::vector<std::size_t> gate_walls_;  ///< indices into finite_walls()
  struct RoughSegment {
    Vec3 a, b;
    double radius;
  };
  std::vector<RoughSegment> rough_segments_;  ///< kept clear of by the fill
  bool has_gate_ = false;
  double max_overlap_ratio_ = 0.5;
  // Statistics and curtain state.
  bool statistics_ = false, displacement_velocity_ = false;
  double stats_start_ = 0, stats_interval_ = 0;
  std::array<double, 4> beta_window_{0, 0, 0, 0};  ///< x0, x1, y0, y1
  bool curtain_ = false;
  std::array<double, 2> curtain_window_{0, 0};     ///< y range of the particles written
  // Domain decomposition.
  bool distributed_ = false;           ///< slabs over more than one rank
  SlabDecomposition decomposition_;
  std::int64_t rebalance_every_ = 0;   ///< steps between re-cuts of the slabs (0: never)
  std::string decomposition_note_;     ///< for describe()
  std::int64_t initial_fixed_ = 0;     ///< fixed particles at the start, all ranks
  std::int64_t global_mobile_ = 0;     ///< moving particles after the last step, all ranks
  // Verlet list.
  double skin_ = 0;                     ///< [m]; 0: cell search at every evaluation
  /// After a restart: where the owned particles were when the writer last built its list (the
  /// next build uses them, so that it lists what the writer's list held), else empty.
  std::vector<Vec3> restart_reference_;
  std::vector<Vec3> ahead_;             ///< the coming step's displacements (scratch)
  std::string skin_failure_;            ///< a particle outran half the skin (check_state)

  // State.
  ParticleStore store_, good_store_;
  Tally tally_, good_tally_;
  std::unique_ptr<ContactForceField> field_;
  VelocityVerlet verlet_;
  RungeKutta2 rk2_;
  BinStatistics bins_, good_bins_;
  std::vector<Vec3> sample_position_, good_sample_position_;  ///< by id, at the last sample
  std::vector<std::uint8_t> sample_seen_, good_sample_seen_;
  std::vector<Vec3> good_force_, good_torque_;
  std::vector<ContactHistoryEntry> good_history_;
  std::int64_t good_history_step_ = 0;
  double initial_energy_ = 0;
  std::int64_t initial_mobile_ = 0;
  // Scratch (no allocation once at working size).
  std::vector<double> y_before_;
  std::vector<Vec3> scratch_velocity_;
  std::vector<std::uint8_t> scratch_use_;
  std::vector<double> scratch_heights_;
};

}  // namespace grainwave::particles::dem

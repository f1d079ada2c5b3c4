#pragma once
// Domain decomposition of the DEM over MPI ranks (002 §3.2.6): the box is cut into slabs along
// one axis, rank r owning the particles whose centres lie in [cut_r, cut_{r+1}). Each force
// evaluation sees, besides the owned particles, ghost copies of the other ranks' particles whose
// centres lie within `reach` (the largest contact distance, twice the largest radius) of the
// rank's slab, across periodic faces too; after each step, particles whose centres left the slab
// migrate to their new owner with the integrator's forces and every live contact-history entry
// they take part in, so a contact's tangential spring continues across the move.
//
// Ordering, on which the bitwise equality with the serial run rests (ContactForceField): the
// owned slots are kept in id order (arrivals are merged in), and ghosts are appended in id order.
//
// Cost per step: one all-to-all of the band particles before each force evaluation and one of
// the migrants after the step (with a Verlet list both only at the list's rebuilds, and in
// between one all-to-all of the ghosts' positions and velocities per evaluation); with a tangential law that keeps history, a scan of the history
// table when some particle leaves. The cuts are balanced by particle count at the start and, if
// the caller asks (DemSystem: dem.rebalance_every), again from time to time; being computed
// from positions alone, they are the same on every rank and in every run.
#include "core/Mpi.hpp"
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/dem/ContactHistory.hpp"

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace grainwave::particles::dem {

class SlabDecomposition {
 public:
  /// One rank owning everything: every call is a no-op.
  SlabDecomposition() = default;
  /// Slabs [cuts[r], cuts[r + 1]) along `axis`, one per rank of `comm` (cuts has P + 1 entries
  /// from domain.lo to domain.hi); `reach` is the ghost band width.
  SlabDecomposition(const Domain& domain, int axis, std::vector<double> cuts, double reach,
                    MPI_Comm comm = MPI_COMM_WORLD);
  /// Cuts that give each of `ranks` slabs about the same number of moving particles of `store`.
  static std::vector<double> balanced_cuts(const Domain& domain, int axis, const ParticleStore& store,
                                           int ranks);
  /// The same from the particles' coordinates along the axis (any order).
  static std::vector<double> balanced_cuts(const Domain& domain, int axis,
                                           std::vector<double> coordinates, int ranks);
  /// Collective: cuts balanced by the moving particles of every rank's `store` (a rebalance;
  /// the particles then migrate to their new owners with migrate()).
  std::vector<double> rebalanced_cuts(const ParticleStore& store) const;
  /// New cuts (P + 1 values from lo to hi); the particles move at the next migrate().
  void set_cuts(std::vector<double> cuts);

  bool active() const { return ranks_ > 1; }
  int axis() const { return axis_; }
  const std::vector<double>& cuts() const { return cuts_; }
  /// The rank owning a particle centred at x.
  int owner(const Vec3& x) const;

  /// Keeps the slots this rank owns, in their order (after a placement made in full on every rank).
  void keep_owned(ParticleStore& store) const;
  /// Drops the ghosts at the end of the store.
  static void strip_ghosts(ParticleStore& store);
  /// Collective. Replaces the ghosts at the end of the store by copies, in id order, of the
  /// other ranks' particles within reach of this slab at their present positions, and keeps
  /// the set (who is sent where, and a copy) for refresh_ghosts().
  void exchange_ghosts(ParticleStore& store);
  /// Collective. The same ghosts as the last exchange_ghosts(), with their owners' present
  /// position, velocity and angular velocity: written over the store's ghosts, or appended
  /// if the store has none (they were stripped after the step). A Verlet list built with the
  /// ghosts stays valid over this (ContactForceField, verlet_managed).
  void refresh_ghosts(ParticleStore& store);
  /// Collective, on a store without ghosts. Sends the particles whose centres left the slab to
  /// their owners with their entries of `force`/`torque` (the integrator's, may be null) and of
  /// `history` (may be null), receives the arrivals and merges them into id order. Returns the
  /// number of particles that arrived.
  std::size_t migrate(ParticleStore& store, std::vector<Vec3>* force, std::vector<Vec3>* torque,
                      ContactHistory* history);

 private:
  /// Distance along the axis from coordinate s to rank r's slab (0 inside), periodic images
  /// included.
  double distance_to_slab(double s, int r) const;

  Domain domain_;
  int axis_ = 0;
  std::vector<double> cuts_;
  double reach_ = 0.0;
  int ranks_ = 1, rank_ = 0;
  MPI_Comm comm_ = MPI_COMM_WORLD;
  // Scratch, reused between steps.
  std::unique_ptr<mpi::Exchange> exchange_;
  std::vector<std::uint8_t> keep_;
  std::vector<std::pair<std::size_t, int>> leaving_;  ///< slot and new owner
  std::vector<std::size_t> particle_count_;
  std::vector<std::int64_t> leaving_ids_;
  std::vector<ContactHistoryEntry> entries_;
  std::vector<std::uint32_t> order_, arrivals_;
  // The ghost set of the last exchange: the slots sent to each rank, in the order sent, the
  // ghost index (0 = first ghost slot) of each arrival in the order received, and the ghosts.
  std::vector<std::vector<std::uint32_t>> sent_;
  std::vector<std::uint32_t> ghost_of_arrival_;
  ParticleStore ghosts_;
};

}  // namespace grainwave::particles::dem

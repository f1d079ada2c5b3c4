#pragma once
// Total force and torque on every particle for one DEM force evaluation (002 Eqs 3.3 and 3.4):
//   F_i = Σ_j (−f_n n + F_t) + F_ext,i + m_i g + F_drag,i,    T_i = Σ_j R_i n × F_t + T_ext,i,
// where j runs over touching particles (found by LinkedCells) and walls (closest point, R_j = 0,
// m_j = ∞), f_n and F_t come from the ContactModel, and F_drag is the periodic-recycling drag of
// Eq. 3.18, F = −c |v| v inside a zone, with c = m |g| / v_term² so that a particle falling
// under gravity alone settles at the terminal speed v_term.
// This class owns the loops and scratch memory; the laws own the pointwise physics. Nothing is
// allocated per evaluation once the contact list has reached its working size.
// For the linear spring–dashpot with static friction or the Coulomb spring on a Verlet list
// (the curtain and channel cases), the listed pairs are evaluated 2, 4 or 8 at a time in SIMD
// lanes (settings().batched, ContactLanes.hpp), with the same arithmetic per contact and the
// forces added in the same order: bitwise the same.
//
// Ghosts (domain decomposition, particles/dem/SlabDecomposition): copies of other ranks'
// particles, flagged kGhost, at the end of the store. A pair of two ghosts is skipped (another
// rank owns it), walls act on owned particles only, and forces on ghosts are discarded by the
// caller. When the owned slots and the ghost slots each lie in id order, the cells are filled in
// their merged id order, so the touching pairs are met, and every owned particle's force summed,
// in the order of the serial run: the forces are bitwise the serial ones. A Verlet list built
// that way (build_list) lists the pairs in the serial list's order, so the same holds with it,
// provided every rank rebuilds at the serial run's steps (verlet_managed: DemSystem decides).
//
// With a history law, each particle contact is put in a canonical orientation before its
// history is looked up: i is the smaller id. The stored displacement δ_t is a vector "of j
// relative to i"; without this, a pair reported the other way round (the particles moved into
// each other's cells) would read δ_t with the wrong sign.
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/dem/ContactHistory.hpp"
#include "particles/dem/ContactLaw.hpp"
#include "particles/dem/LinkedCells.hpp"
#include "particles/dem/VerletList.hpp"
#include "particles/dem/Walls.hpp"

#include <span>
#include <vector>

namespace grainwave::particles::dem {

/// Axis-aligned box in which falling particles are slowed by F = −c |v| v (002 Eq. 3.18).
struct RecyclingDragZone {
  Vec3 lo = Vec3::Zero();
  Vec3 hi = Vec3::Zero();
  double coefficient_per_mass = 0.0;  ///< c / m = |g| / v_term²

  static RecyclingDragZone from_terminal_velocity(const Vec3& lo, const Vec3& hi,
                                                  double gravity_magnitude,
                                                  double terminal_velocity) {
    return {lo, hi, gravity_magnitude / (terminal_velocity * terminal_velocity)};
  }
  bool contains(const Vec3& x) const {
    return (x.array() >= lo.array()).all() && (x.array() <= hi.array()).all();
  }
};

/// Drag of Eq. 3.18 on a particle of mass m moving at v.
inline Vec3 recycling_drag(double coefficient_per_mass, double mass, const Vec3& velocity) {
  return -coefficient_per_mass * mass * velocity.norm() * velocity;
}

struct ContactForceSettings {
  Vec3 gravity = Vec3::Zero();
  std::vector<RecyclingDragZone> drag_zones;
  /// Linked-cell width; 0 means the largest particle diameter at each build. With a Verlet
  /// list the skin is added to it.
  double cell_width = 0.0;
  /// Verlet-list skin: 0 searches the cells at every evaluation; > 0 keeps the pairs closer
  /// than r_i + r_j + skin and searches again only after a particle moved skin/2.
  double verlet_skin = 0.0;
  /// With a skin: the caller decides when the list is rebuilt (list_stale_ahead, build_list),
  /// once per step and before it, and evaluate() never rebuilds on its own. This is how the
  /// list works with ghosts (a domain-decomposed run); without, the list checks itself at each
  /// evaluation and ghosts fall back to the cell search.
  bool verlet_managed = false;
  /// For the built-in laws, each contact's forces are computed (with a history law, its entry
  /// looked up and advanced) and added where the pair is found, without a list of contacts
  /// (bitwise the same forces and history: the same arithmetic, added in the same order).
  /// false keeps the list (contacts()) for every law.
  bool fused = true;
  /// With the fused pass, a Verlet list, the linear spring–dashpot and static friction or the
  /// Coulomb spring (velocity Verlet), the listed pairs' forces are computed several at a time in
  /// SIMD lanes (bitwise the same).
  bool batched = true;
  /// Lanes of the batched pass: 0 takes the law's preferred width (4 for static friction, 8 for
  /// the Coulomb spring, as measured fastest) or the widest below it that this CPU runs
  /// (lane_width_supported: 8 with AVX-512F, 4 with AVX2, 2 always); 2, 4 or 8 asks for that
  /// width. Any width gives the same bits; only the speed differs.
  int lane_width = 0;
  /// Particle count that sizes the cell grid (LinkedCells::build); 0: the store's size. A
  /// domain-decomposed run sets the global count so that every rank uses the serial grid.
  std::size_t grid_particles = 0;
};

/// The deepest contact of an evaluation, relative to the smaller radius (the wall's particle's
/// radius for a wall).
struct DeepestContact {
  double overlap_over_radius = 0.0;
  std::uint32_t i = 0, partner = 0;  ///< slots; partner is the wall index when is_wall
  bool is_wall = false;
  std::int64_t id = -1;  ///< id of particle i (slots of ghosts do not outlive the step)
};

class LinearSpringDashpot;
class StaticFriction;

/// Whether this machine runs the batched pass at `width` lanes (2: any x86-64 or other CPU;
/// 4: AVX2; 8: AVX-512F).
bool lane_width_supported(int width);

class ContactForceField {
 public:
  ContactForceField(ContactModel model, const Domain& domain, ContactForceSettings settings = {});

  std::vector<PlaneWall>& plane_walls() { return plane_walls_; }
  std::vector<FiniteWall>& finite_walls() { return finite_walls_; }
  const Domain& domain() const { return domain_; }
  const ContactModel& model() const { return model_; }
  ContactForceSettings& settings() { return settings_; }

  /// Computes force() and torque() for the current state. kSingle and kPredict start a new
  /// history step; kCorrect re-evaluates within the step begun by the preceding kPredict.
  void evaluate(const ParticleStore& store, HistoryStage stage, double dt);

  const std::vector<Vec3>& force() const { return force_; }
  const std::vector<Vec3>& torque() const { return torque_; }
  /// Contacts found by the last evaluation (particle pairs and wall contacts), when it kept the
  /// list: with settings().fused = false or a law of another type than the built-in ones,
  /// otherwise empty.
  const std::vector<Contact>& contacts() const { return contacts_; }
  /// How many contacts the last evaluation found, and the deepest (either way of evaluating).
  std::size_t contact_count() const { return contact_count_; }
  const DeepestContact& deepest_contact() const { return deepest_; }
  const ContactHistory& history() const { return history_; }
  ContactHistory& history() { return history_; }
  const VerletList& verlet_list() const { return verlet_; }
  /// The lanes the batched pass runs at with the settings and law as they are
  /// (settings().lane_width resolved); throws std::invalid_argument for a width this CPU does
  /// not run.
  int lane_width() const;

  /// Caller-managed Verlet list (settings().verlet_managed). VerletList::kValid when the list
  /// serves the coming step, whose evaluations see the owned slots (those before the ghosts)
  /// at their positions now and at position + ahead[i]; else why not (VerletList::stale_ahead).
  long list_stale_ahead(const ParticleStore& store, std::span<const Vec3> ahead) const;
  /// Builds the list from the store as it is (owned slots, then ghosts in id order).
  void build_list(const ParticleStore& store);
  void invalidate_list() { verlet_.invalidate(); }

 private:
  /// Calls f(contact) for every touching particle pair, then for every wall contact, in a
  /// fixed order; the contact's forces are not set yet. Without kWithEffectiveRadius a pair
  /// contact's effective_radius is NaN (a law that reads it would be caught by the step's
  /// checks): the laws that do not read it save a division per contact.
  template <bool kWithEffectiveRadius = true, class ContactFunction>
  void for_each_contact(const ParticleStore& store, ContactFunction&& f);
  /// The wall part of for_each_contact (f is handed `c` to fill and pass on).
  template <class ContactFunction>
  void for_each_wall_contact(const ParticleStore& store, Contact& c, ContactFunction&& f);
  /// With the Verlet list in use: the particles each wall can touch before the list's next
  /// build, refreshed after each build (wall_candidates_). False without the list.
  bool refresh_wall_candidates(const ParticleStore& store);
  /// The fused pass's listed particle pairs for the linear spring–dashpot with static friction
  /// or (velocity Verlet's single stage) the Coulomb spring with history, the laws of the
  /// curtain and channel cases, several contacts at a time in SIMD lanes (TangentialLanes, in
  /// ContactLanes.hpp): the same operations per contact as the contact-by-contact pass, and the
  /// forces added, the contacts counted and the history entries written in the same order, so
  /// every result is the same to the bit.
  template <class TangentialLanes>
  void add_listed_pairs_linear(const ParticleStore& store, const LinearSpringDashpot& normal,
                               const TangentialLanes& tangential);
  /// The contact of i with particle j (d = x_j - x_i, |d|^2), false if they cannot interact.
  template <bool kWithEffectiveRadius>
  bool particle_contact(const ParticleStore& store, std::uint32_t i, std::uint32_t j, const Vec3& d,
                        double distance2, Contact& c) const;
  void wall_contact(const ParticleStore& store, std::size_t i, std::size_t wall_index, const Vec3& wall_velocity,
                    const Vec3& normal, double overlap, Contact& c) const;
  /// force_ and torque_ from gravity, the stored external forces and the drag zones.
  void external_forces(const ParticleStore& store);
  /// Adds a contact's forces to force_ and torque_ of its particles.
  void apply(const ParticleStore& store, const Contact& c);
  void note_depth(const ParticleStore& store, const Contact& c);
  /// Puts a particle contact in the canonical orientation and sets its history entry.
  void touch_history(const ParticleStore& store, Contact& c);
  /// The entry of (a, b) (canonical order) for Verlet-list pair `list_index` (kNotListed: none):
  /// the pinned one at that position (ContactHistory::pin) when the list's pairs are pinned.
  ContactHistoryEntry* touch_listed_history(std::int64_t a, std::int64_t b, std::uint32_t list_index);
  /// One pass: every contact's forces computed (its history looked up and advanced) and added
  /// where it is found.
  template <class Normal, class Tangential>
  void evaluate_fused(const ParticleStore& store, const Normal& normal, const Tangential& tangential,
                      HistoryStage stage, double dt);
  /// Per-slot scratch of an evaluation or a build: inverse masses and where the ghosts begin.
  void prepare_slots(const ParticleStore& store);
  /// With ghosts, the owned and ghost slots merged by id (for a cell search or a list build).
  void merge_visit_order(const ParticleStore& store);
  /// Cell width of a search: settings().cell_width, or the largest diameter; plus `skin`.
  double search_cell_width(const ParticleStore& store, double skin) const;
  /// settings().lane_width resolved: 0 gives `preferred` or the widest below it the CPU runs.
  int lane_width_for(int preferred) const;
  /// The fused pass for these laws if they are of known final types; false otherwise.
  template <class Normal>
  bool try_fused(const ParticleStore& store, const Normal& normal, HistoryStage stage, double dt);

  ContactModel model_;
  Domain domain_;
  ContactForceSettings settings_;
  std::vector<PlaneWall> plane_walls_;
  std::vector<FiniteWall> finite_walls_;
  LinkedCells cells_;
  VerletList verlet_;
  ContactHistory history_;
  /// The list build and history pin generation at which the listed pairs were pinned in
  /// history_ (at their list positions, so the fused pass walks their entries in list order).
  long pinned_build_ = -1;
  std::uint64_t pinned_generation_ = 0;
  std::vector<std::pair<std::int64_t, std::int64_t>> pin_keys_;  ///< scratch of the pin
  std::vector<Contact> contacts_;
  std::size_t contact_count_ = 0;
  DeepestContact deepest_;
  std::vector<double> inverse_mass_;  ///< per slot, 0 for fixed particles
  std::size_t owned_end_ = 0;         ///< first ghost slot (ghosts trail the owned slots)
  bool has_ghosts_ = false;
  std::vector<std::uint32_t> visit_order_;  ///< owned and ghost slots merged by id
  bool use_list_ = false;  ///< this evaluation takes its pairs from verlet_
  /// Per wall (plane walls, then finite ones), the owned particles (ascending slots) within
  /// their radius plus the list's skin of it, or within the skin of a periodic face (they may
  /// wrap), when the candidates were taken: until the list's next build none moves more than
  /// the skin (half of it from the build, and the candidates are taken at or after it), and a
  /// wall's distance changes no faster than the particle moves, so no other particle can touch
  /// it. Walls then cost a pass over their candidates instead of over every particle (the
  /// walls of curtain_small's hopper took 29 % of its run that way). Walls stand still (their
  /// velocity is their surface's; switching one on or off needs no new candidates, and a wall
  /// added or removed renews them), so their geometry must not change between list builds.
  /// Slots wall_begin_[w] to wall_begin_[w + 1] of wall_candidates_.
  std::vector<std::uint32_t> wall_candidates_;
  std::vector<std::size_t> wall_begin_;
  long wall_candidates_build_ = -1;  ///< verlet_.builds() when they were taken
  std::size_t wall_candidates_owned_ = 0, wall_candidates_walls_ = 0;
  std::vector<Vec3> force_;
  std::vector<Vec3> torque_;
};

}  // namespace grainwave::particles::dem

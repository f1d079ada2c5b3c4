#pragma once
// Per-contact memory of the tangential laws (the stored displacement δ_t of 002 Eq. 3.15),
// keyed by the pair of particle ids rather than slots, so it survives ParticleStore::remove()
// reordering and, later, migration between MPI ranks. A wall partner is keyed by
// wall_key(wall_index) < 0, so particle ids must be >= 0.
//
// Open addressing with linear probing in a flat array. An entry belongs to the step in which it
// was last touched: a contact absent for a whole step is stale and restarts from zero when the
// pair touches again. Stale entries stay in place until a purge (prepare() at a load of 0.7,
// or make_room() when touch() is about to fill it); a purge moves entries, so a
// caller holding entry pointers must look them up again after make_room(). After the table has
// reached its working size nothing is allocated.
#include "particles/ParticleStore.hpp"

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace grainwave::particles::dem {

struct ContactHistoryEntry {
  std::int64_t first = -1;  ///< smaller id of the pair (or the particle id for walls)
  std::int64_t second = -1;
  std::int64_t last_step = -1;  ///< step of the last touch; -1 marks an empty slot
  Vec3 displacement = Vec3::Zero();    ///< committed tangential displacement δ_t
  Vec3 stage_velocity = Vec3::Zero();  ///< v_t of the previous evaluation (trapezoidal update)
  bool is_new = true;  ///< not yet seen by a tangential law (stage_velocity meaningless)
};

class ContactHistory {
 public:
  static constexpr std::int64_t wall_key(std::size_t wall_index) {
    return -1 - static_cast<std::int64_t>(wall_index);
  }

  /// Advances the step counter: contacts not touched during the previous step become stale.
  void begin_step() { ++step_; }
  /// Called once per force evaluation before the lookups: purges above a load of 0.7.
  void prepare();
  /// True when the next touch() could push the load above 0.85: call make_room() first.
  bool nearly_full() const { return 20 * (occupied_ + 1) > 17 * slots_.size(); }
  /// Purges stale entries and doubles the capacity until live entries fill at most half.
  void make_room();
  /// Entry of the pair (a, b), order-independent; a fresh zeroed entry when the pair was not in
  /// contact during the current or previous step. Requires !nearly_full().
  ContactHistoryEntry* touch(std::int64_t a, std::int64_t b);
  /// The same, trying slot `hint` first and leaving there the slot of the entry returned. A
  /// caller that meets the same pair step after step (a Verlet list's pair) keeps one hint per
  /// pair and mostly skips the probe. Any hint is safe: a slot holding the pair's key is its
  /// entry (keys are unique), and a purge that moved the entry makes the next call probe.
  ContactHistoryEntry* touch(std::int64_t a, std::int64_t b, std::uint32_t& hint) {
    if (a > b) std::swap(a, b);
    if (hint < slots_.size()) {
      ContactHistoryEntry& e = slots_[hint];
      if (e.first == a && e.second == b && e.last_step >= 0) return renew(e);
    }
    ContactHistoryEntry* e = touch(a, b);
    hint = static_cast<std::uint32_t>(e - slots_.data());
    return e;
  }
  /// The entry when the pair is live, else nullptr (read-only; does not touch).
  const ContactHistoryEntry* find(std::int64_t a, std::int64_t b) const;

  std::size_t live_count() const;
  /// Copies the live entries into `out` (its capacity is reused), for checkpoints, the last
  /// good state and, later, migration between ranks.
  void live_entries(std::vector<ContactHistoryEntry>& out) const;
  /// Appends to `out` the live entries of which one partner is in `sorted_ids` (ascending):
  /// the history that travels with particles migrating to another rank.
  void live_entries_of(const std::vector<std::int64_t>& sorted_ids,
                       std::vector<ContactHistoryEntry>& out) const;
  /// Takes over an entry from another rank, unless the pair is live here and was touched as
  /// recently (then this rank has been computing the same contact, with the same values).
  void adopt(const ContactHistoryEntry& entry);
  /// Replaces the table by `entries` at step counter `step` (a restart). Entries land in other
  /// slots than before, which changes nothing: lookups go by the id pair.
  void restore(std::int64_t step, const std::vector<ContactHistoryEntry>& entries);
  std::size_t capacity() const { return slots_.size(); }
  /// Mean number of slots a lookup of a stored entry reads (1 when every entry sits at its
  /// home): how well the table spreads its keys.
  double mean_probe_length() const;
  std::int64_t step() const { return step_; }
  static constexpr std::size_t bytes_per_entry() { return sizeof(ContactHistoryEntry); }

 private:
  bool live(const ContactHistoryEntry& e) const { return e.last_step >= step_ - 1; }
  /// A found entry touched in this step: restarted from zero if it was stale.
  ContactHistoryEntry* renew(ContactHistoryEntry& e) {
    if (!live(e)) {
      e.displacement.setZero();
      e.stage_velocity.setZero();
      e.is_new = true;
    }
    e.last_step = step_;
    return &e;
  }
  std::size_t home(std::int64_t a, std::int64_t b) const;
  /// Widens id_span_ to the key's particle id.
  void note_key(std::int64_t a, std::int64_t b);
  /// stride_ for a table of `capacity` slots: the ids seen spread over all of it.
  void choose_stride(std::size_t capacity);
  void rehash(std::size_t new_capacity);

  std::vector<ContactHistoryEntry> slots_;
  std::vector<ContactHistoryEntry> spare_;
  std::size_t occupied_ = 0;  ///< non-empty slots, live or stale
  std::uint64_t id_span_ = 0;  ///< one past the largest particle id keyed so far
  static constexpr int kStrideShift = 16;
  /// Slots between the homes of consecutive ids, in units of 2^-kStrideShift slot.
  std::uint64_t stride_ = std::uint64_t{4} << kStrideShift;
  std::int64_t step_ = 0;
};

}  // namespace grainwave::particles::dem

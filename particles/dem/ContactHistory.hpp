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
//
// Pinning (for a Verlet list; the way LAMMPS keeps shear history beside its neighbour list):
// pin() takes the list's pairs in list order and moves each one's data into a dense array at
// the pair's position in the list, where touch_pinned() finds it without a lookup. The table
// slot stays as the pair's record (its key and where the data is), so find(), touch(), adopt()
// and the listings see pinned pairs like any other. Why: the list visits its pairs in cell
// order while the table keeps them in id order. On the 20 000-particle bench bed a third of
// the lookups (through a per-pair hint of the slot, before stop 32) jumped more than 64 slots,
// and the touches took a third of the step, nearly all of it waiting for the entry's first
// line. Pinned, the walk is in list order. Pinned data never moves (a purge moves only the
// records), so pointers to it stay valid until the next pin() or restore().
#include "particles/ParticleStore.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
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
  static constexpr std::uint32_t kNotPinned = 0xffffffffu;
  /// In a table slot: where a pinned pair's data is (its position in the pinned list), else
  /// kNotPinned. Entries handed out (pointers to data, listings) always say kNotPinned.
  std::uint32_t pinned = kNotPinned;
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
  /// Pins the pairs `keys` (any order within a pair) at positions 0, 1, ... (see the header),
  /// unpinning the previous set first. A pair listed twice is pinned at its first position;
  /// touch_pinned() of a later one finds it by the lookup.
  void pin(std::span<const std::pair<std::int64_t, std::int64_t>> keys);
  /// Puts every pinned pair's data back into its table slot.
  void unpin();
  /// Counts pin() and restore() calls: a caller that pinned at generation g knows its positions
  /// still hold while pin_generation() == g.
  std::uint64_t pin_generation() const { return pin_generation_; }
  std::size_t pinned_count() const { return pinned_.size(); }
  /// touch_pinned() starts loading the entry this many list positions ahead (measured on the
  /// bench bed, 20 000 particles: 8.1-8.2 M particle-steps/s at 8, 8.4-8.6 M at 16, 7.1-8.4 M
  /// at 32, 7.3-7.8 M without).
  static constexpr std::size_t kPinnedPrefetchAhead = 16;
  /// touch() of the pair (a, b) pinned at `position`: its data, without a lookup when the pair
  /// has touched since the pin or had an entry then (else the lookup inserts its record). A
  /// position that holds another pair is looked up the usual way. Requires !nearly_full().
  ContactHistoryEntry* touch_pinned(std::size_t position, std::int64_t a, std::int64_t b) {
    if (a > b) std::swap(a, b);
    // The touches come in list order, but only the touching pairs': the hardware prefetcher
    // missed most of them (the first read of the entry took 10% of the bench step).
    __builtin_prefetch(pinned_.data() + std::min(position + kPinnedPrefetchAhead, pinned_.size() - 1), 1);
    ContactHistoryEntry& e = pinned_[position];
    if (e.last_step >= 0 && e.first == a && e.second == b) return renew(e);
    return touch_unassigned_pin(position, a, b);
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
  /// Memory held: the table, its spare for purges and the pinned data.
  std::size_t bytes() const {
    return (slots_.capacity() + spare_.capacity() + pinned_.capacity()) * sizeof(ContactHistoryEntry);
  }
  /// Mean number of slots a lookup of a stored entry reads (1 when every entry sits at its
  /// home): how well the table spreads its keys.
  double mean_probe_length() const;
  std::int64_t step() const { return step_; }
  static constexpr std::size_t bytes_per_entry() { return sizeof(ContactHistoryEntry); }

 private:
  bool live(const ContactHistoryEntry& e) const { return e.last_step >= step_ - 1; }
  /// A table slot's data: the slot itself, or a pinned pair's entry in pinned_.
  ContactHistoryEntry& data(ContactHistoryEntry& slot) {
    return slot.pinned == ContactHistoryEntry::kNotPinned ? slot : pinned_[slot.pinned];
  }
  const ContactHistoryEntry& data(const ContactHistoryEntry& slot) const {
    return slot.pinned == ContactHistoryEntry::kNotPinned ? slot : pinned_[slot.pinned];
  }
  static constexpr std::size_t kNoSlot = static_cast<std::size_t>(-1);
  /// Index of the slot holding the pair (a <= b), or kNoSlot.
  std::size_t slot_of(std::int64_t a, std::int64_t b) const;
  /// touch_pinned() of a pair with no data yet at its position (or not pinned there).
  ContactHistoryEntry* touch_unassigned_pin(std::size_t position, std::int64_t a, std::int64_t b);
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
  /// Pinned pairs' data, in pin() order; last_step -1: no data yet (the pair had no entry at
  /// the pin and has not touched since).
  std::vector<ContactHistoryEntry> pinned_;
  std::uint64_t pin_generation_ = 0;
  std::size_t occupied_ = 0;  ///< non-empty slots, live or stale
  std::uint64_t id_span_ = 0;  ///< one past the largest particle id keyed so far
  static constexpr int kStrideShift = 16;
  /// Slots between the homes of consecutive ids, in units of 2^-kStrideShift slot.
  std::uint64_t stride_ = std::uint64_t{4} << kStrideShift;
  std::int64_t step_ = 0;
};

}  // namespace grainwave::particles::dem

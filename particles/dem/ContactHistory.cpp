#include "particles/dem/ContactHistory.hpp"

#include <algorithm>
#include <utility>

namespace grainwave::particles::dem {

std::size_t ContactHistory::home(std::int64_t a, std::int64_t b) const {
  // Homes follow the particle id: all contacts of the particle with the smaller id (a wall's
  // contact: of its particle) sit side by side, and the ids seen are spread over the whole
  // table by a fractional stride (capacity / id span, in 1/2^16 of a slot), so the lookups of a
  // cell-ordered contact list walk the table nearly sequentially and the local load is the
  // table's load, also while the table is smaller than the id span. (A whole-slot stride of at
  // least 1 overloaded the homes then: the first evaluation of a 20 000-particle bed, growing
  // its table through sizes below the id span, walked 124 M slots for 131 000 lookups.)
  // (Keyed by the wall instead, a floor's contacts would all share one home.)
  return static_cast<std::size_t>((stride_ * static_cast<std::uint64_t>(a < 0 ? b : a)) >> kStrideShift) &
         (slots_.size() - 1);
}

void ContactHistory::note_key(std::int64_t a, std::int64_t b) {
  const auto key = static_cast<std::uint64_t>(a < 0 ? b : a);
  if (key >= id_span_) id_span_ = key + 1;
}

void ContactHistory::choose_stride(std::size_t capacity) {
  // Ids beyond the span (seen after this rehash) wrap around the table: any home is correct.
  stride_ = id_span_ > 0 ? std::max<std::uint64_t>(1, (std::uint64_t{capacity} << kStrideShift) / id_span_)
                         : std::uint64_t{4} << kStrideShift;
}

void ContactHistory::prepare() {
  // Purge at a load of 0.7; a purge leaves live entries at most half the table, so with a few
  // per cent of contacts renewed per step purges come every few tens of steps.
  if (slots_.empty() || 10 * occupied_ > 7 * slots_.size()) make_room();
}

void ContactHistory::make_room() {
  // What the rehash keeps: live entries and pinned pairs' records (live or not).
  const auto kept = static_cast<std::size_t>(std::count_if(
      slots_.begin(), slots_.end(), [this](const ContactHistoryEntry& e) {
        return e.last_step >= 0 && (e.pinned != ContactHistoryEntry::kNotPinned || live(e));
      }));
  std::size_t capacity = std::max<std::size_t>(slots_.size(), 64);
  while (2 * (kept + 1) > capacity) capacity *= 2;
  rehash(capacity);
}

void ContactHistory::rehash(std::size_t new_capacity) {
  choose_stride(new_capacity);
  spare_.assign(new_capacity, ContactHistoryEntry{});
  std::swap(slots_, spare_);
  occupied_ = 0;
  for (const ContactHistoryEntry& e : spare_) {
    // A pinned pair's record stays while it is pinned: its data is at its position.
    if (e.last_step < 0 || (e.pinned == ContactHistoryEntry::kNotPinned && !live(e))) continue;
    std::size_t k = home(e.first, e.second);
    while (slots_[k].last_step >= 0) k = (k + 1) & (slots_.size() - 1);
    slots_[k] = e;
    ++occupied_;
  }
}

ContactHistoryEntry* ContactHistory::touch(std::int64_t a, std::int64_t b) {
  if (a > b) std::swap(a, b);
  note_key(a, b);
  std::size_t k = home(a, b);
  while (true) {
    ContactHistoryEntry& e = slots_[k];
    if (e.last_step < 0) {
      e = ContactHistoryEntry{a, b, step_, Vec3::Zero(), Vec3::Zero(), true};
      ++occupied_;
      return &e;
    }
    if (e.first == a && e.second == b) return renew(data(e));
    k = (k + 1) & (slots_.size() - 1);
  }
}

std::size_t ContactHistory::slot_of(std::int64_t a, std::int64_t b) const {
  if (slots_.empty()) return kNoSlot;
  std::size_t k = home(a, b);
  while (slots_[k].last_step >= 0) {
    if (slots_[k].first == a && slots_[k].second == b) return k;
    k = (k + 1) & (slots_.size() - 1);
  }
  return kNoSlot;
}

void ContactHistory::unpin() {
  for (ContactHistoryEntry& slot : slots_) {
    if (slot.last_step < 0 || slot.pinned == ContactHistoryEntry::kNotPinned) continue;
    slot = pinned_[slot.pinned];  // pinned data always has last_step >= 0 once it has a record
    slot.pinned = ContactHistoryEntry::kNotPinned;
  }
  pinned_.clear();
}

void ContactHistory::pin(std::span<const std::pair<std::int64_t, std::int64_t>> keys) {
  unpin();
  ++pin_generation_;
  pinned_.resize(keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k) {
    auto [a, b] = keys[k];
    if (a > b) std::swap(a, b);
    ContactHistoryEntry& d = pinned_[k];
    d = ContactHistoryEntry{a, b, -1, Vec3::Zero(), Vec3::Zero(), true};
    const std::size_t s = slot_of(a, b);
    if (s == kNoSlot || slots_[s].pinned != ContactHistoryEntry::kNotPinned) continue;  // none, or listed twice
    d = slots_[s];
    slots_[s].pinned = static_cast<std::uint32_t>(k);
  }
}

ContactHistoryEntry* ContactHistory::touch_unassigned_pin(std::size_t position, std::int64_t a, std::int64_t b) {
  ContactHistoryEntry& d = pinned_[position];
  if (d.first != a || d.second != b) return touch(a, b);  // another pair's position
  ContactHistoryEntry* e = touch(a, b);  // the pair's data, its record inserted if new
  if (e < slots_.data() || e >= slots_.data() + slots_.size()) return e;  // pinned elsewhere (listed twice)
  // The record holds the data (a new pair, or one stored by another path since the pin): the
  // data moves here and the record points to it.
  d = *e;
  e->pinned = static_cast<std::uint32_t>(position);
  return &d;
}

const ContactHistoryEntry* ContactHistory::find(std::int64_t a, std::int64_t b) const {
  if (a > b) std::swap(a, b);
  const std::size_t k = slot_of(a, b);
  if (k == kNoSlot) return nullptr;
  const ContactHistoryEntry& e = data(slots_[k]);
  return live(e) ? &e : nullptr;
}

double ContactHistory::mean_probe_length() const {
  std::size_t entries = 0, probes = 0;
  for (std::size_t k = 0; k < slots_.size(); ++k) {
    const ContactHistoryEntry& e = slots_[k];
    if (e.last_step < 0) continue;
    ++entries;
    probes += ((k - home(e.first, e.second)) & (slots_.size() - 1)) + 1;
  }
  return entries > 0 ? static_cast<double>(probes) / static_cast<double>(entries) : 0.0;
}

std::size_t ContactHistory::live_count() const {
  return static_cast<std::size_t>(std::count_if(
      slots_.begin(), slots_.end(), [this](const ContactHistoryEntry& e) {
        return e.last_step >= 0 && live(data(e));
      }));
}

void ContactHistory::live_entries(std::vector<ContactHistoryEntry>& out) const {
  out.clear();
  for (const ContactHistoryEntry& e : slots_)
    if (e.last_step >= 0 && live(data(e))) out.push_back(data(e));
}

void ContactHistory::live_entries_of(const std::vector<std::int64_t>& sorted_ids,
                                     std::vector<ContactHistoryEntry>& out) const {
  if (sorted_ids.empty()) return;
  auto listed = [&](std::int64_t id) {
    return std::binary_search(sorted_ids.begin(), sorted_ids.end(), id);
  };
  for (const ContactHistoryEntry& e : slots_)
    if (e.last_step >= 0 && live(data(e)) && (listed(e.first) || listed(e.second))) out.push_back(data(e));
}

void ContactHistory::adopt(const ContactHistoryEntry& entry) {
  if (!live(entry)) return;
  // A live copy here that was touched as recently is the same contact computed alike; an older
  // one (this rank stopped seeing the pair a step ago) gives way to the sender's.
  if (const ContactHistoryEntry* here = find(entry.first, entry.second);
      here && here->last_step >= entry.last_step)
    return;
  note_key(entry.first, entry.second);
  if (slots_.empty() || nearly_full()) make_room();
  std::size_t k = home(entry.first, entry.second);
  while (slots_[k].last_step >= 0 &&
         !(slots_[k].first == entry.first && slots_[k].second == entry.second))
    k = (k + 1) & (slots_.size() - 1);
  ContactHistoryEntry& slot = slots_[k];
  if (slot.last_step < 0) ++occupied_;  // an empty slot is never pinned
  const std::uint32_t pinned = slot.pinned;
  ContactHistoryEntry& d = data(slot);  // the slot itself unless the pair is pinned
  d = entry;
  d.pinned = ContactHistoryEntry::kNotPinned;
  slot.pinned = pinned;  // a pinned pair's record keeps pointing to its data
}

void ContactHistory::restore(std::int64_t step, const std::vector<ContactHistoryEntry>& entries) {
  step_ = step;
  pinned_.clear();
  ++pin_generation_;
  std::size_t capacity = 64;
  while (2 * (entries.size() + 1) > capacity) capacity *= 2;
  for (const ContactHistoryEntry& e : entries) note_key(e.first, e.second);
  choose_stride(capacity);
  slots_.assign(capacity, ContactHistoryEntry{});
  occupied_ = 0;
  for (const ContactHistoryEntry& e : entries) {
    std::size_t k = home(e.first, e.second);
    while (slots_[k].last_step >= 0) k = (k + 1) & (slots_.size() - 1);
    slots_[k] = e;
    ++occupied_;
  }
}

}  // namespace grainwave::particles::dem

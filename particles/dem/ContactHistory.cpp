#include "particles/dem/ContactHistory.hpp"

#include <algorithm>
#include <utility>

namespace grainwave::particles::dem {

std::size_t ContactHistory::home(std::int64_t a, std::int64_t b) const {
  // splitmix64-style finaliser of the two ids; capacity is a power of two.
  std::uint64_t h = static_cast<std::uint64_t>(a) * 0x9E3779B97F4A7C15ull ^
                    (static_cast<std::uint64_t>(b) + 0x632BE59BD9B4E019ull);
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<std::size_t>(h) & (slots_.size() - 1);
}

void ContactHistory::prepare(std::size_t incoming) {
  const std::size_t needed = occupied_ + incoming;
  if (!slots_.empty() && 2 * needed <= slots_.size()) return;
  // Purging alone suffices when live entries plus newcomers fill at most a quarter.
  const std::size_t live = live_count();
  std::size_t capacity = std::max<std::size_t>(slots_.size(), 64);
  while (4 * (live + incoming) > capacity) capacity *= 2;
  rehash(capacity);
}

void ContactHistory::rehash(std::size_t new_capacity) {
  spare_.assign(new_capacity, ContactHistoryEntry{});
  std::swap(slots_, spare_);
  occupied_ = 0;
  for (const ContactHistoryEntry& e : spare_) {
    if (e.last_step < 0 || !live(e)) continue;
    std::size_t k = home(e.first, e.second);
    while (slots_[k].last_step >= 0) k = (k + 1) & (slots_.size() - 1);
    slots_[k] = e;
    ++occupied_;
  }
}

ContactHistoryEntry* ContactHistory::touch(std::int64_t a, std::int64_t b) {
  if (a > b) std::swap(a, b);
  std::size_t k = home(a, b);
  while (true) {
    ContactHistoryEntry& e = slots_[k];
    if (e.last_step < 0) {
      e = ContactHistoryEntry{a, b, step_, Vec3::Zero(), Vec3::Zero(), true};
      ++occupied_;
      return &e;
    }
    if (e.first == a && e.second == b) {
      if (!live(e)) {
        e.displacement.setZero();
        e.stage_velocity.setZero();
        e.is_new = true;
      }
      e.last_step = step_;
      return &e;
    }
    k = (k + 1) & (slots_.size() - 1);
  }
}

const ContactHistoryEntry* ContactHistory::find(std::int64_t a, std::int64_t b) const {
  if (slots_.empty()) return nullptr;
  if (a > b) std::swap(a, b);
  std::size_t k = home(a, b);
  while (slots_[k].last_step >= 0) {
    const ContactHistoryEntry& e = slots_[k];
    if (e.first == a && e.second == b) return live(e) ? &e : nullptr;
    k = (k + 1) & (slots_.size() - 1);
  }
  return nullptr;
}

std::size_t ContactHistory::live_count() const {
  return static_cast<std::size_t>(std::count_if(
      slots_.begin(), slots_.end(), [this](const ContactHistoryEntry& e) {
        return e.last_step >= 0 && live(e);
      }));
}

}  // namespace grainwave::particles::dem

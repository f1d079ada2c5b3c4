#include "particles/hardsphere/EventCalendar.hpp"

#include <algorithm>
#include <cmath>

namespace grainwave::particles::hardsphere {

void EventCalendar::reset(std::span<const double> times) {
  const std::size_t n = times.size();
  link_.assign(n, Link{0.0, kNone, kNone, kInOverflow, 0});
  for (std::size_t i = 0; i < n; ++i) link_[i].time = times[i];
  // About two particles per bucket (see rebuild()), over a revolution of 2N to 4N buckets.
  buckets_ = 8;
  while (static_cast<std::size_t>(buckets_) < 2 * n) buckets_ *= 2;
  head_.assign(static_cast<std::size_t>(buckets_) + 1, kNone);
  heap_.clear();
  heap_.reserve(n);
  rebuilds_ = 0;
  rebuild();
  rebuilds_ = 0;  // the set-up is not a re-choice of width
}

void EventCalendar::link(int i, int list) {
  Link& l = link_[static_cast<std::size_t>(i)];
  int& head = head_[static_cast<std::size_t>(list)];
  l.prev = kNone;
  l.next = head;
  if (head != kNone) link_[static_cast<std::size_t>(head)].prev = i;
  head = i;
  if (list == buckets_) {
    l.where = kInOverflow;
    ++in_overflow_;
  } else {
    l.where = list;
    ++in_buckets_;
  }
}

void EventCalendar::unlink(int i) {
  const Link& l = link_[static_cast<std::size_t>(i)];
  const int list = l.where == kInOverflow ? buckets_ : l.where;
  if (l.prev != kNone) link_[static_cast<std::size_t>(l.prev)].next = l.next;
  else head_[static_cast<std::size_t>(list)] = l.next;
  if (l.next != kNone) link_[static_cast<std::size_t>(l.next)].prev = l.prev;
  --(l.where == kInOverflow ? in_overflow_ : in_buckets_);
}

void EventCalendar::place(int i) {
  // s >= current_ + 1 and s < current_ + buckets_ make floor(s) a bucket of this revolution,
  // after the current one; NaN and +inf fail both tests and wait in the overflow.
  const double s = (link_[static_cast<std::size_t>(i)].time - origin_) / width_;
  const auto current = static_cast<double>(current_);
  if (s < current + 1.0) {
    heap_push(i);
  } else if (s < current + static_cast<double>(buckets_)) {
    link(i, static_cast<int>(static_cast<std::int64_t>(s) & (buckets_ - 1)));
  } else {
    link(i, buckets_);
  }
}

void EventCalendar::update(int i, double time) {
  if (link_[static_cast<std::size_t>(i)].where == kInHeap) heap_remove(i);
  else unlink(i);
  link_[static_cast<std::size_t>(i)].time = time;
  place(i);
}

int EventCalendar::top() {
  while (heap_.empty()) {
    if (!advance()) return kNone;
  }
  return heap_.front();
}

bool EventCalendar::advance() {
  // Only the overflow left: start the calendar again at its earliest time (a jump over empty
  // buckets, or the times outgrew the revolution).
  if (in_buckets_ == 0) return rebuild();
  ++current_;
  if ((current_ & (buckets_ - 1)) == 0) {
    // A revolution ended. A width far from about two particles per bucket (the system heated or
    // cooled), or an overflow holding half the particles, is chosen again; otherwise the
    // overflow's times that fall within the next revolution join their buckets.
    const auto loaded = loaded_in_revolution_;
    loaded_in_revolution_ = 0;
    if (16 * loaded < buckets_ || loaded > 16 * static_cast<std::int64_t>(buckets_) ||
        2 * in_overflow_ > static_cast<std::int64_t>(link_.size())) {
      ++rebuilds_;
      return rebuild();
    }
    for (int i = head_[static_cast<std::size_t>(buckets_)]; i != kNone;) {
      const int next = link_[static_cast<std::size_t>(i)].next;
      const double s = (link_[static_cast<std::size_t>(i)].time - origin_) / width_;
      if (s < static_cast<double>(current_ + buckets_)) {
        unlink(i);
        place(i);
      }
      i = next;
    }
  }
  int& head = head_[static_cast<std::size_t>(current_ & (buckets_ - 1))];
  for (int i = head; i != kNone;) {
    const int next = link_[static_cast<std::size_t>(i)].next;
    --in_buckets_;
    heap_push(i);
    i = next;
  }
  head = kNone;
  return true;
}

bool EventCalendar::rebuild() {
  // Every particle is placed anew from an empty calendar whose first bucket starts at the
  // earliest finite time. Width: the mean distance of the finite times from the earliest, over
  // half their number, so that a bucket holds about two times when they spread evenly (a
  // Poisson stream of events of mean spacing mean / n per particle gives the same).
  double earliest = INFINITY;
  for (const Link& l : link_) earliest = std::isfinite(l.time) ? std::min(earliest, l.time) : earliest;
  std::fill(head_.begin(), head_.end(), kNone);
  heap_.clear();
  in_buckets_ = in_overflow_ = 0;
  loaded_in_revolution_ = 0;
  current_ = 0;
  const bool any = std::isfinite(earliest);
  if (any) {
    double spread = 0.0;
    std::size_t finite = 0;
    for (const Link& l : link_) {
      if (!std::isfinite(l.time)) continue;
      spread += l.time - earliest;
      ++finite;
    }
    origin_ = earliest;
    const double mean = spread / static_cast<double>(finite);
    width_ = mean > 0.0 ? 2.0 * mean / static_cast<double>(finite) : 1.0;
    // A width below the spacing of doubles near the origin would put distinct buckets at one
    // time; the floor keeps s = (t - origin) / width well inside the 53-bit range.
    width_ = std::max(width_, 1e-12 * std::max(1.0, std::abs(origin_)));
  }
  for (int i = 0; i < static_cast<int>(link_.size()); ++i) place(i);
  return any;
}

void EventCalendar::set_slot(int slot, int i) {
  heap_[static_cast<std::size_t>(slot)] = i;
  link_[static_cast<std::size_t>(i)].heap_slot = slot;
}

void EventCalendar::heap_push(int i) {
  link_[static_cast<std::size_t>(i)].where = kInHeap;
  ++loaded_in_revolution_;
  heap_.push_back(i);  // reserved for every particle in reset(): no allocation
  sift_up(static_cast<int>(heap_.size()) - 1);
}

void EventCalendar::heap_remove(int i) {
  const int slot = link_[static_cast<std::size_t>(i)].heap_slot;
  const int last = heap_.back();
  heap_.pop_back();
  if (last == i) return;
  set_slot(slot, last);
  sift_up(slot);
  sift_down(link_[static_cast<std::size_t>(last)].heap_slot);
}

void EventCalendar::sift_up(int slot) {
  const int i = heap_[static_cast<std::size_t>(slot)];
  while (slot > 0) {
    const int parent = (slot - 1) / 2;
    if (!before(i, heap_[static_cast<std::size_t>(parent)])) break;
    set_slot(slot, heap_[static_cast<std::size_t>(parent)]);
    slot = parent;
  }
  set_slot(slot, i);
}

void EventCalendar::sift_down(int slot) {
  const int n = static_cast<int>(heap_.size());
  const int i = heap_[static_cast<std::size_t>(slot)];
  while (true) {
    int child = 2 * slot + 1;
    if (child >= n) break;
    if (child + 1 < n && before(heap_[static_cast<std::size_t>(child + 1)], heap_[static_cast<std::size_t>(child)])) ++child;
    if (!before(heap_[static_cast<std::size_t>(child)], i)) break;
    set_slot(slot, heap_[static_cast<std::size_t>(child)]);
    slot = child;
  }
  set_slot(slot, i);
}

}  // namespace grainwave::particles::hardsphere

#pragma once
// The event queue of the event-driven collider: one pending time per particle, and the earliest
// of them on demand. A bounded calendar queue in the manner of Paul (J. Comput. Phys. 221, 615,
// 2007): time is cut into buckets of width `width`, a circular array of them covers the next
// revolution (buckets * width), each bucket holds its particles in an unsorted doubly linked
// list, and only the bucket being worked through is ordered (a small binary heap). Times beyond
// the revolution wait in an overflow list, rescanned once per revolution.
//
// Why not a heap over all particles: a change of time costs O(log N) dependent cache misses in a
// heap, and each collision changes two to four times. Here it costs an unlink and a link (three
// particles' links) plus, for the current bucket only, a sift in a heap of a few entries. The
// width is chosen so that a bucket holds about two particles (from the mean time to the next
// event at set-up), and re-chosen when the buckets run much emptier or the overflow much fuller.
//
// Order: earliest time first, ties to the lower particle index (a fixed rule, so a run does not
// depend on how the queue happened to be arranged). The bucket of a time is floor((t - origin) /
// width), a non-decreasing function of t, so every particle outside the current bucket's heap has
// a time no earlier than every particle in it: the heap's top is the earliest overall.
#include <cstdint>
#include <span>
#include <vector>

#include "core/HugePageAllocator.hpp"

namespace grainwave::particles::hardsphere {

class EventCalendar {
 public:
  /// Takes the times of all particles (index = particle). Allocates; later calls do not.
  void reset(std::span<const double> times);

  /// Particle i's time changed (to no earlier than the time of the last top()).
  void update(int i, double time);

  /// The particle with the earliest time, or -1 if none has a finite one.
  int top();
  /// A particle likely to come after top() (the runner-up in the current bucket, else the first
  /// of the next bucket), or -1: a hint for prefetching its state, never needed for order.
  int upcoming() const {
    if (heap_.size() > 1) return heap_[1];
    return heap_.empty() ? kNone : head_[static_cast<std::size_t>((current_ + 1) & (buckets_ - 1))];
  }
  /// Starts loading particle i's entry (it is about to be updated or popped).
  void prefetch(int i) const { __builtin_prefetch(&link_[static_cast<std::size_t>(i)]); }
  /// Starts loading the entries an update() of particle i will change besides its own (its
  /// neighbours in a bucket or the overflow list). Reads i's entry: call prefetch(i) well before.
  void prefetch_neighbours(int i) const {
    const Link& l = link_[static_cast<std::size_t>(i)];
    if (l.where == kInHeap) return;
    if (l.prev != kNone) __builtin_prefetch(&link_[static_cast<std::size_t>(l.prev)]);
    if (l.next != kNone) __builtin_prefetch(&link_[static_cast<std::size_t>(l.next)]);
  }
  double time(int i) const { return link_[static_cast<std::size_t>(i)].time; }

  std::size_t size() const { return link_.size(); }
  /// Rebuilds with a new bucket width so far (diagnostics and tests).
  long rebuilds() const { return rebuilds_; }

 private:
  static constexpr int kNone = -1;
  static constexpr int kInHeap = -1;      ///< where_ of a particle in the current bucket's heap
  static constexpr int kInOverflow = -2;  ///< where_ of a particle beyond the revolution

  /// A particle's time and links, together: every operation on a particle reads both, and
  /// for large N each particle touched is a cache miss.
  struct alignas(32) Link {
    double time;
    int next, prev;  ///< neighbours in the bucket or overflow list (kNone at the ends)
    int where;       ///< bucket index, kInHeap or kInOverflow
    int heap_slot;   ///< position in heap_ while where == kInHeap
  };

  /// Bucket heads, then the overflow list's head at index buckets_.
  void link(int i, int list);
  void unlink(int i);
  void place(int i);  ///< into the heap, a bucket or the overflow, by its time
  bool before(int a, int b) const {
    const double ta = link_[static_cast<std::size_t>(a)].time, tb = link_[static_cast<std::size_t>(b)].time;
    return ta < tb || (ta == tb && a < b);
  }
  void heap_push(int i);
  void heap_remove(int i);
  void sift_up(int slot);
  void sift_down(int slot);
  void set_slot(int slot, int i);
  /// Moves on to the next bucket (rescanning the overflow at a revolution's end); false when
  /// nothing with a finite time is left.
  bool advance();
  /// Origin at the earliest finite time, width from the spread of the times, everything placed
  /// anew; false when no time is finite.
  bool rebuild();

  HugePageVector<Link> link_;
  HugePageVector<int> head_;     ///< buckets_ bucket heads and the overflow head
  std::vector<int> heap_;     ///< the current bucket's particles, a binary min-heap
  int buckets_ = 1;           ///< a power of two
  std::int64_t current_ = 0;  ///< bucket being worked through, counted from origin_
  double origin_ = 0.0, width_ = 1.0;
  std::int64_t in_buckets_ = 0;  ///< particles in bucket lists (not heap, not overflow)
  std::int64_t in_overflow_ = 0;
  std::int64_t loaded_in_revolution_ = 0;  ///< particles entering the heap since it began
  long rebuilds_ = 0;
};

}  // namespace grainwave::particles::hardsphere

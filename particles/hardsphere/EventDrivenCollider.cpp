#include "particles/hardsphere/EventDrivenCollider.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/Error.hpp"
#include "particles/hardsphere/CollisionTime.hpp"

#if GRAINWAVE_AVX2_SCAN
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace grainwave::particles::hardsphere {

namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

/// First t >= 0 at which g(t) = c + b t + a t^2 reaches 0 while decreasing (g >= 0 is "inside").
/// With g already negative: `outside_is_now` (a particle past a cell face: cross at once), or
/// else (a particle a round-off into a wall) the first moment it moves further in.
double first_descent(double c, double b, double a, bool outside_is_now) {
  if (c < 0.0) {
    if (outside_is_now || b < 0.0) return 0.0;
    if (a >= 0.0) return kNever;                          // leaves for good
    if (b * b - 4.0 * a * c < 0.0) return -b / (2.0 * a);  // turns round before getting out
    // Otherwise it gets out, and the descending root below is its next contact.
  }
  if (a == 0.0) return b < 0.0 ? -c / b : kNever;
  const double discriminant = b * b - 4.0 * a * c;
  if (discriminant < 0.0) return kNever;
  const double q = -0.5 * (b + std::copysign(std::sqrt(discriminant), b));
  if (q == 0.0) return a < 0.0 ? 0.0 : kNever;  // b = c = 0: leaves at once iff pulled outward
  double best = kNever;
  for (double t : {q / a, c / q}) {
    if (t >= 0.0 && b + 2.0 * a * t < 0.0) best = std::min(best, t);
  }
  return best;
}

}  // namespace

EventDrivenCollider::EventDrivenCollider(EventDrivenSettings settings) : settings_(settings) {
  validate(settings_.law, "hardsphere");
#if GRAINWAVE_AVX2_SCAN
  // The AVX2 paths also use POPCNT and BMI1 (every AVX2 machine has them; checked all the same).
  avx2_ = settings_.vector_scan && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt") &&
          __builtin_cpu_supports("bmi");
#endif
}

int EventDrivenCollider::cell_index(const std::array<int, 3>& c) const {
  return (c[2] * cells_[1] + c[1]) * cells_[0] + c[0];
}

double EventDrivenCollider::key(int i) const {
  const Pending& p = pending_[static_cast<std::size_t>(i)];
  return std::min(p.collision_time, p.crossing_time);
}

void EventDrivenCollider::predict_and_schedule(int i, int layer) {
  predict(i, layer);
  calendar_.update(i, key(i));
}

void EventDrivenCollider::sync(int i, double t) {
  const auto k = static_cast<std::size_t>(i);
  Flight& f = flight_[k];
  const double tau = t - f.clock;
  if (tau == 0.0) return;
  // Fixed particles exist only with zero acceleration (initialize), so one a serves all.
  f.position += f.velocity * tau + 0.5 * acceleration_ * tau * tau;
  f.velocity += acceleration_ * tau;
  if (spinning_) {  // else the angular velocities change only in collisions
    Spin& spin = spin_[k];
    spin.angular_velocity += spin.angular_acceleration * tau;
  }
  f.clock = t;
}

double EventDrivenCollider::next_crossing(int i, const Vec3& x, const Vec3& v, int* face) const {
  const auto k = static_cast<std::size_t>(i);
#if GRAINWAVE_AVX2_SCAN
  if (avx2_ && !accelerated_) return next_crossing_avx2(pending_[k], x, v, face);
#endif
  const Vec3& a = acceleration_;
  // Exit times through the low and high face of each axis (+inf where impossible), then the
  // earliest, the first in the order x low, x high, y low, ... on a tie. Which face comes first
  // is data-dependent, so both steps select rather than branch (the compiler turns the scalar
  // selects of the unaccelerated formula into branches, hence SSE2 there).
  std::array<double, 6> exit{};
  for (int axis = 0; axis < 3; ++axis) {
    const auto ax = static_cast<std::size_t>(axis);
    const int c = pending_[k].cell[ax];
    const double gap_low = x[axis] - (lo_[axis] + c * cell_size_[ax]);
    const double gap_high = lo_[axis] + (c + 1) * cell_size_[ax] - x[axis];
    double low, high;
    if (accelerated_) {
      low = first_descent(gap_low, v[axis], 0.5 * a[axis], true);
      high = first_descent(gap_high, -v[axis], -0.5 * a[axis], true);
    } else {
      // first_descent(gap, rate, 0, true): gap < 0 ? 0 : rate < 0 ? -gap / rate : +inf, for the
      // pair (low, high) with rates (v, -v).
#if defined(__SSE2__)
      const __m128d gap = _mm_set_pd(gap_high, gap_low), rate = _mm_set_pd(-v[axis], v[axis]);
      const __m128d zero = _mm_setzero_pd(), sign = _mm_set1_pd(-0.0);
      const __m128d ahead = _mm_div_pd(_mm_xor_pd(gap, sign), rate);
      const __m128d approaching = _mm_cmplt_pd(rate, zero);
      const __m128d t = _mm_or_pd(_mm_and_pd(approaching, ahead),
                                  _mm_andnot_pd(approaching, _mm_set1_pd(kNever)));
      const __m128d exit_time = _mm_andnot_pd(_mm_cmplt_pd(gap, zero), t);
      low = _mm_cvtsd_f64(exit_time);
      high = _mm_cvtsd_f64(_mm_unpackhi_pd(exit_time, exit_time));
#else
      low = gap_low < 0.0 ? 0.0 : (v[axis] < 0.0 ? -gap_low / v[axis] : kNever);
      high = gap_high < 0.0 ? 0.0 : (-v[axis] < 0.0 ? -gap_high / -v[axis] : kNever);
#endif
    }
    // Leaving through a wall face is impossible (the wall collision comes first).
    const bool active = axis < dimension_;
    exit[2 * ax] = active && (c > 0 || periodic_[ax]) ? low : kNever;
    exit[2 * ax + 1] = active && (c < cells_[ax] - 1 || periodic_[ax]) ? high : kNever;
  }
  double best = kNever;
  int best_face = *face;
  for (std::size_t f = 0; f < 6; ++f) {
    best_face = exit[f] < best ? static_cast<int>(f) : best_face;
    best = exit[f] < best ? exit[f] : best;
  }
  *face = best_face;
  return best;
}

#if GRAINWAVE_AVX2_SCAN
[[gnu::target("avx2,popcnt,bmi")]] double EventDrivenCollider::next_crossing_avx2(const Pending& p, const Vec3& x,
                                                                               const Vec3& v, int* face) const {
  // next_crossing()'s formula without acceleration, the axes as lanes (x, y, z, unused): the
  // same operations, so the same times, and the same face (the first of x low, x high, y low,
  // ... at the earliest; NaNs passed over, as `exit < best` does).
  const __m256d zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0), never = _mm256_set1_pd(kNever);
  const __m256d position = _mm256_setr_pd(x[0], x[1], x[2], 0.0);
  const __m256d rate = _mm256_setr_pd(v[0], v[1], v[2], 0.0);
  const __m128i cell = _mm_setr_epi32(p.cell[0], p.cell[1], p.cell[2], 0);  // widened
  const __m256d lo = _mm256_loadu_pd(crossing_lo_.data()), size = _mm256_loadu_pd(crossing_size_.data());
  const __m256d low_face = _mm256_add_pd(lo, _mm256_mul_pd(_mm256_cvtepi32_pd(cell), size));
  const __m256d high_face =
      _mm256_add_pd(lo, _mm256_mul_pd(_mm256_cvtepi32_pd(_mm_add_epi32(cell, _mm_set1_epi32(1))), size));
  // gap < 0 ? 0 : rate < 0 ? -gap / rate : +inf, for the low faces (rate v) and the high (-v).
  const __m256d gap_low = _mm256_sub_pd(position, low_face), gap_high = _mm256_sub_pd(high_face, position);
  const __m256d rate_high = _mm256_xor_pd(rate, sign);
  __m256d low = _mm256_blendv_pd(never, _mm256_div_pd(_mm256_xor_pd(gap_low, sign), rate),
                                 _mm256_cmp_pd(rate, zero, _CMP_LT_OQ));
  __m256d high = _mm256_blendv_pd(never, _mm256_div_pd(_mm256_xor_pd(gap_high, sign), rate_high),
                                  _mm256_cmp_pd(rate_high, zero, _CMP_LT_OQ));
  low = _mm256_andnot_pd(_mm256_cmp_pd(gap_low, zero, _CMP_LT_OQ), low);
  high = _mm256_andnot_pd(_mm256_cmp_pd(gap_high, zero, _CMP_LT_OQ), high);
  // Leaving through a wall face is impossible (the wall collision comes first).
  const __m256i active = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(crossing_active_.data()));
  const __m256i periodic = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(crossing_periodic_.data()));
  const __m128i last = _mm_setr_epi32(cells_[0] - 1, cells_[1] - 1, cells_[2] - 1, 0);
  const __m256i above_first = _mm256_cvtepi32_epi64(_mm_cmpgt_epi32(cell, _mm_setzero_si128()));
  const __m256i below_last = _mm256_cvtepi32_epi64(_mm_cmpgt_epi32(last, cell));
  low = _mm256_blendv_pd(never, low, _mm256_castsi256_pd(_mm256_and_si256(active, _mm256_or_si256(above_first, periodic))));
  high = _mm256_blendv_pd(never, high, _mm256_castsi256_pd(_mm256_and_si256(active, _mm256_or_si256(below_last, periodic))));
  // min_pd(a, b) is a < b ? a : b: a NaN in a leaves b.
  __m256d best = _mm256_min_pd(high, _mm256_min_pd(low, never));
  best = _mm256_min_pd(_mm256_permute4x64_pd(best, 0x4e), best);
  best = _mm256_min_pd(_mm256_permute_pd(best, 0x5), best);
  const double earliest = _mm256_cvtsd_f64(best);
  if (!(earliest < kNever)) return kNever;  // *face as it was
  const __m256d at = _mm256_set1_pd(earliest);
  const auto lows = static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(low, at, _CMP_EQ_OQ)));
  const auto highs = static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(high, at, _CMP_EQ_OQ)));
  const unsigned in_face_order = (lows & 1u) | (highs & 1u) << 1 | (lows & 2u) << 1 | (highs & 2u) << 2 |
                                 (lows & 4u) << 2 | (highs & 4u) << 3;
  *face = std::countr_zero(in_face_order);
  return earliest;
}
#endif

void EventDrivenCollider::bin(int i, int cell) {
  // i joins the end of the cell's ring (the order a block appended in).
  int& head = head_[static_cast<std::size_t>(cell)];
  CellLink& joining = cell_link_[static_cast<std::size_t>(i)];
  if (head == kEmptyHead) {
    joining = {i, i};
    head = i;
    return;
  }
  const int first = head >= 0 ? head : first_of(head);
  CellLink& front = cell_link_[static_cast<std::size_t>(first)];
  const int last = front.prev;
  joining = {first, last};
  cell_link_[static_cast<std::size_t>(last)].next = i;
  front.prev = i;
  head = several_head(first);
}

void EventDrivenCollider::unbin(int i, int cell) {
  int& head = head_[static_cast<std::size_t>(cell)];
  if (head == i) {  // its cell's only particle
    head = kEmptyHead;
    return;
  }
  // The ring's last particle takes i's place (as a block's last slot filled the hole), so the
  // order of the rest is what it was.
  int first = first_of(head);
  CellLink& front = cell_link_[static_cast<std::size_t>(first)];
  const int last = front.prev;
  const int before_last = cell_link_[static_cast<std::size_t>(last)].prev;
  cell_link_[static_cast<std::size_t>(before_last)].next = first;
  front.prev = before_last;
  if (last != i) {
    const CellLink around = cell_link_[static_cast<std::size_t>(i)];
    const int prev = around.prev == i ? last : around.prev;  // i was alone once last left
    const int next = around.next == i ? last : around.next;
    cell_link_[static_cast<std::size_t>(last)] = {next, prev};
    cell_link_[static_cast<std::size_t>(prev)].next = last;
    cell_link_[static_cast<std::size_t>(next)].prev = last;
    if (first == i) first = last;
  }
  head = cell_link_[static_cast<std::size_t>(first)].next == first ? first : several_head(first);
}

void EventDrivenCollider::grow_candidates() {
  candidates_.resize(2 * candidates_.size(), -1);
  columns_.resize(candidates_.size());
  candidate_lines_.resize(candidates_.size());
}

int EventDrivenCollider::padded_index(const std::array<int, 3>& c) const {
  return ((c[2] + pad_[2]) * padded_cells_[1] + c[1] + pad_[1]) * padded_cells_[0] + c[0] + pad_[0];
}

bool EventDrivenCollider::needs_image(const std::array<int, 3>& c) const {
  if (imaging_interior_) return true;
  for (std::size_t ax = 0; ax < 3; ++ax)
    if (periodic_[ax] && (c[ax] == 0 || c[ax] == cells_[ax] - 1)) return true;
  return false;
}

int EventDrivenCollider::gather_adjacent(const std::array<int, 3>& c, int layer) {
  // Interior cells of a large grid find their neighbours by index arithmetic, the others in the
  // padded grid (whose border names the wrapped cell, or the empty one beyond a wall).
  const bool interior = arithmetic_interior_ && c[0] >= 1 && c[0] <= cells_[0] - 2 && c[1] >= 1 &&
                        c[1] <= cells_[1] - 2 && (dimension_ == 2 || (c[2] >= 1 && c[2] <= cells_[2] - 2));
  const auto which = static_cast<std::size_t>(layer < 0 ? kWholeStencil : layer);
  const int* offsets = interior ? interior_offset_[which].data() : padded_offset_[which].data();
  const int base = interior ? cell_index(c) : padded_index(c);
  const int count = layer < 0 ? stencil_size_ : layer_size_;
#if GRAINWAVE_AVX2_SCAN
  if (avx2_) return gather_avx2(base, offsets, count, !interior);
#endif
  std::array<int, 27> cells{};
  for (std::size_t k = 0; k < static_cast<std::size_t>(count); ++k)
    cells[k] = interior ? base + offsets[k] : padded_cell_[static_cast<std::size_t>(base + offsets[k])];
  return gather(cells.data(), count);
}

int EventDrivenCollider::gather(const int* cells, int count) {
  // Most cells hold at most one particle, which their head word names: it is written out and
  // the write position advanced by one if the cell is occupied, without a branch. The cells
  // holding several (about one in eleven in the hard-sphere gas) are marked, and their rings
  // appended after.
  const int* heads = head_.data();
  int* out = candidates_.data();
  int gathered = 0;
  std::uint32_t several = 0;
  for (int k = 0; k < count; ++k) {
    const int head = heads[cells[k]];
    out[gathered] = head;
    gathered += head >= 0 ? 1 : 0;
    several |= static_cast<std::uint32_t>(head < kEmptyHead) << k;
  }
  return append_rings(cells, several, gathered);
}

int EventDrivenCollider::append_rings(const int* cells, std::uint32_t several, int gathered) {
  // Each ring is walked from its first particle, whose link also names the last: a cell of two
  // (most of those holding several) costs one load. candidates_ keeps room for the vector stores
  // past the end (kCandidateSlack).
  for (; several != 0; several &= several - 1) {
    const int first = first_of(head_[static_cast<std::size_t>(cells[std::countr_zero(several)])]);
    const CellLink front = cell_link_[static_cast<std::size_t>(first)];
    if (static_cast<std::size_t>(gathered) + 2 + kCandidateSlack > candidates_.size()) grow_candidates();
    candidates_[static_cast<std::size_t>(gathered++)] = first;
    for (int k = front.next; k != front.prev; k = cell_link_[static_cast<std::size_t>(k)].next) {
      if (static_cast<std::size_t>(gathered) + 2 + kCandidateSlack > candidates_.size()) grow_candidates();
      candidates_[static_cast<std::size_t>(gathered++)] = k;
    }
    candidates_[static_cast<std::size_t>(gathered++)] = front.prev;
  }
  return gathered;
}

#if GRAINWAVE_AVX2_SCAN
namespace {

/// For each 8-bit mask, the positions of its set bits packed to the front, a byte each.
constexpr std::array<std::uint64_t, 256> kPackedLanes = [] {
  std::array<std::uint64_t, 256> table{};
  for (std::size_t mask = 0; mask < table.size(); ++mask) {
    int packed = 0;
    for (std::uint64_t lane = 0; lane < 8; ++lane)
      if ((mask >> lane) & 1u) table[mask] |= lane << (8 * packed++);
  }
  return table;
}();

}  // namespace

[[gnu::target("avx2,popcnt,bmi")]] int EventDrivenCollider::gather_avx2(int base, const int* offsets,
                                                                        int count, bool padded) {
  // gather()'s work eight cells at a time: their indices from the offsets (and the padded grid),
  // their head words by one vector gather, the occupied ones packed to the front by a
  // permutation from a table and written at once. Lanes past `count` read nothing.
  alignas(32) std::array<int, 32> cells;  // only the first count are written and read
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i empty = _mm256_set1_epi32(kEmptyHead);
  int* out = candidates_.data();
  int gathered = 0;
  std::uint32_t several = 0;
  for (int k = 0; k < count; k += 8) {
    const __m256i valid = _mm256_cmpgt_epi32(_mm256_set1_epi32(count - k), lanes);
    __m256i cell = _mm256_add_epi32(_mm256_set1_epi32(base),
                                    _mm256_loadu_si256(reinterpret_cast<const __m256i*>(offsets + k)));
    if (padded) cell = _mm256_mask_i32gather_epi32(empty, padded_cell_.data(), cell, valid, 4);
    _mm256_store_si256(reinterpret_cast<__m256i*>(cells.data() + k), cell);
    const __m256i head = _mm256_mask_i32gather_epi32(empty, head_.data(), cell, valid, 4);
    const auto single = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(head, _mm256_set1_epi32(-1)))));
    const auto full = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(empty, head))));
    const __m256i order = _mm256_cvtepu8_epi32(
        _mm_cvtsi64_si128(static_cast<long long>(kPackedLanes[single])));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + gathered), _mm256_permutevar8x32_epi32(head, order));
    gathered += std::popcount(single);
    several |= full << k;
  }
  return append_rings(cells.data(), several, gathered);
}
#endif

void EventDrivenCollider::contact_times(CandidateColumns& columns, int count, const ScanFrame& f) {
  const double* __restrict const px = columns.x.data();
  const double* __restrict const py = columns.y.data();
  const double* __restrict const pz = columns.z.data();
  const double* __restrict const wx = columns.vx.data();
  const double* __restrict const wy = columns.vy.data();
  const double* __restrict const wz = columns.vz.data();
  const double* __restrict const clock = columns.clock.data();
  const double* __restrict const radius = columns.radius.data();
  double* __restrict const times = columns.time.data();
  const double ax = f.acceleration[0], ay = f.acceleration[1], az = f.acceleration[2];
  const double lx = f.length[0], ly = f.length[1], lz = f.length[2];
  const double hx = f.half_image[0], hy = f.half_image[1], hz = f.half_image[2];
  const double xx = f.position[0], xy = f.position[1], xz = f.position[2];
  const double vx = f.velocity[0], vy = f.velocity[1], vz = f.velocity[2];
  const double now = f.now;
  const double r = f.radius;
  for (int k = 0; k < count; ++k) {
    const double tau = now - clock[k];
    // Uniform acceleration cancels in the relative motion: only velocities differ. Without
    // acceleration the added terms are zeros, which change no value (a branch would stop the
    // vectorisation).
    const double dx0 = px[k] + wx[k] * tau - xx + 0.5 * ax * tau * tau;
    const double dy0 = py[k] + wy[k] * tau - xy + 0.5 * ay * tau * tau;
    const double dz0 = pz[k] + wz[k] * tau - xz + 0.5 * az * tau * tau;
    const double ux = wx[k] - vx + ax * tau, uy = wy[k] - vy + ay * tau, uz = wz[k] - vz + az * tau;
    // Minimum image (Domain::separation) as masked adds; h is +inf on axes that are not periodic.
    double dx = dx0 - (dx0 > hx ? lx : 0.0);
    double dy = dy0 - (dy0 > hy ? ly : 0.0);
    double dz = dz0 - (dz0 > hz ? lz : 0.0);
    dx += dx < -hx ? lx : 0.0;
    dy += dy < -hy ? ly : 0.0;
    dz += dz < -hz ? lz : 0.0;
    // ballistic_contact_time_or_never (CollisionTime.hpp), spelled out on plain doubles.
    const double sigma = r + radius[k];
    const double b = dx * ux + dy * uy + dz * uz;
    const double c = dx * dx + dy * dy + dz * dz - sigma * sigma;
    const double discriminant = b * b - (ux * ux + uy * uy + uz * uz) * c;
    const double t = std::max(0.0, c / (std::sqrt(std::max(discriminant, 0.0)) - b));
    times[k] = (b < 0.0 && discriminant >= 0.0) ? now + t : kNever;
  }
}

#if GRAINWAVE_AVX2_SCAN
namespace {

/// Columns c[0..3] of the 4 x 4 block of doubles at line[0..3] + offset (row m from line[m]).
[[gnu::target("avx2"), gnu::always_inline]] inline void load_columns(const double* const* line,
                                                                     int offset, __m256d* c) {
  const __m256d r0 = _mm256_load_pd(line[0] + offset), r1 = _mm256_load_pd(line[1] + offset);
  const __m256d r2 = _mm256_load_pd(line[2] + offset), r3 = _mm256_load_pd(line[3] + offset);
  const __m256d a = _mm256_unpacklo_pd(r0, r1), b = _mm256_unpackhi_pd(r0, r1);
  const __m256d d = _mm256_unpacklo_pd(r2, r3), e = _mm256_unpackhi_pd(r2, r3);
  c[0] = _mm256_permute2f128_pd(a, d, 0x20);
  c[1] = _mm256_permute2f128_pd(b, e, 0x20);
  c[2] = _mm256_permute2f128_pd(a, d, 0x31);
  c[3] = _mm256_permute2f128_pd(b, e, 0x31);
}

}  // namespace

template <bool kAccelerated, bool kImaged>
[[gnu::target("avx2")]] double EventDrivenCollider::contact_times_avx2(const Flight* flight,
                                                                       const int* candidates,
                                                                       int count, int self,
                                                                       const ScanFrame& f,
                                                                       std::uintptr_t* lines,
                                                                       double* times) {
  // contact_times() on four candidates at a time, read straight from their Flight lines: each
  // line is two rows of four doubles (x y z clock, vx vy vz radius), and a 4 x 4 transposition
  // of four candidates' rows gives the columns, without the copy through memory. The operations
  // and their order are those of contact_times() (no FMA), so every time is bitwise the same.
  // i itself (and the padding, which is i) gets +inf here rather than being skipped later.
  const __m256d zero = _mm256_setzero_pd(), never = _mm256_set1_pd(kNever);
  const __m256d now = _mm256_set1_pd(f.now), r = _mm256_set1_pd(f.radius);
  __m256d a[3], half_a[3], length[3], half[3], minus_half[3], x[3], v[3];
  for (std::size_t k = 0; k < 3; ++k) {
    a[k] = _mm256_set1_pd(f.acceleration[k]);
    half_a[k] = _mm256_set1_pd(0.5 * f.acceleration[k]);
    length[k] = _mm256_set1_pd(f.length[k]);
    half[k] = _mm256_set1_pd(f.half_image[k]);
    minus_half[k] = _mm256_set1_pd(-f.half_image[k]);
    x[k] = _mm256_set1_pd(f.position[k]);
    v[k] = _mm256_set1_pd(f.velocity[k]);
  }
  // All candidates' lines are requested before the arithmetic, whose long division and square
  // root chains would otherwise hold back the later groups' loads (cache misses for large N).
  // Their addresses are computed four at a time (index * 64 + base, in 64-bit lanes) and kept
  // in `lines` for the loop below.
  static_assert(sizeof(Flight) == 64);
  const __m256i base = _mm256_set1_epi64x(static_cast<long long>(reinterpret_cast<std::uintptr_t>(flight)));
  for (int k = 0; k < count; k += 4) {
    const __m128i index = _mm_loadu_si128(reinterpret_cast<const __m128i*>(candidates + k));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(lines + k),
                       _mm256_add_epi64(base, _mm256_slli_epi64(_mm256_cvtepi32_epi64(index), 6)));
    for (int m = 0; m < 4; ++m) __builtin_prefetch(reinterpret_cast<const void*>(lines[k + m]));
  }
  const __m128i self4 = _mm_set1_epi32(self);
  __m256d earliest = never;
  for (int k = 0; k < count; k += 4) {
    const double* line[4];
    for (int m = 0; m < 4; ++m) line[m] = reinterpret_cast<const double*>(lines[k + m]);
    __m256d p[4], w[4];  // x y z clock; vx vy vz radius
    load_columns(line, 0, p);
    load_columns(line, 4, w);
    const __m256d tau = _mm256_sub_pd(now, p[3]);
    __m256d d[3], u[3];
    for (int m = 0; m < 3; ++m) {
      // Without acceleration the terms left out are zeros, and x + 0 is x (but for -0 + 0, whose
      // sign no later result shows); without the image the masked lengths are zeros.
      d[m] = _mm256_sub_pd(_mm256_add_pd(p[m], _mm256_mul_pd(w[m], tau)), x[m]);
      u[m] = _mm256_sub_pd(w[m], v[m]);
      if constexpr (kAccelerated) {
        d[m] = _mm256_add_pd(d[m], _mm256_mul_pd(_mm256_mul_pd(half_a[m], tau), tau));
        u[m] = _mm256_add_pd(u[m], _mm256_mul_pd(a[m], tau));
      }
      if constexpr (kImaged) {
        d[m] = _mm256_sub_pd(d[m], _mm256_and_pd(_mm256_cmp_pd(d[m], half[m], _CMP_GT_OQ), length[m]));
        d[m] = _mm256_add_pd(d[m], _mm256_and_pd(_mm256_cmp_pd(d[m], minus_half[m], _CMP_LT_OQ), length[m]));
      }
    }
    const __m256d sigma = _mm256_add_pd(r, w[3]);
    const __m256d b = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(d[0], u[0]), _mm256_mul_pd(d[1], u[1])), _mm256_mul_pd(d[2], u[2]));
    const __m256d c = _mm256_sub_pd(
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
                      _mm256_mul_pd(d[2], d[2])),
        _mm256_mul_pd(sigma, sigma));
    const __m256d uu = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(u[0], u[0]), _mm256_mul_pd(u[1], u[1])), _mm256_mul_pd(u[2], u[2]));
    const __m256d discriminant = _mm256_sub_pd(_mm256_mul_pd(b, b), _mm256_mul_pd(uu, c));
    // max_pd(p, q) is p > q ? p : q, so these are std::max(discriminant, 0.0) and
    // std::max(0.0, ...) with the same results for signed zeros and NaN.
    const __m256d root = _mm256_sqrt_pd(_mm256_max_pd(zero, discriminant));
    const __m256d t = _mm256_max_pd(_mm256_div_pd(c, _mm256_sub_pd(root, b)), zero);
    const __m256d self_mask = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm_cmpeq_epi32(
        _mm_loadu_si128(reinterpret_cast<const __m128i*>(candidates + k)), self4)));
    const __m256d touches = _mm256_andnot_pd(
        self_mask, _mm256_and_pd(_mm256_cmp_pd(b, zero, _CMP_LT_OQ),
                                 _mm256_cmp_pd(discriminant, zero, _CMP_GE_OQ)));
    const __m256d time = _mm256_blendv_pd(never, _mm256_add_pd(now, t), touches);
    _mm256_storeu_pd(times + k, time);
    earliest = _mm256_min_pd(earliest, time);
  }
  const __m128d half_min = _mm_min_pd(_mm256_castpd256_pd128(earliest), _mm256_extractf128_pd(earliest, 1));
  return _mm_cvtsd_f64(_mm_min_sd(half_min, _mm_unpackhi_pd(half_min, half_min)));
}
#endif

void EventDrivenCollider::scan(int i, int count, const Vec3& x, const Vec3& v, bool imaged, Pending& p) {
  // Contact times of all candidates in one pass without data-dependent branches, then the
  // earliest. A count that is a multiple of the vector width keeps every candidate in the
  // vectorised loop (none is left to a scalar remainder); the padding is i itself, never a
  // partner.
  pair_checks_ += count;
  const Flight* flight = flight_.data();
  int* const candidates = candidates_.data();
  for (int k = 0; k < kScanLanes - 1; ++k) candidates[count + k] = i;
  count = (count + kScanLanes - 1) / kScanLanes * kScanLanes;
  // The box's part of the frame was set by initialize().
  ScanFrame& frame = scan_frame_;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    frame.position[axis] = x[static_cast<int>(axis)];
    frame.velocity[axis] = v[static_cast<int>(axis)];
  }
  frame.now = now_;
  frame.radius = flight[i].radius;
  CandidateColumns& columns = columns_;
  double* const times = columns.time.data();
  double earliest = kNever;
#if GRAINWAVE_AVX2_SCAN
  if (avx2_) {
    const auto kernel = accelerated_ ? (imaged ? &contact_times_avx2<true, true> : &contact_times_avx2<true, false>)
                                     : (imaged ? &contact_times_avx2<false, true> : &contact_times_avx2<false, false>);
    earliest = kernel(flight, candidates, count, i, frame, candidate_lines_.data(), times);
  } else
#endif
  {
    // Portable: the candidates' flight states copied into columns (locals, not members, in the
    // loop: stores would otherwise force reloads), a loop the compiler vectorises, then the
    // earliest time with i left out.
    double* __restrict const px = columns.x.data();
    double* __restrict const py = columns.y.data();
    double* __restrict const pz = columns.z.data();
    double* __restrict const wx = columns.vx.data();
    double* __restrict const wy = columns.vy.data();
    double* __restrict const wz = columns.vz.data();
    double* __restrict const clock = columns.clock.data();
    double* __restrict const radius = columns.radius.data();
    for (int k = 0; k < count; ++k) {
      const Flight& fj = flight[candidates[k]];
      px[k] = fj.position.x();
      py[k] = fj.position.y();
      pz[k] = fj.position.z();
      wx[k] = fj.velocity.x();
      wy[k] = fj.velocity.y();
      wz[k] = fj.velocity.z();
      clock[k] = fj.clock;
      radius[k] = fj.radius;
    }
    contact_times(columns, count, frame);
    for (int k = 0; k < count; ++k) {
      times[k] = candidates[k] == i ? kNever : times[k];
      earliest = std::min(earliest, times[k]);
    }
  }
  // The first candidate at the earliest time, as a sequential "strictly earlier" scan picks.
  if (earliest < p.collision_time) {
    int k = 0;
    while (times[k] != earliest) ++k;
    p.collision_time = earliest;
    p.partner = candidates[k];
    p.partner_count = counter_[static_cast<std::size_t>(candidates[k])];
  }
}

void EventDrivenCollider::predict(int i, int layer) {
  const auto k = static_cast<std::size_t>(i);
  Pending& p = pending_[k];
  const Flight& fi = flight_[k];
  const double tau = now_ - fi.clock;
  const Vec3& a = acceleration_;
  const Vec3 x = fi.position + fi.velocity * tau + 0.5 * a * tau * tau;
  const Vec3 v = fi.velocity + a * tau;
  const std::array<int, 3> c = cell_of(p);
  const bool fixed = p.fixed;
  if (layer < 0) {
    ++predictions_;
    p.collision_time = kNever;
    p.partner = kNoPartner;
  }
  if (!fixed && any_wall_) {
    for (int axis = 0; axis < dimension_; ++axis) {
      const auto ax = static_cast<std::size_t>(axis);
      for (int side = 0; side < 2; ++side) {
        if (!wall_[ax][static_cast<std::size_t>(side)]) continue;
        if (c[ax] != (side == 0 ? 0 : cells_[ax] - 1)) continue;  // only from boundary cells
        const double sign = side == 0 ? 1.0 : -1.0;
        const double plane = side == 0 ? lo_[axis] : lo_[axis] + length_[axis];
        // The gap to the wall is a quadratic in t: its first decreasing zero, in closed form.
        const double t = first_descent(sign * (x[axis] - plane) - fi.radius, sign * v[axis],
                                       0.5 * sign * a[axis], false);
        if (now_ + t < p.collision_time) {
          p.collision_time = now_ + t;
          p.partner = -1 - (2 * axis + side);
        }
      }
    }
  }
  // After a crossing only the layer ahead of the crossed face is new; the rest was scanned before.
  scan(i, gather_adjacent(c, layer), x, v, needs_image(c), p);
  if (layer < 0) --pair_checks_;  // i itself was among the candidates
  if (fixed && p.partner >= 0 && pending_[static_cast<std::size_t>(p.partner)].fixed) {
    p.collision_time = kNever;  // two immovable particles never collide (fixed ones are at rest)
    p.partner = kNoPartner;
  }
  int face = 0;
  p.crossing_time = now_ + next_crossing(i, x, v, &face);
  p.crossing_face = static_cast<std::uint8_t>(face);
}

void EventDrivenCollider::initialize(ParticleStore& store, const Domain& domain, double start_time) {
  set_up(store, domain, start_time, nullptr);
}

void EventDrivenCollider::resume(ParticleStore& store, const Domain& domain, const EventSchedule& schedule) {
  set_up(store, domain, schedule.time, &schedule);
}

EventSchedule EventDrivenCollider::schedule() const {
  EventSchedule out;
  out.time = now_;
  const std::size_t n = pending_.size();
  for (const auto& column : kEventScheduleReals) (out.*column.values).resize(column.per_particle * n);
  for (const auto& column : kEventScheduleIntegers) (out.*column.values).resize(column.per_particle * n);
  for (std::size_t i = 0; i < n; ++i) {
    const Pending& p = pending_[i];
    out.collision_time[i] = p.collision_time;
    out.crossing_time[i] = p.crossing_time;
    out.partner[i] = p.partner;
    out.partner_count[i] = p.partner_count;
    out.crossing_face[i] = p.crossing_face;
    for (std::size_t ax = 0; ax < 3; ++ax) out.cell[3 * i + ax] = p.cell[ax];
    out.counter[i] = counter_[i];
    out.burst_start[i] = burst_[i].start;
    out.burst_count[i] = burst_[i].count;
    out.ring_next[i] = cell_link_[i].next;
  }
  out.head.assign(head_.begin(), head_.end());
  return out;
}

void EventDrivenCollider::take_schedule(const EventSchedule& schedule) {
  const std::size_t n = pending_.size();
  auto fits = [&](bool ok, const char* what) {
    if (!ok)
      throw std::invalid_argument(
          std::string("EventDrivenCollider: the saved event schedule does not fit the particles (") + what + ")");
  };
  for (const auto& column : kEventScheduleReals)
    fits((schedule.*column.values).size() == column.per_particle * n, column.name);
  for (const auto& column : kEventScheduleIntegers)
    fits((schedule.*column.values).size() == column.per_particle * n, column.name);
  fits(schedule.head.size() == head_.size(), "head");
  const auto n_int = static_cast<std::int64_t>(n);
  for (std::size_t i = 0; i < n; ++i) {
    Pending& p = pending_[i];
    p.collision_time = schedule.collision_time[i];
    p.crossing_time = schedule.crossing_time[i];
    // Partners are particles (>= 0), walls (-1 - face, six faces) or none.
    const std::int64_t partner = schedule.partner[i];
    fits(partner == kNoPartner || (partner >= -6 && partner < n_int), "a partner");
    p.partner = static_cast<int>(partner);
    p.partner_count = static_cast<std::uint32_t>(schedule.partner_count[i]);
    fits(schedule.crossing_face[i] >= 0 && schedule.crossing_face[i] < 6, "a crossing face");
    p.crossing_face = static_cast<std::uint8_t>(schedule.crossing_face[i]);
    for (std::size_t ax = 0; ax < 3; ++ax) {
      const std::int64_t c = schedule.cell[3 * i + ax];
      fits(c >= 0 && c < cells_[ax], "a cell");
      p.cell[ax] = static_cast<std::uint16_t>(c);
    }
    counter_[i] = static_cast<std::uint32_t>(schedule.counter[i]);
    burst_[i] = Burst{schedule.burst_start[i], static_cast<std::uint32_t>(schedule.burst_count[i])};
    fits(schedule.ring_next[i] >= 0 && schedule.ring_next[i] < n_int, "a ring");
    cell_link_[i].next = static_cast<int>(schedule.ring_next[i]);
  }
  // Each ring runs through one cell's particles, and each head word names one of its own.
  for (std::size_t i = 0; i < n; ++i) {
    const auto next = static_cast<std::size_t>(cell_link_[i].next);
    fits(pending_[next].cell == pending_[i].cell, "a ring across cells");
    cell_link_[next].prev = static_cast<int>(i);
  }
  for (std::size_t c = 0; c < head_.size(); ++c) {
    const std::int64_t head = schedule.head[c];
    // Empty, one particle, or several_head() of the first of a ring.
    const std::int64_t first = head >= 0 ? head : kEmptyHead - 1 - head;
    fits(head == kEmptyHead || (first >= 0 && first < n_int &&
                                cell_index(cell_of(pending_[static_cast<std::size_t>(first)])) == static_cast<int>(c)),
         "a cell's head");
    head_[c] = static_cast<int>(head);
  }
}

void EventDrivenCollider::set_up(ParticleStore& store, const Domain& domain, double start_time,
                                 const EventSchedule* schedule) {
  const std::size_t n = store.size();
  now_ = start_time;
  dimension_ = domain.dimension;
  lo_ = domain.lo;
  length_ = domain.length();
  double max_radius = 0.0;
  bool any_fixed = false, first = true;
  for (std::size_t i = 0; i < n; ++i) {
    max_radius = std::max(max_radius, store.radius[i]);
    if (store.is_fixed(i)) { any_fixed = true; continue; }
    const Vec3 a = store.force[i] / store.mass[i];
    if (first) { acceleration_ = a; first = false; }
    if ((a - acceleration_).norm() > 1e-14 * (1.0 + acceleration_.norm())) {
      throw std::invalid_argument("EventDrivenCollider: particles must share one acceleration");
    }
  }
  if (first) acceleration_.setZero();
  accelerated_ = !acceleration_.isZero(0.0);
  if (any_fixed && !acceleration_.isZero(0.0)) {
    throw std::invalid_argument("EventDrivenCollider: fixed particles need zero acceleration");
  }
  for (int k = 0; k < 3; ++k) {
    const auto ax = static_cast<std::size_t>(k);
    wall_[ax] = {false, false};
    half_image_[ax] = kNever;
    if (k >= dimension_) {
      cells_[ax] = 1;
      cell_size_[ax] = 1.0;
      periodic_[ax] = false;
      continue;
    }
    for (std::size_t side = 0; side < 2; ++side) {
      if (domain.face[ax][side] == FaceKind::kOpen) {
        throw std::invalid_argument("EventDrivenCollider: open faces are not supported");
      }
      wall_[ax][side] = domain.face[ax][side] == FaceKind::kWall;
    }
    periodic_[ax] = domain.periodic(k);
    if (periodic_[ax]) half_image_[ax] = 0.5 * length_[k];
    // Wider cells than needed are only slower; Pending::cell holds 16 bits an axis.
    cells_[ax] = static_cast<int>(
        std::clamp(std::floor(length_[k] / (2.0 * max_radius)), 1.0, double{kMaxCellsPerAxis}));
    if (periodic_[ax] && cells_[ax] < 3) {
      throw std::invalid_argument("EventDrivenCollider: periodic axis " + std::to_string(k) +
                                  " must span at least three diameters");
    }
    cell_size_[ax] = length_[k] / cells_[ax];
  }
  for (std::size_t ax = 0; ax < 3; ++ax) {
    scan_frame_.acceleration[ax] = acceleration_[static_cast<int>(ax)];
    scan_frame_.length[ax] = length_[static_cast<int>(ax)];
    scan_frame_.half_image[ax] = half_image_[ax];
  }
  // Cells are numbered by int (with the padded grid's border): spheres so small against the
  // box that this overflows would need more memory for empty cells than any machine has.
  const std::int64_t cell_count = std::int64_t{cells_[0] + 2} * (cells_[1] + 2) * (cells_[2] + 2);
  if (cell_count > std::numeric_limits<int>::max() / 2) {
    throw std::invalid_argument("EventDrivenCollider: " + std::to_string(cell_count) +
                                " cells of one largest diameter: the box is too large for its spheres");
  }
  const auto n_cells = static_cast<std::size_t>(cells_[0] * cells_[1] * cells_[2]);
  // Adjacent cells (itself included) at fixed positions: dz, dy, dx from -1 to 1, dz only 0 in
  // 2D. They are read from a grid padded by one layer of cells, whose border names the cell it
  // wraps to across periodic faces or the always empty cell n_cells beyond walls, so every cell
  // finds its neighbours at the same index offsets. Positions of each face's layer: those one
  // step across it.
  const int reach_z = dimension_ == 3 ? 1 : 0;
  stencil_size_ = dimension_ == 3 ? 27 : 9;
  layer_size_ = stencil_size_ / 3;
  empty_cell_ = static_cast<int>(n_cells);
  for (std::size_t ax = 0; ax < 3; ++ax) {
    pad_[ax] = static_cast<int>(ax) < dimension_ ? 1 : 0;
    padded_cells_[ax] = cells_[ax] + 2 * pad_[ax];
  }
  std::array<std::size_t, 7> filled{};
  padded_offset_ = {};
  interior_offset_ = {};
  for (int dz = -reach_z; dz <= reach_z; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const std::array<int, 3> offset{dx, dy, dz};
        for (std::size_t list = 0; list < 7; ++list) {
          if (list != kWholeStencil && offset[list / 2] != (list % 2 == 0 ? -1 : 1)) continue;
          padded_offset_[list][filled[list]] = (dz * padded_cells_[1] + dy) * padded_cells_[0] + dx;
          interior_offset_[list][filled[list]++] = (dz * cells_[1] + dy) * cells_[0] + dx;
        }
      }
  // next_crossing_avx2()'s constants, and whether interior cells need the minimum image.
  imaging_interior_ = false;
  any_wall_ = false;
  for (const auto& sides : wall_) any_wall_ = any_wall_ || sides[0] || sides[1];
  for (std::size_t ax = 0; ax < 4; ++ax) {
    const bool active = static_cast<int>(ax) < dimension_;
    crossing_lo_[ax] = ax < 3 ? lo_[static_cast<int>(ax)] : 0.0;
    crossing_size_[ax] = ax < 3 ? cell_size_[ax] : 1.0;
    crossing_active_[ax] = active ? -1 : 0;
    crossing_periodic_[ax] = active && periodic_[ax] ? -1 : 0;
    if (active && periodic_[ax] && cells_[ax] < 5) imaging_interior_ = true;
  }
  padded_cell_.resize(
      static_cast<std::size_t>(padded_cells_[0] * padded_cells_[1] * padded_cells_[2]));
  // A padded grid larger than a core's share of cache costs a miss per lookup; interior cells
  // then find their neighbours by arithmetic (a data-dependent branch, not worth it otherwise).
  arithmetic_interior_ = padded_cell_.size() > kCachedPaddedCells;
  for (int pz = 0; pz < padded_cells_[2]; ++pz)
    for (int py = 0; py < padded_cells_[1]; ++py)
      for (int px = 0; px < padded_cells_[0]; ++px) {
        std::array<int, 3> cell{px - pad_[0], py - pad_[1], pz - pad_[2]};
        bool inside = true;
        for (std::size_t ax = 0; ax < 3; ++ax) {
          if (cell[ax] >= 0 && cell[ax] < cells_[ax]) continue;
          if (periodic_[ax]) cell[ax] = (cell[ax] + cells_[ax]) % cells_[ax];
          else inside = false;
        }
        const int padded = (pz * padded_cells_[1] + py) * padded_cells_[0] + px;
        padded_cell_[static_cast<std::size_t>(padded)] = inside ? cell_index(cell) : empty_cell_;
      }
  flight_.resize(n);
  counter_.assign(n, 0u);
  pending_.assign(n, Pending{kNever, kNever, kNoPartner, 0u, {0, 0, 0}, 0, false});
  inverse_mass_.resize(n);
  burst_.assign(n, Burst{});
  spin_.resize(n);
  spinning_ = false;
  frictionless_ = settings_.law.friction == 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    spin_[i] = Spin{store.angular_velocity[i], store.torque[i] * store.inverse_inertia(i), store.inverse_inertia(i)};
    pending_[i].fixed = store.is_fixed(i);
    inverse_mass_[i] = store.inverse_mass(i);
    spinning_ = spinning_ || !spin_[i].angular_acceleration.isZero(0.0);
    // A resumed store holds the positions as advance_to() left them (the cells from the
    // schedule): wrapping one that rounding put on the far side of a face would change it.
    if (!schedule) domain.wrap(store.position[i]);
    flight_[i] = Flight{store.position[i], now_, store.velocity[i], store.radius[i]};
    for (std::size_t ax = 0; ax < 3; ++ax) {
      const auto k = static_cast<int>(ax);
      const double s = (flight_[i].position[k] - lo_[k]) / cell_size_[ax];
      pending_[i].cell[ax] = static_cast<std::uint16_t>(
          k >= dimension_ ? 0 : std::clamp(static_cast<int>(std::floor(s)), 0, cells_[ax] - 1));
    }
  }
  head_.assign(n_cells + 1, kEmptyHead);  // and the empty cell
  cell_link_.resize(n);
  // Room for 27 cells of two particles; append_rings() grows it for fuller neighbourhoods.
  candidates_.assign(2 * 27 + kCandidateSlack, -1);
  columns_.resize(candidates_.size());
  candidate_lines_.resize(candidates_.size());
  if (schedule) {
    take_schedule(*schedule);
  } else {
    for (std::size_t i = 0; i < n; ++i) bin(static_cast<int>(i), cell_index(cell_of(pending_[i])));
    for (std::size_t i = 0; i < n; ++i) predict(static_cast<int>(i), -1);
  }
  std::vector<double> keys(n);
  for (std::size_t i = 0; i < n; ++i) keys[i] = key(static_cast<int>(i));
  calendar_.reset(keys);
}

EventStats EventDrivenCollider::advance_to(ParticleStore& store, const Domain& domain, double target) {
  EventStats stats;
  predictions_ = pair_checks_ = 0;
  const std::size_t n = store.size();
  if (n != flight_.size()) throw std::logic_error("EventDrivenCollider: store changed size");
  while (n > 0) {
    const int i = calendar_.top();
    if (i < 0 || calendar_.time(i) > target) break;
    // The next event's particle is usually known already: its lines start loading now, behind
    // this event's work (for large N each is a cache miss).
    if (const int next = calendar_.upcoming(); next >= 0) {
      __builtin_prefetch(&pending_[static_cast<std::size_t>(next)]);
      __builtin_prefetch(&flight_[static_cast<std::size_t>(next)]);
      calendar_.prefetch(next);
    }
    const auto a = static_cast<std::size_t>(i);
    Pending& p = pending_[a];
    now_ = key(i);
    if (p.crossing_time <= p.collision_time) {
      const int face = p.crossing_face;
      const int axis = face / 2;
      const auto ax = static_cast<std::size_t>(axis);
      const int step = face % 2 == 0 ? -1 : 1;
      int c = p.cell[ax] + step;  // as int: -1 wraps below
      if (c < 0) c += cells_[ax];
      if (c >= cells_[ax]) c -= cells_[ax];
      // The old and the new cell's head words and i's ring link, started together.
      const int left_cell = cell_index(cell_of(p));
      std::array<int, 3> entered = cell_of(p);
      entered[ax] = c;
      __builtin_prefetch(&head_[static_cast<std::size_t>(cell_index(entered))]);
      __builtin_prefetch(&head_[static_cast<std::size_t>(left_cell)]);
      __builtin_prefetch(&cell_link_[a]);
      sync(i, now_);
      unbin(i, left_cell);
      p.cell[ax] = static_cast<std::uint16_t>(c);
      // Snap onto the shared face (wrapped) so the new cell's exit test starts exactly at 0.
      flight_[a].position[axis] = lo_[axis] + (step > 0 ? c : c + 1) * cell_size_[ax];
      bin(i, cell_index(entered));
      ++stats.cell_crossings;
      const bool stale = p.partner >= 0 && counter_[static_cast<std::size_t>(p.partner)] != p.partner_count;
      stats.stale_events += stale ? 1 : 0;
      predict_and_schedule(i, stale ? -1 : face);
      continue;
    }
    const int partner = p.partner;
    const bool pair = partner >= 0;
    const auto b = static_cast<std::size_t>(pair ? partner : 0);
    if (pair && counter_[b] != p.partner_count) {
      ++stats.stale_events;
      predict_and_schedule(i, -1);
      continue;
    }
    // What the collision reads besides i's Flight and Pending lines, all requested at once.
    // Without friction an impulse is along the normal: it changes no angular velocity, and the
    // angular velocities do not enter it (Spin lines are left alone, Body's stay zero).
    const bool spin = !frictionless_;
    if (spin) __builtin_prefetch(&spin_[a]);
    __builtin_prefetch(&inverse_mass_[a]);
    if (pair) {
      __builtin_prefetch(&flight_[b]);
      __builtin_prefetch(&pending_[b]);
      __builtin_prefetch(&inverse_mass_[b]);
      if (spin) __builtin_prefetch(&spin_[b]);
      calendar_.prefetch(partner);
    }
    // Each particle's previous event (collision or crossing), for the collapse detector below.
    std::array<double, 2> previous_event{flight_[a].clock, 0.0};
    sync(i, now_);
    auto body = [&](std::size_t k) {
      Body bk;
      bk.velocity = flight_[k].velocity;
      bk.inverse_mass = inverse_mass_[k];
      bk.radius = flight_[k].radius;
      if (spin) {
        bk.angular_velocity = spin_[k].angular_velocity;
        bk.inverse_inertia = spin_[k].inverse_inertia;
      }
      return bk;
    };
    Body body_a = body(a);
    Body body_b;
    Vec3 normal = Vec3::Zero();
    if (pair) {
      previous_event[1] = flight_[b].clock;
      sync(partner, now_);
      body_b = body(b);
      normal = domain.separation(flight_[a].position, flight_[b].position).normalized();
    } else {
      const int face = -1 - partner;
      normal[face / 2] = face % 2 == 0 ? -1.0 : 1.0;
    }
    // Inelastic collapse (infinitely many collisions before a finite time, e.g. a ball with
    // e < 1 settling on a floor) shows as bursts of collisions a few ulps apart: report it.
    // A burst's record is read only when the particle's previous event lies within the span (a
    // burst's start is no later than that event): elsewhere the burst is over, and the next
    // collision within the span starts a new record, one collision late.
    const double burst_span = 1e4 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(now_));
    for (std::size_t member = 0; member < (pair ? 2u : 1u); ++member) {
      if (now_ - previous_event[member] > burst_span) continue;
      Burst& burst = burst_[member == 0 ? a : b];
      if (now_ - burst.start <= burst_span) {
        if (++burst.count > kBurstLimit) {
          throw NumericalFailure("hard-sphere collisions piled up at one instant (inelastic "
                                 "collapse or a resting contact)", "EventDrivenCollider", now_, -1);
        }
      } else {
        burst.start = now_;
        burst.count = 0;
      }
    }
    const CollisionImpulse impulse = collide(body_a, body_b, normal, settings_.law);
    if (!impulse.approaching && !pair && normal.dot(acceleration_) > 0.0) {
      // Touching a wall without approaching it while pushed into it: a resting contact.
      throw NumericalFailure("hard sphere at rest on a wall under a force pressing it in (resting "
                             "contacts need a soft-sphere model)", "EventDrivenCollider", now_, -1);
    }
    ++counter_[a];  // even a grazing no-op: the rescan below must not return the same contact
    flight_[a].velocity = body_a.velocity;
    if (spin) spin_[a].angular_velocity = body_a.angular_velocity;
    if (pair) {
      ++counter_[b];
      flight_[b].velocity = body_b.velocity;
      if (spin) spin_[b].angular_velocity = body_b.angular_velocity;
    }
    if (impulse.approaching) {
      ++(pair ? stats.collisions : stats.wall_hits);
      if (log_) log_->push_back(CollisionRecord{now_, store.id[a], pair ? store.id[b] : partner});
    }
    // The partner's calendar entry has arrived by now; its list neighbours load during i's scan.
    if (pair) calendar_.prefetch_neighbours(partner);
    predict_and_schedule(i, -1);
    if (pair) predict_and_schedule(partner, -1);
  }
  stats.predictions = predictions_;
  stats.pair_checks = pair_checks_;
  now_ = target;
  for (std::size_t i = 0; i < n; ++i) {
    sync(static_cast<int>(i), target);
    store.position[i] = flight_[i].position;
    store.velocity[i] = flight_[i].velocity;
    store.angular_velocity[i] = spin_[i].angular_velocity;
  }
  return stats;
}

}  // namespace grainwave::particles::hardsphere

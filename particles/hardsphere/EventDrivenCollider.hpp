#pragma once
// Event-driven hard spheres for equal accelerations (none, or gravity alone): 002 §2.3.3 notes
// that then Eq. 2.26 reduces to a quadratic and the system can be advanced collision by
// collision (Alder & Wainwright; Rapaport, "The Art of Molecular Dynamics Simulation", ch. 14;
// Lubachevsky 1991 for lazy per-particle clocks and one pending event per particle).
//
// Relative motion of any two particles is uniform, so a pair's contact time is the closed-form
// smaller root of |d + u t| = sigma (CollisionTime.hpp). Each particle keeps its own clock: its
// state is stored at the time of its last event and extrapolated with Eqs 2.11–2.13 on demand.
// Cells are at least one largest diameter wide. Each particle holds only its earliest predicted
// collision (partner or wall, with the partner's collision counter at prediction time) and its
// next cell crossing; a calendar queue over particles orders them (EventCalendar.hpp: earliest
// first, ties to the lower index). Why this is complete:
// every pair that will touch is adjacent from the later of the partners' last events on, and each
// of those events scans the cells that became adjacent (all 27 after a collision, the new layer
// of 9 after a crossing); a candidate whose partner has collided since is stale and triggers a
// full rescan of that particle when its time comes. Impulses: CollisionImpulse.hpp.
//
// Speed (the pair scan is most of the work; bench/bench_hardsphere.cpp measures it): each cell
// has a head word that names its particle when it holds exactly one (most occupied cells), and
// otherwise is empty or names the first of its particles' ring (a circular list through a dense
// per-particle array of links, 8 bytes a particle). A scan finds the
// adjacent cells (from a grid padded with one layer of wrapped or empty cells, or, for interior
// cells of large grids, by index arithmetic), gathers their particles from the head words
// (4 bytes a cell, which mostly stay in cache), then appends the rings of the few cells holding
// several (the first's link names the second and the last: a pair, most of them, is one load),
// and takes all contact times in one pass without data-dependent
// branches (minimum image and "never" by selects). Where the machine has AVX2 (x86-64, picked
// at run time) the head words are gathered eight at a time and the occupied ones packed by a
// permutation from a table; the pass reads four candidates' Flight lines and transposes them in
// registers into columns, compiled without the acceleration's terms when there is none and
// without the minimum image when the scanning cell cannot see an image (both add zeros there);
// and the unaccelerated crossing time takes the three axes as lanes. Elsewhere the flight
// states are copied into columns and the loop left to the compiler's vectoriser. Every path does
// the arithmetic of ballistic_contact_time_or_never in the same order (no FMA), and the earliest
// candidate is the first at the minimum in one fixed candidate order: none of this changes a
// result (the vector and portable paths are compared bitwise by a test). For large N every event's reads are cache misses, so what an event touches of a
// particle is packed into one line each (Flight, Pending, Spin), the large arrays sit on huge
// pages (core/HugePageAllocator.hpp), and the lines an event will need are requested together
// as soon as they are known (a collision's partner's lines and calendar entry, a crossing's two
// cells): at N = 97 556 these took bench_hardsphere from 0.40 M to about 0.49 M
// collisions/s, and the head words (which spare the scan 6 MB of blocks there) a further 15 %
// on a later machine (medians of five alternating runs: 0.49 M -> 0.57 M).
// Stop 40 (gather by vector, the kernel variants, the vector crossing time, the scan's fixed
// frame and address computation, the prefetches above): callgrind on a 1372-particle gas to
// t = 3, 15 151 collisions, bitwise the same results: 5995 -> 4356 instructions a collision;
// bench_hardsphere medians of five, six alternating rounds against the build before:
// N = 1372 1.07-1.12 M -> 1.32-1.37 M collisions/s, N = 97 556 0.67-0.77 M -> 0.81-0.87 M.
// Tried then without gain: keeping a runner-up candidate, taken without a rescan when the
// earliest turns stale (only 26% of stale events could use it, its partner having collided too
// in the others; 1.20-1.23 M against 1.28-1.31 M at N = 1372); prefetching both of the
// calendar heap's runners-up instead of one (760 against 780 k/s at N = 97 556).
// Where the time went before stop 40 (callgrind at N = 97 556, a 2 MB last-level cache modelled: about
// 6000 instructions, 51 cache misses and 35 mispredicted branches per collision, the misses
// mostly the candidates' Flight lines, 22, and the head words and blocks, 9): the event loop is
// bound by latency, not arithmetic. Tried and measured without gain (five alternating runs
// each): an AVX-512 kernel, eight candidates at a time, with the gather by vpgatherdd and
// compression; square roots and divisions only for the pairs that touch (packed first); two
// particles per head word (fewer block reads, but a head array twice the size: 4 more misses
// per collision); particles renumbered in cell order (no change: each candidate is one line
// wherever it is); at each event's start, prefetching the next event's neighbourhood (the Flight
// lines of its adjacent cells' particles, its partner's lines): no change either (0.63 M/s with
// and without, N = 97 556, three alternating runs), so the misses are not what a prefetch can
// hide; the instructions per event are the next thing to cut (callgrind: the contact-time kernel
// 31%, gather 19%, predict 11%, next_crossing 10% of them).
// Also tried and measured without gain (medians of five, three alternating rounds): a calendar
// that leaves out-of-date entries in place (a version per particle, entries in chunked bucket
// lists, a lazy heap): 0.58-0.60 M against 0.68-0.70 M collisions/s at N = 97 556, slower at
// 1372 too; a quarter or half as many buckets, four or eight times as wide (a bucket-head array
// that stays in cache): within the noise; skipping a group of four's square root and division
// when a root-free bound (t >= c / (-2b)) puts every lane after the earliest time known:
// 1.06-1.08 M against 1.08-1.11 M at N = 1372, the branch costing what it saved. perf at
// N = 97 556 puts 18% of the time in the calendar (the bucket head and the particle's own
// link, two misses per change), 25% in the contact-time kernel, 11% in gather and 7% in unbin
// (the cell block): the misses are spread over every structure an event touches. After stop
// 40, perf there: contact-time kernels 22%, the event handling in advance_to 18% (mostly the
// event's own Pending line where the calendar's hint named another particle, 44% of events, and
// the Spin lines), the calendar 18%, gather 15%, scan 7%, unbin 6%.
// Stop 41, how the rate falls with N (best of five windows of about one collision per particle,
// k/s): N = 1372 1320, 4000 1320, 8788 1185, 16 384 1147, 32 000 936, 55 296 862, 97 556 773,
// 186 624 601: it falls as the working set (about 300 bytes a particle) outgrows the 2 MB L2,
// not at one size. callgrind at N = 97 556 (2 MB last level modelled, prefetches not): 4496
// instructions and 59 read misses a collision (candidates' Flight lines 22, head words and
// blocks 11, the event's and partner's lines in advance_to 12 and sync 7, calendar 4) and 10
// write misses. Without gain: the whole library built with link-time optimisation (calendar
// calls inlined): 737-752 against 718-771 k/s; the old cell's block requested from the cell
// rather than from slot_of_ (a load that can miss): best of seven 791-815 against 781-832 k/s.
// Stop 42, on another VM (AMD EPYC with AVX-512; 2 MB L2 reported, but a pointer chase through
// a shuffled array takes 10-17 ns up to 4 MB and 116-160 ns from 8 MB on): N = 1372 1.32-1.43 M,
// N = 97 556 0.47-0.56 M collisions/s (0.80 M on the stop-41 VM): the large gas's ~30 MB are
// all beyond that cache here. Without gain there (three-repetition medians, alternating): the
// neighbourhood of the calendar's runner-up gathered and its Flight lines prefetched before
// each event's own scans (1372: 1.19-1.21 M against 1.34-1.40 M; 97 556: 503 against 468-532
// k/s), the partner's neighbourhood prefetched before scanning the first particle (1.14-1.27 M
// against 1.32-1.40 M, 420-462 against 495-497 k/s): the gathers' own loads stall. Kept:
// frictionless collisions leave the Spin lines alone (468-532 -> 467-564 k/s, within the noise).
// Stop 43 (an EPYC VM with 1 MB L2 and 32 MB L3 reported; a pointer chase on huge pages: 20 ns
// at 8 MB, 68 ns at 16, 105 ns at 24; the L3 is shared with other tenants, and the rate at
// N = 97 556 swings between about 0.45 and 1.1 M/s with their load): what the large gas touches
// went from about 24 to 16.5 MB, outputs bitwise as before. Each cell's fixed block of ints
// (occupancy, then its particles: 6.2 MB at N = 97 556, grown for every cell when one
// overflowed) gave way to the rings (0.8 MB), in the blocks' order; perf then put a third of
// the gather on the rings' dependent loads, and taking the last from the first's link left one
// load for a pair. Pending went from 64 to 32 bytes: the cell in 16-bit coordinates, the inverse
// mass in a dense array, the collapse detector's burst record in one read only when a collision
// follows the particle's previous event within the burst span. bench_hardsphere, 30
// repetitions each in alternating rounds (k/s): N = 97 556 median 529 -> 577, 90th percentile
// 629 -> 670; N = 1372 median 1412-1440 -> 1389-1411 (within the rounds' spread). Without gain
// (medians within the noise, so left out): the calendar's next buckets' entries prefetched as a
// bucket is entered (perf: top() 9.4% -> 6.7% of the time, the rate unchanged), and a
// collision's two calendar updates moved after both rescans with their bucket heads prefetched
// (update() stayed at 10%, most of it that head's load); the head words of i's and the
// partner's rescans prefetched, row by row, as soon as their cells are known (the gather's share
// in perf unchanged at 13-14%, medians 546 against 577 k/s); the scalar gather instead of the
// vector one on this AMD machine, whose vector gathers perf blames for 17% of the time at
// N = 1372 (1375 against 1416 k/s there: the vector gather stays).
// Stop 50 (this VM's pointer chase on huge pages: 18 ns at 4 MB, 105 ns at 8 MB, 138 ns at
// 16 MB, so the large gas's ~15 MB are served from DRAM; perf per collision, N = 97 556 against
// 1372: 2.04 against 0.91 us, the 1.13 us between them spread over the contact times +0.33, the
// event's own lines in advance_to +0.17, the calendar's top and update +0.29, gather and rings
// +0.25): a pipeline of prefetches over the calendar's next events, without gain. Each
// particle of the current bucket's heap (buckets 4 or 8 times as wide, to hold the next 6-12
// events) advanced one stage per event: its Pending and Flight lines, then its cells' head
// words and its partner's lines, then its candidates' Flight lines. 76-80% of events found
// their candidates requested an event or more ahead, and the contact times' share in perf fell
// from 26 to 18%, but the look-ahead took 17% itself (its own loads of head words): medians of
// three repetitions, five alternating rounds, 391-498 k/s without, 378-432 and 360-481 with;
// requesting all 27 head words instead of one per row of three was slower still (275-314 k/s).
// glibc's huge pages for every allocation (GLIBC_TUNABLES=glibc.malloc.hugetlb=1, the arrays
// under 2 MB included): 483-585 against 530-558 k/s, no change.
// Stop 51, the runs rather than the collider: ParticleSystem had called initialize() at every
// step (so that a restart would be exact) and searched the state for overlaps twice, laying the
// search's cell grid anew each time. For hs_gas.toml (N = 1372, steps of 0.1, 0.8 collisions a
// particle each) that was 725 M instructions to t = 3 against 228 M now (callgrind): the events
// go on across steps, checkpoints carry schedule() (resume()), and the overlap search is one a
// step on a grid laid once. collisions_per_s of the case 0.41-0.42 M -> 0.81-0.90 M (three
// alternating runs), at N = 97 556 0.245 M -> 0.35-0.37 M; the bench above never had these costs.
// A dependent read of the other line of a 128-byte pair after a miss took 13-16 ns against
// 155-160 ns for the miss (this VM), so Flight and Pending in one pair would save little: the
// event's two lines are requested together already.
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/HugePageAllocator.hpp"
#include "particles/Domain.hpp"
#include "particles/ParticleStore.hpp"
#include "particles/hardsphere/CollisionImpulse.hpp"
#include "particles/hardsphere/CollisionRecord.hpp"
#include "particles/hardsphere/EventCalendar.hpp"

// scan() has an AVX2 kernel, picked at run time, where the compiler can target it.
#if defined(__x86_64__) && defined(__GNUC__)
#define GRAINWAVE_AVX2_SCAN 1
#else
#define GRAINWAVE_AVX2_SCAN 0
#endif

namespace grainwave::particles::hardsphere {

struct EventDrivenSettings {
  CollisionLaw law{};
  /// Use the AVX2 pair scan where the machine has it; false takes the portable scan everywhere
  /// (the results are bitwise the same: the test comparing the two needs this switch).
  bool vector_scan = true;
};

struct EventStats {
  long collisions = 0;
  long wall_hits = 0;
  long cell_crossings = 0;
  long stale_events = 0;  ///< candidates invalidated by the partner's other collision
  long predictions = 0;   ///< full 27-cell rescans
  long pair_checks = 0;   ///< partner candidates examined
};

/// What the collider holds between advance_to() calls besides the store it writes back: each
/// particle's pending events, cell, collision counter and place in its cell's ring, and the
/// collapse detector's records. A checkpoint that keeps it lets a restarted run go on exactly as
/// the uninterrupted one; without it initialize() predicts every event afresh from the store
/// (the same physics, other round-off from then on).
struct EventSchedule {
  double time = 0;  ///< when the store was written back (the particles' common clock)
  // Per particle, in store order.
  std::vector<double> collision_time, crossing_time, burst_start;
  std::vector<std::int64_t> partner, partner_count, counter, burst_count, crossing_face, ring_next;
  std::vector<std::int64_t> cell;  ///< three per particle
  std::vector<std::int64_t> head;  ///< per cell, and the empty cell
};

/// EventSchedule's per-particle columns by name, with their values per particle: the one list
/// that saving, reading and checking a schedule go through.
template <class T>
struct EventScheduleColumn {
  const char* name;
  std::vector<T> EventSchedule::*values;
  std::size_t per_particle;
};
inline constexpr std::array<EventScheduleColumn<double>, 3> kEventScheduleReals{{
    {"collision_time", &EventSchedule::collision_time, 1},
    {"crossing_time", &EventSchedule::crossing_time, 1},
    {"burst_start", &EventSchedule::burst_start, 1},
}};
inline constexpr std::array<EventScheduleColumn<std::int64_t>, 7> kEventScheduleIntegers{{
    {"partner", &EventSchedule::partner, 1},
    {"partner_count", &EventSchedule::partner_count, 1},
    {"counter", &EventSchedule::counter, 1},
    {"burst_count", &EventSchedule::burst_count, 1},
    {"crossing_face", &EventSchedule::crossing_face, 1},
    {"ring_next", &EventSchedule::ring_next, 1},
    {"cell", &EventSchedule::cell, 3},
}};

class EventDrivenCollider {
 public:
  explicit EventDrivenCollider(EventDrivenSettings settings = {});

  /// Takes over the store at time `start_time`: checks that every particle has the same
  /// acceleration F/m (throws std::invalid_argument otherwise, or for open faces), bins the
  /// particles and predicts their first events.
  void initialize(ParticleStore& store, const Domain& domain, double start_time = 0.0);
  /// initialize() from a store written back by advance_to() and the schedule() taken then (a
  /// restart): nothing is predicted, and the events come in the order they would have come
  /// without the break. Throws std::invalid_argument when the schedule does not fit the store
  /// and the domain.
  void resume(ParticleStore& store, const Domain& domain, const EventSchedule& schedule);
  /// The state to resume() from, valid right after advance_to() (before anything changes the
  /// store).
  EventSchedule schedule() const;

  /// Processes every event up to `target` and leaves all particles synchronised at `target`
  /// (positions wrapped into the box) and written back to the store. Throws
  /// grainwave::NumericalFailure when a particle collides hundreds of times within a few ulps of
  /// time (inelastic collapse, resting contacts: hard spheres cannot represent them). The store must be the one
  /// passed to initialize(); after changing it from outside (particles, velocities, forces),
  /// call initialize() again: the collider keeps its own copies (positions, velocities,
  /// angular velocities, masses, inertia) and writes them back at the end of each call.
  EventStats advance_to(ParticleStore& store, const Domain& domain, double target);

  double time() const { return now_; }
  /// When set, every impulse is appended with its absolute time. Pass nullptr to stop.
  void record_collisions(std::vector<CollisionRecord>* log) { log_ = log; }

 private:
  static constexpr int kNoPartner = -1000;  ///< partners >= 0 are particles, -1 - face are walls
  static constexpr std::uint32_t kBurstLimit = 256;  ///< collisions of one particle a few ulps apart
  static constexpr int kScanLanes = 4;  ///< scan() pads its candidates to a multiple of this
  static constexpr std::size_t kCachedPaddedCells = 1 << 16;  ///< 256 KiB of cell indices
  static constexpr int kEmptyHead = -1;  ///< head_ of an empty cell
  /// head_ of a cell holding several particles, `first` the first of its ring.
  static constexpr int several_head(int first) { return kEmptyHead - 1 - first; }
  static constexpr int first_of(int several) { return kEmptyHead - 1 - several; }
  /// Room candidates_ keeps past the candidates gathered: gather_avx2() stores eight at a time,
  /// scan() pads to a multiple of kScanLanes.
  static constexpr std::size_t kCandidateSlack = 8;
  /// A particle's neighbours in its cell's ring (a circular list, in the order of arrival).
  struct CellLink {
    int next, prev;
  };

  /// Compact per-particle flight state (one cache line): what the pair scan reads, as two rows
  /// of four doubles (contact_times_avx2() loads them whole).
  struct alignas(64) Flight {
    Vec3 position;
    double clock;  ///< time at which position and velocity are valid
    Vec3 velocity;
    double radius;
  };
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  /// The rest of what every event reads and writes of its particle, in half a cache line: its
  /// pending events (earliest predicted collision, next cell crossing) and its cell. (The
  /// collision counters stay a dense array of their own: every scan reads its candidates'
  /// counters, which then fit in cache, as these lines would not.)
  struct alignas(32) Pending {
    double collision_time;
    double crossing_time;
    int partner;
    std::uint32_t partner_count;
    std::array<std::uint16_t, 3> cell;  ///< initialize() keeps cells_ within kMaxCellsPerAxis
    std::uint8_t crossing_face;         ///< 2 axis + (0 low, 1 high)
    bool fixed;                         ///< immovable (ParticleStore::is_fixed)
  };
  static_assert(sizeof(Pending) == 32);
  static constexpr int kMaxCellsPerAxis = 65535;
  static std::array<int, 3> cell_of(const Pending& p) { return {p.cell[0], p.cell[1], p.cell[2]}; }
  /// The collapse detector's record of a particle's current burst of collisions a few ulps
  /// apart: read only when a collision comes within that span of the particle's previous event.
  struct Burst {
    double start = -std::numeric_limits<double>::infinity();
    std::uint32_t count = 0;
  };
  /// What a collision with friction reads and writes of its particle besides Flight and
  /// Pending, in one cache line: the store's angular velocity (authoritative while events are
  /// pending, like Flight), the angular acceleration from its torque, and the inverse moment of
  /// inertia.
  struct alignas(64) Spin {
    Vec3 angular_velocity;
    Vec3 angular_acceleration;
    double inverse_inertia;
  };

  /// initialize()'s work, from `schedule` when given (resume()).
  void set_up(ParticleStore& store, const Domain& domain, double start_time, const EventSchedule* schedule);
  /// Takes the pending events, counters, bursts and rings from `schedule` (set_up's part).
  void take_schedule(const EventSchedule& schedule);
  void sync(int i, double t);
  /// Rescans all adjacent cells and walls (layer < 0), or after a crossing only the cells that
  /// became adjacent (layer = crossed face), keeping the earlier of old and new candidates.
  void predict(int i, int layer);
  /// Copies the particles of the cells adjacent to cell c (all of them for layer < 0, else only
  /// those one step across face `layer`) into candidates_ and returns how many there are: first
  /// those of the cells holding one particle, in stencil order, then those of the cells holding
  /// several, in stencil order and each cell's block order (a fixed order: ties in contact time
  /// go to the first candidate).
  int gather_adjacent(const std::array<int, 3>& c, int layer);
  /// gather_adjacent()'s work on a list of `count` cells.
  int gather(const int* cells, int count);
  /// Appends the rings of the cells k of `cells` whose bit k of `several` is set (cells holding
  /// several particles) to the `gathered` candidates; returns the new count.
  int append_rings(const int* cells, std::uint32_t several, int gathered);
  /// Doubles candidates_ and the scan's scratch with it.
  void grow_candidates();
  /// Updates p with the earliest contact of i (at x, moving with v) with the first `count`
  /// candidates; `imaged`: whether a candidate may need a periodic image (needs_image()).
  void scan(int i, int count, const Vec3& x, const Vec3& v, bool imaged, Pending& p);
  /// Whether the minimum image can change the separation of a particle in cell c from one in an
  /// adjacent cell: not when c is not at a periodic face and the box spans at least 5 cells
  /// along every periodic axis (separations then stay under 2 cells, the half box 2.5 or more).
  bool needs_image(const std::array<int, 3>& c) const;
  /// Scratch of scan(): the candidates' flight states as columns, and their contact times.
  struct CandidateColumns {
    std::vector<double> x, y, z, vx, vy, vz, clock, radius, time;
    void resize(std::size_t n) {
      for (auto* column : {&x, &y, &z, &vx, &vy, &vz, &clock, &radius, &time}) column->resize(n);
    }
  };
  /// The scanning particle and the box, as scan() hands them to contact_times().
  struct ScanFrame {
    std::array<double, 3> position, velocity, acceleration, length, half_image;
    double now, radius;
  };
  /// columns.time[k] = absolute contact time with candidate k, or +inf if they never touch.
  static void contact_times(CandidateColumns& columns, int count, const ScanFrame& frame);
  /// The same times for a count that is a multiple of 4, read from the candidates' Flight lines,
  /// written to times, +inf for `self`; returns the earliest. Compiled without the acceleration's
  /// terms (kAccelerated false: they add zeros) and without the minimum image (kImaged false:
  /// it adds zeros where needs_image() is false) where a scan allows, the times bitwise the same.
  /// `lines`: scratch for the candidates' line addresses, as long as candidates_.
  template <bool kAccelerated, bool kImaged>
  static double contact_times_avx2(const Flight* flight, const int* candidates, int count,
                                   int self, const ScanFrame& frame, std::uintptr_t* lines,
                                   double* times);
  /// gather_adjacent() in AVX2 registers: the cells are `base` plus `offsets` (in the grid, or
  /// in the padded grid when `padded`), their head words gathered eight at a time and the
  /// occupied ones packed to the front.
  int gather_avx2(int base, const int* offsets, int count, bool padded);
  /// next_crossing() without acceleration, the three axes in one vector.
  double next_crossing_avx2(const Pending& p, const Vec3& x, const Vec3& v, int* face) const;
  /// Puts particle i at the end of `cell`'s ring, or takes it out of it (the ring's last
  /// particle taking its place).
  void bin(int i, int cell);
  void unbin(int i, int cell);
  int padded_index(const std::array<int, 3>& c) const;
  int cell_index(const std::array<int, 3>& c) const;
  /// Time from now until particle i leaves its cell, and across which face; +inf if never.
  double next_crossing(int i, const Vec3& x, const Vec3& v, int* face) const;
  double key(int i) const;
  /// predict(), then the particle's new key() into the calendar.
  void predict_and_schedule(int i, int layer);

  EventDrivenSettings settings_;
  bool avx2_ = false;  ///< whether scan() uses contact_times_avx2()
  std::vector<CollisionRecord>* log_ = nullptr;
  Vec3 acceleration_ = Vec3::Zero();
  bool accelerated_ = false;
  double now_ = 0.0;
  int dimension_ = 3;
  Vec3 lo_ = Vec3::Zero();
  Vec3 length_ = Vec3::Ones();
  std::array<double, 3> cell_size_{1, 1, 1};
  std::array<int, 3> cells_{1, 1, 1};
  std::array<bool, 3> periodic_{true, true, true};
  std::array<double, 3> half_image_{};  ///< half the length of periodic axes, +inf on the others
  std::array<std::array<bool, 2>, 3> wall_{};
  HugePageVector<Flight> flight_;               ///< authoritative x, v while events are pending
  HugePageVector<Pending> pending_;
  HugePageVector<Spin> spin_;
  HugePageVector<double> inverse_mass_;  ///< every collision reads its particles' (8 bytes each)
  HugePageVector<Burst> burst_;
  bool spinning_ = false;  ///< whether any particle has an angular acceleration
  /// Whether collisions leave angular velocities alone (no friction): then they read and write
  /// no Spin line (one cache miss per particle less for large N).
  bool frictionless_ = false;
  HugePageVector<std::uint32_t> counter_;       ///< collisions so far (stale-candidate test)
  /// Per cell (and the empty one): the particle if it holds exactly one, kEmptyHead if none,
  /// else several_head() of the first of its ring. What a scan reads of a cell: 4 bytes, which
  /// mostly stay in cache, and the ring's links only where it holds several.
  HugePageVector<int> head_;
  HugePageVector<CellLink> cell_link_;          ///< per particle: its cell's ring
  std::vector<int> candidates_;              ///< scratch of gather(), kCandidateSlack past them
  CandidateColumns columns_;                 ///< scratch of scan()
  ScanFrame scan_frame_{};                   ///< scan()'s, the box's part set by initialize()
  /// contact_times_avx2()'s scratch: the candidates' Flight line addresses.
  std::vector<std::uintptr_t> candidate_lines_;
  bool any_wall_ = false;  ///< whether any face is a wall (predict() then looks for wall contacts)
  int stencil_size_ = 27;                    ///< adjacent cells of a cell, itself included
  std::array<int, 3> pad_{};                 ///< layers of border cells (1 on the active axes)
  std::array<int, 3> padded_cells_{};
  HugePageVector<int> padded_cell_;             ///< padded grid -> cell (wrapped, or the empty one)
  /// Offsets of the adjacent cells (index 6, stencil_size_ of them, in stencil order) and of each
  /// face's layer (index = face, layer_size_: those one step across it), from a cell in the
  /// padded grid (padded_offset_) or, for an interior cell, in the grid itself (interior_offset_);
  /// 32 entries, zeros past the count, so that gather_avx2() reads whole vectors.
  static constexpr int kWholeStencil = 6;
  std::array<std::array<int, 32>, 7> padded_offset_{};
  std::array<std::array<int, 32>, 7> interior_offset_{};
  bool arithmetic_interior_ = false;         ///< whether interior cells use interior_offset_
  int empty_cell_ = 0;                       ///< stands in for cells beyond walls (n_cells)
  int layer_size_ = 9;                       ///< cells one step across a face
  bool imaging_interior_ = true;  ///< whether interior cells need the minimum image (needs_image)
  /// next_crossing_avx2()'s constants per axis (x, y, z, unused): the box's low corner, the cell
  /// size, and which faces a particle may cross (active axis, periodic or not at the box's face).
  std::array<double, 4> crossing_lo_{}, crossing_size_{};
  std::array<std::int64_t, 4> crossing_active_{}, crossing_periodic_{};
  EventCalendar calendar_;  ///< the particles by key()
  long predictions_ = 0, pair_checks_ = 0;
};

}  // namespace grainwave::particles::hardsphere

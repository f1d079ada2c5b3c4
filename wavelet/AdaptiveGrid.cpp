#include "wavelet/AdaptiveGrid.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <optional>
#include <unordered_map>
#include <type_traits>
#include <unordered_set>

#if defined(__x86_64__)
#include <x86intrin.h>
#endif

#include <fmt/format.h>

#include "core/StreamingCopy.hpp"
#include "core/Timers.hpp"
#include "wavelet/BlockPrediction.hpp"
#include "wavelet/DetailKernels.hpp"
#include "wavelet/WeightTable.hpp"

namespace grainwave::wavelet {

using namespace prediction;  // this file's own building blocks

namespace {

struct Term {
  std::size_t leaf;
  std::int64_t point;  // interior flat index of the leaf
  double weight;
};

/// How far array coordinate x of a block (bs interior points, g ghost layers) lies outside its
/// interior along an axis: 0 inside, k in the k-th ghost layer.
constexpr int ghost_depth(int x, int bs, int g) { return x < g ? g - x : x >= g + bs ? x - g - bs + 1 : 0; }

/// Adds `shift` to the field-array indices at or beyond `scratch_start`: a reused block's
/// references to its scratch points, which moved with the plan, while its block points (all
/// below scratch_start, in pages the block and its sources kept) stay.
void shift_scratch_points(std::span<std::int32_t> indices, std::int64_t scratch_start, std::int64_t shift) {
  if (shift == 0) return;
  const auto start = static_cast<std::int32_t>(scratch_start), by = static_cast<std::int32_t>(shift);
  for (auto& i : indices) i += i >= start ? by : 0;
}

/// A cheap monotone tick count, to time parts of a loop apart: the x86 time-stamp counter
/// (constant rate on current processors), else steady_clock's.
inline std::uint64_t cycle_count() {
#if defined(__x86_64__)
  return __rdtsc();
#else
  return static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
#endif
}

/// Items 0, 1, ... put in buckets by their time (0 .. times - 1, or -1 for none), keeping their
/// order within a bucket (a counting sort): bucket t is sorted[begin[t] .. begin[t + 1]), item k
/// stored as item(k).
template <class Item, class ItemOf>
void bucket_by_time(std::span<const std::int32_t> time, std::size_t times, ItemOf&& item, std::vector<std::int32_t>& begin,
                    std::vector<Item>& sorted) {
  begin.assign(times + 1, 0);
  for (const std::int32_t t : time)
    if (t >= 0) ++begin[static_cast<std::size_t>(t) + 1];
  for (std::size_t t = 0; t < times; ++t) begin[t + 1] += begin[t];
  sorted.resize(static_cast<std::size_t>(begin[times]));
  std::vector<std::int32_t> next(begin.begin(), begin.end() - 1);
  for (std::size_t k = 0; k < time.size(); ++k)
    if (time[k] >= 0) sorted[static_cast<std::size_t>(next[static_cast<std::size_t>(time[k])]++)] = item(k);
}

/// Calls f(std::integral_constant<int, k>, fields) on the field arrays in groups of k: the
/// fluid's 4 (2D) or 5 (3D) conserved fields together, other counts one by one.
template <class F>
void for_field_groups(std::vector<std::vector<double>>& data, F&& f) {
  switch (data.size()) {
    case 4: f(std::integral_constant<int, 4>{}, data.data()); break;
    case 5: f(std::integral_constant<int, 5>{}, data.data()); break;
    default:
      for (auto& field : data) f(std::integral_constant<int, 1>{}, &field);
  }
}

}  // namespace

template <int Dim>
struct AdaptiveGrid<Dim>::GhostPlan {
  // One row per ghost point of the local blocks: its offset in a field array and its value as
  // a weighted sum of local values (local_*) and of values received from other ranks (remote_*).
  std::vector<std::int32_t> dest;  // 32 bits, as local_src
  std::vector<std::int32_t> local_begin, remote_begin;
  // A local term's point: its index in the field arrays (32 bits: build_ghost_plan refuses a
  // rank holding more points, blocks and scratch points together, than that can number).
  std::vector<std::int32_t> local_src;
  // A local term's weight, as its index in `weights`: a plan holds few distinct weights
  // (products of the Deslauriers-Dubuc weights: 82 over the 2.1 million terms of a 3D sphere's
  // grid), and a fill reads each term's weight, so 2 bytes instead of 8 (the plan is read from
  // memory on every fill where it outgrows the caches).
  std::vector<std::uint16_t> local_weight;
  WeightTable weights;
  std::vector<std::int32_t> remote_src;  // index of a received point (times fields + field)
  std::vector<double> remote_w;
  // Per row: how many of its remote terms come before its local ones. A row's terms are in one
  // order on any number of ranks (by leaf along the curve, then point), and the fill sums them
  // in that order, so a ghost is bitwise the same on 1 and on several ranks.
  std::vector<std::int32_t> remote_lead;
  // Per row: 0, or for a row summed from other ghost rows (below) the number of odd axes of its
  // point less one: such rows are filled after every row with a lower stage.
  std::vector<std::uint8_t> row_stage;
  std::vector<std::uint8_t> kind;        // per local array point (GhostKind)
  // Separable prolongation. A ghost point predicted from a coarser leaf with several odd axes is
  // the tensor product of one-dimensional Deslauriers-Dubuc stencils: (ghost_order)^k terms for
  // k odd axes (36 in 2D with ghost_order 6). Along one odd axis A (the one on which it lies
  // least far out: inside the block but for corner ghosts) it is instead summed from the
  // `ghost_order` points of its line along A at the stencil's even positions, each the
  // prediction along the remaining odd axes. Where such a point is one of the block's ghosts, no
  // farther out along A and in a coarser leaf, that ghost holds this prediction already (its
  // own row); the others are "scratch" points: rows of the plan like ghosts, stored after the
  // blocks in each field array (from scratch_start on, each block's contiguous, from
  // block_scratch_begin). Neighbouring ghosts share most of these points: in 2D a face's odd-odd
  // rows fall from 36 terms to 6, plus a few scratch rows of 6 at its ends. The sum is the
  // tensor's in another order (equal to round-off), and the same on any number of ranks.
  std::int64_t scratch_start = 0;  // pages x block volume when built
  std::vector<std::int32_t> block_scratch_begin;
  /// Where block `slot`'s scratch points start in the field arrays.
  std::int64_t scratch_of(std::size_t slot) const { return scratch_start + block_scratch_begin[slot]; }
  // Per local block, for reuse after an adaptation: its first row (a block reused from the
  // previous plan has none: its grouped entries below are all that is kept of it), whether any
  // of its terms is remote, its position along the curve, and the leaves its rows were resolved
  // from (as local slots, -1 for another rank's; flattened).
  std::vector<std::int32_t> block_row_begin, block_dependency_begin;
  std::vector<char> block_has_remote, block_rebuilt;  // ... and whether its rows were built afresh
  std::vector<std::uint64_t> block_curve;
  std::vector<std::int32_t> block_dependencies;
  // Per local term, the page of the block it reads (the plan addresses points by page, which a
  // block keeps while it stays, so a reused block's entries need no renumbering), or
  // kScratchPage.
  std::vector<std::int32_t> local_src_page;
  static constexpr std::int32_t kScratchPage = -1;
  /// Whether row k copies one value: one local term of weight 1, nothing remote.
  bool is_copy(std::size_t k) const {
    return remote_begin[k + 1] == remote_begin[k] && local_begin[k + 1] - local_begin[k] == 1 &&
           local_weight[static_cast<std::size_t>(local_begin[k])] == WeightTable::kOne;
  }
  // The rows (and segments, below) again, sorted for filling: copies (one local term of weight
  // 1, nothing remote: same-level neighbours and injection from finer leaves, most ghosts),
  // merged into runs of consecutive points (a ghost row facing one neighbour reads one of its
  // rows), and weighted sums; and the rows with remote terms. In two groups: 0, the ghosts
  // within the stencil reach (AdaptiveGrid::set_stencil_reach; all of them unless it is set),
  // and 1, the others.
  // Runs of one length that follow each other at fixed strides in the destination and the
  // source are one rectangle, as a box-to-box copy: a block's side face with two ghost layers
  // is eight runs of two values (2D, 8^2 blocks), each a few loads and a loop exit that the
  // next run's length may mispredict; as one rectangle its rows repeat one pattern.
  struct CopyRun {
    std::int32_t dest, src;  // field array indices of the first row (32 bits, as local_src)
    std::int32_t length;     // values per row
    std::int32_t src_page;   // the page of the local block it reads (a rectangle reads one block)
    std::int32_t rows = 1;
    std::int32_t dest_stride = 0, src_stride = 0;  // from one row to the next
  };
  // Lists 0 and 1: the two groups; list 2: the rows of the blocks whose rows were built afresh
  // by the last rebuild (both groups: the others' ghosts came through the adaptation unchanged).
  std::array<std::vector<CopyRun>, 3> copy_runs;
  // The ghosts copied from a same-level leaf of this rank (most of them), which have no rows:
  // one segment (a CopyRun of one row) per line of the block's array and region around it,
  // `length` consecutive points of that leaf, in array order; block `slot`'s from
  // block_segment_begin[slot] (none for a block reused from the previous plan, which, as for its
  // rows, keeps only its grouped entries). The grouping splits each segment by reach group
  // instead of testing its points one by one as rows (they were two thirds of a rebuild's rows).
  std::vector<CopyRun> segments;
  std::vector<std::int32_t> block_segment_begin;
  std::array<std::vector<std::int32_t>, 3> remote_rows;  // row numbers
  // The local weighted rows, as a fill reads them: per list, its sums and (kinds 1 and 2) the
  // rows summed from other ghost rows, of stages 1 and 2, filled after everything else, stage by
  // stage. Each with its destination and terms alongside: a fill reads them in sequence, and a
  // reused block's are copied from the previous plan, which kept no rows for it.
  struct PackedRows {
    std::vector<std::int32_t> dest, begin, src;
    std::vector<std::uint16_t> weight;
    std::size_t rows() const { return dest.size(); }
    /// No rows, the storage kept.
    void clear() {
      dest.clear();
      src.clear();
      weight.clear();
      begin.assign(1, 0);
    }
    /// A row writing `to`, its terms at `from` with weights `by` (indices into the WeightTable).
    void append(std::int32_t to, std::span<const std::int32_t> from, std::span<const std::uint16_t> by) {
      dest.push_back(to);
      src.insert(src.end(), from.begin(), from.end());
      weight.insert(weight.end(), by.begin(), by.end());
      begin.push_back(static_cast<std::int32_t>(src.size()));
    }
  };
  std::array<std::array<PackedRows, 3>, 3> packed;
  // Per kind of packed rows, its index in block_group_begin (below).
  static constexpr std::array<std::size_t, 3> kPackedGroup{1, 3, 4};
  // Per list 0 and 1 and per local block (and one past the last): where its entries begin in
  // copy_runs, packed[.][0], remote_rows, packed[.][1] and packed[.][2]. Each block's entries are
  // contiguous (no run spans two blocks), so a block whose rows are reused after an adaptation
  // takes its entries from the old plan instead of having its rows built and grouped again
  // (group_ghost_rows). grouped_reach: the stencil reach they were grouped for; a plan grouped
  // for another reach is not reused.
  std::array<std::array<std::vector<std::int32_t>, 5>, 2> block_group_begin;
  std::array<int, 3> grouped_reach{-1, -1, -1};
  // Per local block: its slot in the plan it was reused from, or -1 (built afresh).
  std::vector<std::int32_t> reused_from;
  // The blocks in the order write_and_fill_stencil_ghosts fills them: each once the last block
  // its rows read has been written (fill_when_written[fill_when_begin[t] .. fill_when_begin[t +
  // 1]) after block t), those reading another rank's values after the messages.
  std::vector<std::int32_t> fill_when_begin, fill_when_written, fill_after_messages;
  // The copy rectangles of list 0 of those blocks (not of the blocks filled after the messages),
  // each made as soon as the later of its two blocks is written, source or destination
  // (copy_when[copy_when_begin[t] .. copy_when_begin[t + 1]) after block t), rather than when
  // its destination's last source is: both blocks' values are then the freshest they can be in
  // cache (two moving cylinders: the share of copied values with a side written over 64 blocks
  // earlier falls from 0.24 to 0.11).
  // Ordered by the first fill that uses them (only write_and_fill_stencil_ghosts does), not by
  // every rebuild: a wavelet-only grid never needs them.
  std::vector<std::int32_t> copy_when_begin;
  std::vector<CopyRun> copy_when;
  // Their sums (list 0's packed rows of kind 0: ghosts predicted from coarser leaves) likewise,
  // each after the later of its destination and every block it reads is written
  // (sum_when[sum_when_begin[t] .. sum_when_begin[t + 1]) after block t). The rows summed
  // from other ghost rows (kinds 1 and 2) still come when the block is filled: they read these.
  std::vector<std::int32_t> sum_when_begin;
  PackedRows sum_when;
  bool copies_and_sums_ordered = false;
  // Messages: point-major buffers [point][field], one contiguous range per peer rank.
  std::vector<int> recv_rank, recv_first, recv_count;
  std::vector<int> send_rank, send_first, send_count;
  std::vector<std::int64_t> send_src;
  std::vector<double> send_buffer, recv_buffer;
  std::vector<MPI_Request> requests;

  /// Empties every list, keeping its storage (a rebuild refills the plan it replaced last time).
  void clear() {
    auto empty = [](auto&... lists) { (lists.clear(), ...); };
    empty(dest, local_begin, remote_begin, local_src, local_weight, remote_src, remote_w, remote_lead, row_stage, kind,
          block_scratch_begin, block_row_begin, block_dependency_begin, block_has_remote, block_rebuilt, block_curve,
          segments, block_segment_begin,
          block_dependencies, local_src_page, recv_rank, recv_first, recv_count, send_rank, send_first, send_count,
          send_src, send_buffer, recv_buffer, requests);
    scratch_start = 0;
    for (std::size_t list = 0; list < copy_runs.size(); ++list) {
      empty(copy_runs[list], remote_rows[list]);
      for (auto& rows : packed[list]) rows.clear();
    }
    for (auto& list : block_group_begin)
      for (auto& begin : list) begin.clear();
    reused_from.clear();
    weights = WeightTable{};
    grouped_reach = {-1, -1, -1};
    empty(fill_when_begin, fill_when_written, fill_after_messages, copy_when_begin, copy_when, sum_when_begin);
    sum_when.clear();
    copies_and_sums_ordered = false;
  }
};

template <int Dim>
AdaptiveGrid<Dim>::AdaptiveGrid(GridConfig<Dim> config, MPI_Comm comm)
    : config_(std::move(config)), comm_(comm), forest_([&] {
        ForestConfig<Dim> f;
        f.roots = config_.roots;
        f.periodic = config_.periodic;
        f.max_level = config_.max_level;
        f.curve = config_.curve;
        return f;
      }()) {
  const int bs = config_.block_size;
  if (bs < 8 || bs > kMaxBlockSize || bs % 2 != 0)
    throw std::invalid_argument("AdaptiveGrid: block size must be even, 8.." + std::to_string(kMaxBlockSize));
  if (config_.order != 4 && config_.order != 6)
    throw std::invalid_argument("AdaptiveGrid: interpolation order must be 4 or 6");
  if (config_.ghost_order == 0) config_.ghost_order = config_.order;
  if (config_.ghost_order != 4 && config_.ghost_order != 6)
    throw std::invalid_argument("AdaptiveGrid: ghost interpolation order must be 4 or 6");
  if (config_.min_level < 0 || config_.min_level > config_.max_level)
    throw std::invalid_argument("AdaptiveGrid: need 0 <= min_level <= max_level");
  // Prediction of the last odd point reads order - 1 points beyond it; derivatives accuracy / 2.
  // (Stencils are built from global level indices, so the ghost width need not be even.)
  if (config_.ghosts == 0) config_.ghosts = std::max(config_.order - 1, config_.derivative_accuracy / 2);
  if (config_.ghosts < config_.order - 1 || config_.ghosts < config_.derivative_accuracy / 2 || config_.ghosts > bs)
    throw std::invalid_argument("AdaptiveGrid: ghosts must be >= order - 1, >= accuracy / 2 and <= block size");
  if (config_.fields.empty()) throw std::invalid_argument("AdaptiveGrid: no fields");
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    if (!(config_.hi[au] > config_.lo[au])) throw std::invalid_argument("AdaptiveGrid: empty domain");
    // A non-periodic line needs `order` coarse points at the coarsest level for one-sided rows.
    // (Ghosts are predicted from level >= 0, which has roots * bs >= 8 points: enough for order 6.)
    if (!config_.periodic[au] && config_.roots[au] * bs / 2 < config_.order)
      throw std::invalid_argument("AdaptiveGrid: too few points for the interpolation order");
  }
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &ranks_);
  layout_.interior.fill(bs);
  layout_.ghosts = config_.ghosts;
  stencil_reach_.fill(config_.ghosts);
  interior_points_ = 1;
  for (int a = 0; a < Dim; ++a) interior_points_ *= static_cast<std::size_t>(bs);
  block_volume_ = layout_.shape().size();
  for (int l = 0; l < config_.min_level; ++l) {
    std::vector<AdaptTag> all(forest_.size(), AdaptTag::kRefine);
    forest_.adapt(all);
  }
  refresh_partition();
  allocate_local();
  build_ghost_plan();
}

template <int Dim>
AdaptiveGrid<Dim>::AdaptiveGrid(const AdaptiveGrid& o)
    : config_(o.config_), comm_(o.comm_), rank_(o.rank_), ranks_(o.ranks_), forest_(o.forest_),
      offsets_(o.offsets_), first_leaf_(o.first_leaf_), local_keys_(o.local_keys_), layout_(o.layout_),
      interior_points_(o.interior_points_), block_volume_(o.block_volume_), data_(o.data_), page_of_(o.page_of_),
      free_pages_(o.free_pages_), pages_(o.pages_), plan_(std::make_unique<GhostPlan>(*o.plan_)), layout_serial_(o.layout_serial_), stencil_reach_(o.stencil_reach_) {
  // The plan is copied, not rebuilt: the solver copies its grid every step to keep the last good
  // state, and rebuilding the plan there cost 7% of a 2D Navier-Stokes run in perf (11% of wall time).
}

template <int Dim>
AdaptiveGrid<Dim>& AdaptiveGrid<Dim>::operator=(const AdaptiveGrid& o) {
  if (this == &o) return *this;
  if (o.comm_ != comm_) throw std::invalid_argument("AdaptiveGrid: assignment across communicators");
  data_.resize(o.data_.size());
  // Streamed (core/StreamingCopy.hpp): the copy is the solver's last good state, read back only
  // after a failure.
  for (std::size_t f = 0; f < data_.size(); ++f) {
    data_[f].resize(o.data_[f].size());
    copy_streaming(o.data_[f].data(), o.data_[f].size(), data_[f].data());
  }
  // The solver keeps its last good state by assignment every step; between adaptations only
  // the values differ (copying the plan as well was 1.3% of a 2D Navier-Stokes run).
  if (plan_ && layout_serial_ == o.layout_serial_ && stencil_reach_ == o.stencil_reach_) return *this;
  layout_serial_ = o.layout_serial_;
  stencil_reach_ = o.stencil_reach_;
  config_ = o.config_;
  rank_ = o.rank_;
  ranks_ = o.ranks_;
  forest_ = o.forest_;
  offsets_ = o.offsets_;
  first_leaf_ = o.first_leaf_;
  local_keys_ = o.local_keys_;
  layout_ = o.layout_;
  interior_points_ = o.interior_points_;
  block_volume_ = o.block_volume_;
  page_of_ = o.page_of_;
  free_pages_ = o.free_pages_;
  pages_ = o.pages_;
  if (plan_) *plan_ = *o.plan_;
  else plan_ = std::make_unique<GhostPlan>(*o.plan_);
  operators_.clear();  // built again on demand, for this grid's configuration
  detail_stencils_.clear();
  slot_detail_stencils_.clear();
  bound_rest_.clear();
  first_field_.clear();
  fields_computed_.clear();
  parent_sources_.clear();
  return *this;
}

template <int Dim>
AdaptiveGrid<Dim>::~AdaptiveGrid() = default;

template <int Dim>
void AdaptiveGrid<Dim>::refresh_partition() {
  offsets_ = forest_.partition(ranks_);
  first_leaf_ = offsets_[static_cast<std::size_t>(rank_)];
  const auto leaves = forest_.leaves();
  slot_detail_stencils_.clear();  // the slots hold other blocks now
  bound_rest_.clear();
  first_field_.clear();
  fields_computed_.clear();
  local_keys_.assign(leaves.begin() + static_cast<std::ptrdiff_t>(first_leaf_),
                     leaves.begin() + static_cast<std::ptrdiff_t>(offsets_[static_cast<std::size_t>(rank_) + 1]));
}

template <int Dim>
void AdaptiveGrid<Dim>::allocate_local() {
  pages_in_slot_order();
  data_.assign(config_.fields.size(), std::vector<double>(pages_ * block_volume_, 0.0));
}

template <int Dim>
void AdaptiveGrid<Dim>::pages_in_slot_order() {
  pages_ = local_keys_.size();
  page_of_.resize(pages_);
  std::iota(page_of_.begin(), page_of_.end(), 0);
  free_pages_.clear();
}

template <int Dim>
int AdaptiveGrid<Dim>::owner(std::size_t leaf) const {
  const auto it = std::upper_bound(offsets_.begin(), offsets_.end(), leaf);
  return static_cast<int>(it - offsets_.begin()) - 1;
}

template <int Dim>
typename AdaptiveGrid<Dim>::Point AdaptiveGrid<Dim>::spacing(int level) const {
  Point h{};
  // 2^level exactly, as std::ldexp(1.0, level) gives it, without a library call (block origins
  // and spacings are asked for every leaf in every adaptation pass: the forced region's boxes).
  const double blocks_per_root = level >= 0 && level < 63 ? static_cast<double>(std::uint64_t{1} << level) : std::ldexp(1.0, level);
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    h[au] = (config_.hi[au] - config_.lo[au]) / (static_cast<double>(config_.roots[au]) * config_.block_size * blocks_per_root);
  }
  return h;
}

template <int Dim>
typename AdaptiveGrid<Dim>::Point AdaptiveGrid<Dim>::origin(const Key& key) const {
  const Point h = spacing(key.level);
  const auto c = key.coords();
  Point x{};
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    x[au] = config_.lo[au] + static_cast<double>(c[au]) * config_.block_size * h[au];
  }
  return x;
}

template <int Dim>
double AdaptiveGrid<Dim>::uniform_points() const {
  double n = 1;
  for (int a = 0; a < Dim; ++a)
    n *= static_cast<double>(config_.roots[static_cast<std::size_t>(a)]) * config_.block_size *
         std::ldexp(1.0, config_.max_level);
  return n;
}

template <int Dim>
typename AdaptiveGrid<Dim>::Point AdaptiveGrid<Dim>::position(std::size_t slot, const Index& i) const {
  const Point x0 = origin(local_keys_[slot]);
  const Point h = spacing(local_keys_[slot].level);
  Point x{};
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    x[au] = x0[au] + i[au] * h[au];
  }
  return x;
}

template <int Dim>
int AdaptiveGrid<Dim>::field_index(const std::string& name) const {
  for (std::size_t k = 0; k < config_.fields.size(); ++k)
    if (config_.fields[k] == name) return static_cast<int>(k);
  return -1;
}

template <int Dim>
std::span<double> AdaptiveGrid<Dim>::block(int field, std::size_t slot) {
  return {data_[static_cast<std::size_t>(field)].data() + block_base(slot), block_volume_};
}

template <int Dim>
std::span<const double> AdaptiveGrid<Dim>::block(int field, std::size_t slot) const {
  return {data_[static_cast<std::size_t>(field)].data() + block_base(slot), block_volume_};
}

template <int Dim>
std::array<std::array<bool, 2>, Dim> AdaptiveGrid<Dim>::bounded_edges(const Key& key) const {
  std::array<std::array<bool, 2>, Dim> touches{};
  const auto c = key.coords();  // once: de-interleaving the Morton code is not free
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    touches[au][0] = !config_.periodic[au] && c[au] == 0;
    touches[au][1] = !config_.periodic[au] && c[au] + 1 == forest_.blocks_along(a, key.level);
  }
  return touches;
}

// ---------------------------------------------------------------------------------------------
// Ghost plan: every ghost point as a weighted sum of leaf interior points (see the header).

namespace {

template <int Dim>
struct PointResolver {
  const BlockForest<Dim>& forest;
  const GridConfig<Dim>& config;

  GlobalIndex64 points_along(int axis, int level) const {
    return static_cast<GlobalIndex64>(config.roots[static_cast<std::size_t>(axis)]) * config.block_size << level;
  }

  /// Leaf containing the level-`level` point `idx` (inside the domain). Levels are tried
  /// outwards from `level` (2:1 balance puts the answer within a level or two), and the last
  /// few hits are remembered: consecutive ghost points mostly fall into the same block, and a
  /// block's walk through its array alternates between a few (the left and right neighbours
  /// along each row of its side faces), which a single remembered hit missed at every turn.
  std::size_t leaf_containing(int level, const std::array<GlobalIndex64, Dim>& idx) const {
    for (int k = 0; k < remembered; ++k) {
      const Hit& hit = recent[static_cast<std::size_t>(k)];
      // A range test, not a division (64-bit divisions by the block size dominated the rebuild:
      // a coarse-fine ghost resolves up to 36 points in 2D, each tested here).
      bool same = true;
      for (int a = 0; a < Dim && same; ++a) {
        const auto au = static_cast<std::size_t>(a);
        const GlobalIndex64 at = hit.level >= level ? idx[au] << (hit.level - level) : idx[au] >> (level - hit.level);
        const GlobalIndex64 offset = at - hit.first[au];
        same = offset >= 0 && offset < config.block_size;
      }
      if (!same) continue;
      if (k > 0) std::rotate(recent.begin(), recent.begin() + k, recent.begin() + k + 1);  // to the front
      return recent[0].leaf;
    }
    for (int step = 0; step <= 2 * config.max_level + 1; ++step) {
      const int l = level + ((step % 2 == 0) ? step / 2 : -(step + 1) / 2);
      if (l < 0 || l > config.max_level) continue;
      std::array<std::uint32_t, Dim> c{};
      for (int a = 0; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        const GlobalIndex64 at = l >= level ? idx[au] << (l - level) : idx[au] >> (level - l);
        c[au] = static_cast<std::uint32_t>(at / config.block_size);
      }
      if (const auto found = forest.find(BlockKey<Dim>::from_coords(l, c))) {
        Hit hit{l, c, {}, *found};
        for (int a = 0; a < Dim; ++a)
          hit.first[static_cast<std::size_t>(a)] = static_cast<GlobalIndex64>(c[static_cast<std::size_t>(a)]) * config.block_size;
        std::rotate(recent.begin(), recent.end() - 1, recent.end());  // the oldest out
        recent[0] = hit;
        remembered = std::min(remembered + 1, static_cast<int>(recent.size()));
        // Consecutive lookups mostly find the same few leaves: skip repeats of the last one.
        if (found_leaves && (found_leaves->empty() || found_leaves->back() != *found)) found_leaves->push_back(*found);
        return *found;
      }
    }
    throw std::logic_error("AdaptiveGrid: point not covered by the forest");
  }
  /// The interior coordinates, in the leaf last found (at its level, no coarser than `level`),
  /// of the level-`level` point idx it contains: the point injected from there.
  std::array<int, Dim> injected(int level, const std::array<GlobalIndex64, Dim>& idx) const {
    std::array<int, Dim> i{};
    for (int a = 0; a < Dim; ++a) {
      const auto au = static_cast<std::size_t>(a);
      const GlobalIndex64 fine = idx[au] << (last().level - level);
      i[au] = static_cast<int>(fine - static_cast<GlobalIndex64>(last().coords[au]) * config.block_size);
    }
    return i;
  }
  /// The last few leaves found, the one last found or hit first: level, coordinates, first
  /// point (coordinates * block size) and index.
  struct Hit {
    int level;
    std::array<std::uint32_t, Dim> coords;
    std::array<GlobalIndex64, Dim> first;
    std::size_t leaf;
  };
  mutable std::array<Hit, 4> recent{};
  mutable int remembered = 0;
  /// The leaf the last lookup found or hit (after a lookup).
  const Hit& last() const { return recent[0]; }
  /// When set, every leaf found by a lookup (not among the remembered hits) is appended: with
  /// the hits forgotten before each block, these are all the leaves its ghosts read (but the
  /// same-level ones build_ghost_plan finds per region, which it appends itself).
  std::vector<std::size_t>* found_leaves = nullptr;
  void forget() const { remembered = 0; }

  /// Appends the terms giving the value at (level, idx): a leaf's point, by injection from a
  /// finer leaf, or by Deslauriers-Dubuc prediction from level - 1.
  void resolve(int level, const std::array<GlobalIndex64, Dim>& idx, double weight,
               std::vector<Term>& out) const {
    const std::size_t leaf = leaf_containing(level, idx);
    // leaf_containing leaves the leaf's level and coordinates in last_*: no de-interleaving.
    const int leaf_level = last().level;
    if (leaf_level >= level) {
      const auto i = injected(level, idx);
      std::int64_t point = 0;
      for (int a = Dim - 1; a >= 0; --a) point = point * config.block_size + i[static_cast<std::size_t>(a)];
      out.push_back({leaf, point, weight});
      return;
    }
    predict(level, idx, weight, out);
  }

  /// Appends the terms of the Deslauriers-Dubuc prediction at (level, idx) from level - 1 (what
  /// resolve gives where a coarser leaf contains the point), whichever leaf contains it.
  void predict(int level, const std::array<GlobalIndex64, Dim>& idx, double weight, std::vector<Term>& out) const {
    std::array<LineStencil, Dim> st{};
    for (int a = 0; a < Dim; ++a) {
      const auto au = static_cast<std::size_t>(a);
      if (idx[au] % 2 == 0) {
        st[au].size = 1;
        st[au].even[0] = idx[au];
        st[au].weight[0] = 1.0;
      } else {
        st[au] = dd_line(config.ghost_order, idx[au], points_along(a, level), config.periodic[au]);
      }
    }
    std::array<int, Dim> k{};
    while (true) {
      std::array<GlobalIndex64, Dim> coarse{};
      double w = weight;
      for (int a = 0; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        const GlobalIndex64 n = points_along(a, level);
        GlobalIndex64 e = st[au].even[static_cast<std::size_t>(k[au])];
        // Periodic images (non-periodic stencils stay inside); a stencil reaches less than a
        // block beyond the domain, so this wraps once, without a division.
        while (e < 0) e += n;
        while (e >= n) e -= n;
        coarse[au] = e / 2;
        w *= st[au].weight[static_cast<std::size_t>(k[au])];
      }
      resolve(level - 1, coarse, w, out);
      int a = 0;
      for (; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        if (++k[au] < st[au].size) break;
        k[au] = 0;
      }
      if (a == Dim) break;
    }
  }
};

}  // namespace

template <int Dim>
void AdaptiveGrid<Dim>::build_ghost_plan(std::unique_ptr<GhostPlan> previous, std::span<const Key> previous_keys) {
  static std::atomic<std::uint64_t> serials{0};
  layout_serial_ = ++serials;
  // Built into the plan the previous rebuild replaced: its lists keep their storage, so a moving
  // grid's rebuilds do not fault fresh pages in (the kernel zeroing them was 10% of a rebuild).
  // Without a previous plan (a rebuild from a leaf set), the current one is replaced outright:
  // its storage serves the same way.
  if (!spare_plan_ && !previous) spare_plan_ = std::move(plan_);
  plan_ = spare_plan_ ? std::move(spare_plan_) : std::make_unique<GhostPlan>();
  plan_->clear();
  GhostPlan& plan = *plan_;
  std::vector<std::size_t> found;
  PointResolver<Dim> resolver{forest_, config_};
  resolver.found_leaves = &found;
  const auto shape = layout_.shape();
  const int g = layout_.ghosts, bs = config_.block_size;
  plan.kind.assign(local_keys_.size() * block_volume_, static_cast<std::uint8_t>(GhostKind::kSameLevel));
  plan.local_begin.push_back(0);
  plan.remote_begin.push_back(0);
  plan.block_row_begin.push_back(0);
  plan.block_dependency_begin.push_back(0);
  plan.block_scratch_begin.push_back(0);
  plan.block_segment_begin.push_back(0);
  plan.scratch_start = static_cast<std::int64_t>(pages_ * block_volume_);
  // The plan numbers points in 32 bits (GhostPlan::local_src).
  auto refuse_beyond_32_bits = [](std::int64_t points) {
    if (points > std::numeric_limits<std::int32_t>::max())
      throw std::length_error(fmt::format("AdaptiveGrid: {} points (blocks and scratch) on one rank, more than a ghost plan "
                                          "numbers (2^31 - 1): use more ranks or fewer levels",
                                          points));
  };
  refuse_beyond_32_bits(plan.scratch_start);
  std::int64_t scratch_points = 0;  // so far, over the blocks done
  // Requests to other ranks: (leaf, point) -> position in that rank's list.
  std::vector<std::map<std::pair<std::size_t, std::int64_t>, int>> wanted(static_cast<std::size_t>(ranks_));
  std::vector<std::pair<int, int>> remote_pending;  // (rank, position) per remote term
  std::vector<Term> terms;
  std::vector<std::pair<Index, std::array<GlobalIndex64, Dim>>> scratch;  // the block's (GhostPlan)
  // Where in `scratch` each position around a block is (-1: none yet), over the block's array
  // widened by a stencil's reach on every side, and which entries were set (reset per block).
  const int scratch_margin = 2 * kMaxPredictOrder;
  const int scratch_width = bs + 2 * g + 2 * scratch_margin;
  std::size_t scratch_table_size = 1;
  for (int a = 0; a < Dim; ++a) scratch_table_size *= static_cast<std::size_t>(scratch_width);
  std::vector<std::int32_t> scratch_at(scratch_table_size, -1);
  auto scratch_cell = [&](const Index& at) {
    std::size_t cell = 0;
    for (int a = Dim - 1; a >= 0; --a) {
      const int x = at[static_cast<std::size_t>(a)] + scratch_margin;
      if (x < 0 || x >= scratch_width) throw std::logic_error("AdaptiveGrid: scratch point beyond a stencil's reach");
      cell = cell * static_cast<std::size_t>(scratch_width) + static_cast<std::size_t>(x);
    }
    return cell;
  };

  // Reuse after an adaptation. A block's rows are a function of the leaves containing the
  // points its ghosts resolve to (leaves tile the domain, so whichever lookup found them, the
  // same leaves give the same rows). If the block is still here and every one of those leaves
  // is still a leaf owned by this rank, its grouped entries are taken from the previous plan
  // (group_ghost_rows) and it gets no rows; otherwise (or when a row read another rank) they are
  // built again. A plan grouped for another stencil reach is not reused.
  // The old and the new local blocks are both sorted by (curve index, key): one merge pairs the
  // blocks still here with their old slots, without a lookup per block and per leaf read.
  const GhostPlan* reused = previous && previous->grouped_reach == stencil_reach_ ? previous.get() : nullptr;
  std::vector<std::int64_t> slot_now;  // previous slot -> slot now, -1 if not local any more
  std::vector<std::int64_t> slot_before(local_keys_.size(), -1);  // slot now -> previous slot, or -1
  if (reused) {
    slot_now.assign(previous_keys.size(), -1);
    std::size_t o = 0, n = 0;
    while (o < previous_keys.size() && n < local_keys_.size()) {
      const auto before = std::make_pair(previous->block_curve[o], previous_keys[o]);
      const auto now = std::make_pair(forest_.leaf_curve_index(first_leaf_ + n), local_keys_[n]);
      if (before < now) {
        ++o;
      } else if (now < before) {
        ++n;
      } else {
        slot_now[o] = static_cast<std::int64_t>(n);
        slot_before[n] = static_cast<std::int64_t>(o);
        ++o;
        ++n;
      }
    }
  }
  auto reusable = [&](std::size_t slot) -> std::optional<std::size_t> {
    if (!reused || slot_before[slot] < 0) return std::nullopt;
    const auto o = static_cast<std::size_t>(slot_before[slot]);
    if (reused->block_has_remote[o]) return std::nullopt;
    for (auto d = reused->block_dependency_begin[o]; d < reused->block_dependency_begin[o + 1]; ++d) {
      const std::int32_t read = reused->block_dependencies[static_cast<std::size_t>(d)];
      if (read < 0 || slot_now[static_cast<std::size_t>(read)] < 0) return std::nullopt;
    }
    return o;
  };
  if (reused) plan.weights = reused->weights;  // the rows taken from it keep their weights' indices

  // Appends the terms a resolution left in `terms` to row `row`: sorted by (leaf, point), the
  // same order on any number of ranks, repeated points merged, zero weights dropped.
  auto add_terms = [&](std::size_t row) {
    if (terms.size() > 1) std::sort(terms.begin(), terms.end(), [](const Term& x, const Term& y) {
        return x.leaf != y.leaf ? x.leaf < y.leaf : x.point < y.point;
      });
    for (std::size_t t = 0; t < terms.size(); ++t) {
      double w = terms[t].weight;
      while (t + 1 < terms.size() && terms[t + 1].leaf == terms[t].leaf && terms[t + 1].point == terms[t].point)
        w += terms[++t].weight;
      if (w == 0.0) continue;
      const std::size_t leaf = terms[t].leaf;
      const bool mine = leaf >= first_leaf_ && leaf < first_leaf_ + local_keys_.size();  // no search
      const int who = mine ? rank_ : owner(leaf);
      if (who == rank_) {
        std::array<int, Dim> q{};
        // 32-bit division: a block has at most 32^3 points (64-bit idiv dominated here).
        auto rest = static_cast<std::uint32_t>(terms[t].point);
        const auto ubs = static_cast<std::uint32_t>(bs);
        for (int a = 0; a < Dim; ++a) {
          q[static_cast<std::size_t>(a)] = static_cast<int>(rest % ubs) + g;
          rest /= ubs;
        }
        plan.local_src.push_back(static_cast<std::int32_t>(block_base(leaf - first_leaf_) + static_cast<std::size_t>(shape.index(q))));
        plan.local_src_page.push_back(page_of_[leaf - first_leaf_]);
        plan.local_weight.push_back(plan.weights.index_of(w));
      } else {
        auto& list = wanted[static_cast<std::size_t>(who)];
        const auto [it, added] = list.try_emplace({leaf, terms[t].point}, static_cast<int>(list.size()));
        remote_pending.emplace_back(who, it->second);
        plan.remote_w.push_back(w);
        if (static_cast<std::int32_t>(plan.local_src.size()) == plan.local_begin[row]) ++plan.remote_lead[row];
      }
    }
  };
  auto depth = [&](int x) { return ghost_depth(x, bs, g); };
  // The separable form (GhostPlan) of row `row`: ghost i (global idx) of block `slot`, predicted
  // from a coarser leaf. Returns false, adding nothing, where it has none (fewer than two odd
  // axes). It runs along the odd axis A on which the ghost lies least far out (inside the block
  // for all but corner ghosts). Of the points it reads, the block's own ghosts are those no
  // farther out along A, so no farther out at all: each is filled whenever this row is (a ghost
  // within a stencil reach has its whole line towards the block within it). None of them is an
  // interior point: had the ghost another axis inside the block, that axis would be odd-free or
  // of depth 0 < depth(A); an odd one would have been chosen, so another axis is outside.
  auto add_separable_row = [&](std::size_t slot, int level, const Index& i, const std::array<GlobalIndex64, Dim>& idx,
                               const std::array<GlobalIndex64, Dim>& points_along, std::size_t row) {
    int odd_axes = 0, along = -1;
    for (int a = 0; a < Dim; ++a) {
      const auto au = static_cast<std::size_t>(a);
      if (idx[au] % 2 == 0) continue;
      ++odd_axes;
      if (along < 0 || depth(i[au]) < depth(i[static_cast<std::size_t>(along)])) along = a;
    }
    if (odd_axes < 2) return false;
    const auto A = static_cast<std::size_t>(along);
    const GlobalIndex64 n = points_along[A];
    const LineStencil line = dd_line(config_.ghost_order, idx[A], n, config_.periodic[A]);
    for (int m = 0; m < line.size; ++m) {
      const auto mu = static_cast<std::size_t>(m);
      Index at = i;
      at[A] += static_cast<int>(line.even[mu] - idx[A]);
      std::array<GlobalIndex64, Dim> point = idx;
      point[A] = line.even[mu];
      while (point[A] < 0) point[A] += n;  // periodic images, as resolve() takes them
      while (point[A] >= n) point[A] -= n;
      // One of this block's ghosts, no farther out, holds the prediction if a coarser leaf
      // contains it too.
      bool own = at[A] >= 0 && at[A] < bs + 2 * g && depth(at[A]) <= depth(i[A]);
      if (own) {
        resolver.leaf_containing(level, point);
        own = resolver.last().level < level;
      }
      if (own) {
        plan.local_src.push_back(static_cast<std::int32_t>(block_base(slot) + static_cast<std::size_t>(shape.index(at))));
        plan.local_src_page.push_back(page_of_[slot]);
      } else {
        const std::size_t cell = scratch_cell(at);
        if (scratch_at[cell] < 0) {
          scratch_at[cell] = static_cast<std::int32_t>(scratch.size());
          scratch.emplace_back(at, point);
        }
        const auto q = static_cast<std::size_t>(scratch_at[cell]);
        plan.local_src.push_back(static_cast<std::int32_t>(plan.scratch_start + scratch_points + static_cast<std::int64_t>(q)));
        plan.local_src_page.push_back(GhostPlan::kScratchPage);
      }
      plan.local_weight.push_back(plan.weights.index_of(line.weight[mu]));
    }
    plan.row_stage[row] = static_cast<std::uint8_t>(odd_axes - 1);
    return true;
  };

  for (std::size_t s = 0; s < local_keys_.size(); ++s) {
    const Key key = local_keys_[s];
    plan.block_curve.push_back(forest_.leaf_curve_index(first_leaf_ + s));
    if (const auto o = reusable(s)) {
      // Nothing of its rows is copied: group_ghost_rows takes its grouped entries from the
      // previous plan. The block and every leaf its rows read kept their pages, so they address
      // the same points, but for the block's scratch points, which move to where this plan's
      // scratch for it starts.
      const GhostPlan& old = *reused;
      std::copy_n(old.kind.begin() + static_cast<std::ptrdiff_t>(*o * block_volume_), block_volume_,
                  plan.kind.begin() + static_cast<std::ptrdiff_t>(s * block_volume_));
      for (auto d = old.block_dependency_begin[*o]; d < old.block_dependency_begin[*o + 1]; ++d)
        plan.block_dependencies.push_back(
            static_cast<std::int32_t>(slot_now[static_cast<std::size_t>(old.block_dependencies[static_cast<std::size_t>(d)])]));
      plan.block_has_remote.push_back(0);
      plan.block_rebuilt.push_back(0);
      plan.reused_from.push_back(static_cast<std::int32_t>(*o));
      scratch_points += old.block_scratch_begin[*o + 1] - old.block_scratch_begin[*o];
      plan.block_scratch_begin.push_back(static_cast<std::int32_t>(scratch_points));
      plan.block_row_begin.push_back(static_cast<std::int32_t>(plan.dest.size()));
      plan.block_dependency_begin.push_back(static_cast<std::int32_t>(plan.block_dependencies.size()));
      plan.block_segment_begin.push_back(static_cast<std::int32_t>(plan.segments.size()));
      continue;
    }
    found.clear();
    resolver.forget();
    const std::size_t remote_before = remote_pending.size();
    const auto c = key.coords();
    std::array<GlobalIndex64, Dim> points_along{};  // per axis, at the block's level
    for (int a = 0; a < Dim; ++a) points_along[static_cast<std::size_t>(a)] = resolver.points_along(a, key.level);
    // This block's scratch points (separable prolongation, GhostPlan): where they would sit in
    // its array (beyond it along one axis) and their global index.
    scratch.clear();
    std::size_t row = plan.dest.size();
    auto end_row = [&] {
      plan.local_begin[row + 1] = static_cast<std::int32_t>(plan.local_src.size());
      plan.remote_begin[row + 1] = static_cast<std::int32_t>(remote_pending.size());
      ++row;
    };
    // Per region around the block (3^Dim, by side along each axis: below, inside, above), the
    // same-level leaf of this rank there, or -1: its ghosts are copies from it (most ghosts),
    // found without a lookup per point.
    std::array<std::int64_t, Dim == 1 ? 3 : Dim == 2 ? 9 : 27> same_level{};
    std::size_t segment_points = 0;
    for (std::size_t r = 0; r < same_level.size(); ++r) {
      std::array<int, Dim> direction{};
      bool centre = true;
      for (std::size_t a = 0, rest = r; a < static_cast<std::size_t>(Dim); ++a, rest /= 3) {
        direction[a] = static_cast<int>(rest % 3) - 1;
        centre = centre && direction[a] == 0;
      }
      same_level[r] = -1;
      if (centre) continue;
      const auto beyond = forest_.shifted(key, direction);
      const auto leaf = beyond ? forest_.find(*beyond) : std::nullopt;
      if (!leaf || *leaf < first_leaf_ || *leaf >= first_leaf_ + local_keys_.size()) continue;
      same_level[r] = static_cast<std::int64_t>(*leaf - first_leaf_);
      found.push_back(*leaf);  // a leaf its rows read
      std::size_t region_points = 1;  // copied by segment (GhostPlan::segments), without rows
      for (int a = 0; a < Dim; ++a) region_points *= static_cast<std::size_t>(direction[static_cast<std::size_t>(a)] == 0 ? bs : g);
      segment_points += region_points;
    }
    // One row per other ghost point, in array order: the row lists are sized once and written
    // by index (a push_back per row and list was a tenth of a rebuild).
    const std::size_t first_row = row;
    const std::size_t ghost_rows = block_volume_ - interior_points_ - segment_points;
    plan.dest.resize(first_row + ghost_rows);
    plan.local_begin.resize(first_row + ghost_rows + 1);
    plan.remote_begin.resize(first_row + ghost_rows + 1);
    plan.remote_lead.resize(first_row + ghost_rows, 0);
    plan.row_stage.resize(first_row + ghost_rows, 0);
    // A ghost point outside the regions of same-level leaves of this rank (those are copied by
    // segment, below): outside the domain, injected from a finer leaf of this rank found by
    // lookup, or a weighted row (coarser leaves, other ranks).
    auto resolve_point = [&](std::size_t p, const Index& i) {
      bool outside = false;
      std::array<GlobalIndex64, Dim> idx{};
      for (int a = 0; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        const GlobalIndex64 n = points_along[au];
        GlobalIndex64 v = static_cast<GlobalIndex64>(c[au]) * bs + (i[au] - g);
        if (v < 0 || v >= n) {
          // A ghost reaches less than a block beyond the domain: one period at most.
          if (config_.periodic[au]) v += v < 0 ? n : -n;
          else outside = true;
        }
        idx[au] = v;
      }
      const std::size_t at = s * block_volume_ + p;  // in plan.kind, by slot
      plan.dest[row] = static_cast<std::int32_t>(block_base(s) + p);
      if (outside) {
        // Never read: derivatives use one-sided rows and prediction one-sided stencils there.
        plan.kind[at] = static_cast<std::uint8_t>(GhostKind::kOutsideDomain);
        end_row();
        return;
      }
      // The lookup leaves the containing leaf in last() (and remembered, so
      // resolve below finds it again at once).
      resolver.leaf_containing(key.level, idx);
      const int source_level = resolver.last().level;
      plan.kind[at] = static_cast<std::uint8_t>(source_level == key.level  ? GhostKind::kSameLevel
                                                : source_level > key.level ? GhostKind::kFromFiner
                                                                           : GhostKind::kFromCoarser);
      const std::size_t source = resolver.last().leaf;
      if (source_level >= key.level && source >= first_leaf_ && source < first_leaf_ + local_keys_.size()) {
        // A finer leaf of this rank (same-level ones are copied by segment): the one term
        // resolve() would give, its point injected (weight 1), without the term list.
        auto q = resolver.injected(key.level, idx);
        for (int& qa : q) qa += g;
        plan.local_src.push_back(static_cast<std::int32_t>(block_base(source - first_leaf_) + static_cast<std::size_t>(shape.index(q))));
        plan.local_src_page.push_back(page_of_[source - first_leaf_]);
        plan.local_weight.push_back(WeightTable::kOne);
        end_row();
        return;
      }
      if (source_level < key.level && add_separable_row(s, key.level, i, idx, points_along, row)) {
        end_row();
        return;
      }
      terms.clear();
      resolver.resolve(key.level, idx, 1.0, terms);
      add_terms(row);
      end_row();
    };
    // The ghosts in array order, line by line along axis 0, each line in its three segments
    // (below, inside and above the block along axis 0). A segment lies in one region: where
    // that region is a same-level leaf of this rank (most ghosts), its rows are copies of
    // consecutive points of that leaf, written as one run without a lookup or a coordinate per
    // point (the per-point path was most of a rebuild). Such a leaf exists only where the region
    // is inside the domain or periodic, and ghosts <= block size puts the whole region in it.
    const int line_length = shape.extent[0];
    const std::array<int, 4> segment_edge{0, g, g + bs, bs + 2 * g};
    Index i{};  // the line's coordinates along axes 1 .. Dim - 1 (i[0] set per point)
    for (std::size_t line = 0; line < block_volume_; line += static_cast<std::size_t>(line_length)) {
      std::size_t region_across = 0;  // the region's digits along axes 1 .. Dim - 1
      bool inside_across = true;
      for (int a = Dim - 1; a >= 1; --a) {
        const int x = i[static_cast<std::size_t>(a)];
        const int side = x < g ? 0 : x < g + bs ? 1 : 2;
        region_across = 3 * region_across + static_cast<std::size_t>(side);
        inside_across = inside_across && side == 1;
      }
      for (int side = 0; side < 3; ++side) {
        if (inside_across && side == 1) continue;  // the block's interior
        const int x0 = segment_edge[static_cast<std::size_t>(side)], x1 = segment_edge[static_cast<std::size_t>(side) + 1];
        const std::size_t region = 3 * region_across + static_cast<std::size_t>(side);
        if (const std::int64_t from = same_level[region]; from >= 0) {
          // The neighbour's points: one block's width back along each axis the region lies beyond.
          Index q = i;
          q[0] = x0;
          for (std::size_t a = 0, rest = region; a < static_cast<std::size_t>(Dim); ++a, rest /= 3)
            q[a] -= (static_cast<int>(rest % 3) - 1) * bs;
          const auto first_src = static_cast<std::int32_t>(static_cast<std::int64_t>(block_base(static_cast<std::size_t>(from))) + shape.index(q));
          const auto first_dest = static_cast<std::int32_t>(block_base(s) + line) + x0;
          // kind: kSameLevel, as plan.kind starts
          plan.segments.push_back({first_dest, first_src, x1 - x0, page_of_[static_cast<std::size_t>(from)]});
          continue;
        }
        for (int x = x0; x < x1; ++x) {
          i[0] = x;
          resolve_point(line + static_cast<std::size_t>(x), i);
        }
      }
      i[0] = 0;
      for (std::size_t a = 1; a < static_cast<std::size_t>(Dim); ++a) {
        if (++i[a] < shape.extent[a]) break;
        i[a] = 0;
      }
    }
    if (row != first_row + ghost_rows) throw std::logic_error("AdaptiveGrid: ghost rows miscounted");
    // The scratch points' rows: the prediction along the remaining odd axes, whichever leaf
    // contains the point.
    const std::size_t scratch_rows = scratch.size();
    plan.dest.resize(row + scratch_rows);
    plan.local_begin.resize(row + scratch_rows + 1);
    plan.remote_begin.resize(row + scratch_rows + 1);
    plan.remote_lead.resize(row + scratch_rows, 0);
    plan.row_stage.resize(row + scratch_rows, 0);
    for (std::size_t q = 0; q < scratch_rows; ++q) {
      plan.dest[row] = static_cast<std::int32_t>(plan.scratch_start + scratch_points + static_cast<std::int64_t>(q));
      terms.clear();
      resolver.predict(key.level, scratch[q].second, 1.0, terms);
      add_terms(row);
      end_row();
    }
    scratch_points += static_cast<std::int64_t>(scratch_rows);
    plan.block_scratch_begin.push_back(static_cast<std::int32_t>(scratch_points));
    for (const auto& entry : scratch) scratch_at[scratch_cell(entry.first)] = -1;
    std::sort(found.begin(), found.end());
    found.erase(std::unique(found.begin(), found.end()), found.end());
    for (const std::size_t leaf : found)
      plan.block_dependencies.push_back(leaf >= first_leaf_ && leaf < first_leaf_ + local_keys_.size()
                                            ? static_cast<std::int32_t>(leaf - first_leaf_)
                                            : -1);
    plan.block_has_remote.push_back(remote_pending.size() > remote_before ? 1 : 0);
    plan.block_rebuilt.push_back(1);
    plan.reused_from.push_back(-1);
    plan.block_row_begin.push_back(static_cast<std::int32_t>(plan.dest.size()));
    plan.block_dependency_begin.push_back(static_cast<std::int32_t>(plan.block_dependencies.size()));
    plan.block_segment_begin.push_back(static_cast<std::int32_t>(plan.segments.size()));
  }

  refuse_beyond_32_bits(plan.scratch_start + scratch_points);
  // Exchange the request lists once; the receivers translate them to local offsets.
  const auto P = static_cast<std::size_t>(ranks_);
  std::vector<int> recv_counts(P), send_counts(P), recv_first(P + 1, 0), send_first(P + 1, 0);
  for (std::size_t r = 0; r < P; ++r) recv_counts[r] = static_cast<int>(wanted[r].size());
  MPI_Alltoall(recv_counts.data(), 1, MPI_INT, send_counts.data(), 1, MPI_INT, comm_);
  for (std::size_t r = 0; r < P; ++r) {
    recv_first[r + 1] = recv_first[r] + recv_counts[r];
    send_first[r + 1] = send_first[r] + send_counts[r];
  }
  std::vector<std::int64_t> request(2 * static_cast<std::size_t>(recv_first[P]));
  for (std::size_t r = 0; r < P; ++r)
    for (const auto& [what, position] : wanted[r]) {
      const auto at = 2 * static_cast<std::size_t>(recv_first[r] + position);
      request[at] = static_cast<std::int64_t>(what.first);
      request[at + 1] = what.second;
    }
  std::vector<std::int64_t> asked(2 * static_cast<std::size_t>(send_first[P]));
  std::vector<int> rc2(P), rf2(P), sc2(P), sf2(P);
  for (std::size_t r = 0; r < P; ++r) {
    rc2[r] = 2 * recv_counts[r];
    rf2[r] = 2 * recv_first[r];
    sc2[r] = 2 * send_counts[r];
    sf2[r] = 2 * send_first[r];
  }
  MPI_Alltoallv(request.data(), rc2.data(), rf2.data(), MPI_INT64_T, asked.data(), sc2.data(), sf2.data(),
                MPI_INT64_T, comm_);
  for (std::size_t k = 0; k < asked.size(); k += 2) {
    const auto leaf = static_cast<std::size_t>(asked[k]);
    std::array<int, Dim> q{};
    std::int64_t rest = asked[k + 1];
    for (int a = 0; a < Dim; ++a) {
      q[static_cast<std::size_t>(a)] = static_cast<int>(rest % bs) + g;
      rest /= bs;
    }
    plan.send_src.push_back(static_cast<std::int64_t>(block_base(leaf - first_leaf_)) + shape.index(q));
  }
  for (std::size_t r = 0; r < P; ++r) {
    if (recv_counts[r] > 0) {
      plan.recv_rank.push_back(static_cast<int>(r));
      plan.recv_first.push_back(recv_first[r]);
      plan.recv_count.push_back(recv_counts[r]);
    }
    if (send_counts[r] > 0) {
      plan.send_rank.push_back(static_cast<int>(r));
      plan.send_first.push_back(send_first[r]);
      plan.send_count.push_back(send_counts[r]);
    }
  }
  const int F = fields();
  plan.remote_src.reserve(remote_pending.size());
  for (const auto& [who, position] : remote_pending)
    plan.remote_src.push_back((recv_first[static_cast<std::size_t>(who)] + position) * F);
  plan.send_buffer.assign(plan.send_src.size() * static_cast<std::size_t>(F), 0.0);
  plan.recv_buffer.assign(static_cast<std::size_t>(recv_first[P]) * static_cast<std::size_t>(F), 0.0);
  plan.requests.resize(plan.recv_rank.size() + plan.send_rank.size());
  group_ghost_rows(plan, reused);
  spare_plan_ = std::move(previous);
  // The scratch points sit after the blocks in every field array.
  for (auto& field : data_) field.resize(static_cast<std::size_t>(plan.scratch_start + scratch_points), 0.0);
}

template <int Dim>
void AdaptiveGrid<Dim>::group_ghost_rows(GhostPlan& plan, const GhostPlan* previous) const {
  for (std::size_t list = 0; list < plan.copy_runs.size(); ++list) {
    plan.copy_runs[list].clear();
    plan.remote_rows[list].clear();
    for (auto& rows : plan.packed[list]) rows.clear();
  }
  for (auto& list : plan.block_group_begin)
    for (auto& begin : list) begin.clear();
  // The blocks reused from the previous plan have no rows: their entries are its grouping's,
  // which build_ghost_plan reuses only if it was made for this reach.
  if (previous && previous->grouped_reach != stencil_reach_)
    throw std::logic_error("AdaptiveGrid: ghost rows reused from a plan grouped for another stencil reach");
  plan.grouped_reach = stencil_reach_;
  // Per array point: its group (0 within the stencil reach, interior points unused).
  const auto shape = layout_.shape();
  const int g = layout_.ghosts, bs = config_.block_size;
  std::vector<std::uint8_t> group_of(block_volume_, 0);
  for (std::size_t p = 0; p < block_volume_; ++p) {
    const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
    int outside = 0, deepest = 0;
    for (int a = 0; a < Dim; ++a) {
      const int depth = ghost_depth(i[static_cast<std::size_t>(a)], bs, g);
      outside += depth > 0 ? 1 : 0;
      deepest = std::max(deepest, depth);
    }
    group_of[p] = outside == 0 || deepest <= stencil_reach_[static_cast<std::size_t>(outside - 1)] ? 0 : 1;
  }
  // Per list, the copy run the block's rows are extending (kept here, not in the list, so that
  // each row's test does not wait on the last row's store), appended when it ends: runs stay
  // within a block.
  std::array<typename GhostPlan::CopyRun, 3> open_run{};
  std::array<bool, 3> run_open{};
  // Per list, the block's rectangles so far (GhostPlan::CopyRun), appended when the block is
  // done: each run closed joins the one it continues (same length, same source block, the next
  // row at the same strides), else starts one. In array order a row's left-face run and
  // right-face run alternate, one rectangle each. Only the last few rectangles are tried (a 3D
  // block's face is a rectangle per plane, and its rectangles many): the search stays short.
  // The order of copies does not matter (their sources are interior points).
  std::array<std::vector<typename GhostPlan::CopyRun>, 3> open_rects;
  constexpr std::ptrdiff_t kRectsTried = 4;
  auto append_run = [&](std::size_t l, const typename GhostPlan::CopyRun& run) {
    const auto tried = std::min<std::ptrdiff_t>(kRectsTried, std::ssize(open_rects[l]));
    for (auto rect = open_rects[l].rbegin(); rect != open_rects[l].rbegin() + tried; ++rect) {
      if (rect->length != run.length || rect->src_page != run.src_page) continue;
      if (rect->rows == 1 && run.dest - rect->dest >= run.length) {
        rect->dest_stride = run.dest - rect->dest;
        rect->src_stride = run.src - rect->src;
        rect->rows = 2;
        return;
      }
      if (rect->rows > 1 && run.dest == rect->dest + rect->rows * rect->dest_stride &&
          run.src == rect->src + rect->rows * rect->src_stride) {
        ++rect->rows;
        return;
      }
    }
    open_rects[l].push_back(run);
  };
  auto close_runs = [&] {
    for (std::size_t l = 0; l < open_run.size(); ++l) {
      if (run_open[l]) append_run(l, open_run[l]);
      plan.copy_runs[l].insert(plan.copy_runs[l].end(), open_rects[l].begin(), open_rects[l].end());
      open_rects[l].clear();
    }
    run_open.fill(false);
  };
  // Into list `list`, and (for a block built afresh) into kRebuiltRows too: sorted once for both.
  const auto into = [](std::size_t list, bool rebuilt, auto&& append) {
    append(list);
    if (rebuilt) append(kRebuiltRows);
  };
  // `length` consecutive points copied from src on: they extend the open copy run where they
  // continue it, else start the next.
  auto add_copies = [&](std::size_t list, bool rebuilt, std::int32_t dest, std::int32_t src, std::int32_t length,
                        std::int32_t src_page) {
    into(list, rebuilt, [&](std::size_t l) {
      auto& run = open_run[l];
      if (run_open[l] && dest == run.dest + run.length && src == run.src + run.length) {
        run.length += length;
        return;
      }
      if (run_open[l]) append_run(l, run);
      run = {dest, src, length, src_page};
      run_open[l] = true;
    });
  };
  // Row k, all its terms local, to the packed rows of a kind (0: sums, 1 and 2: the stages of
  // those summed from other ghost rows).
  auto pack = [&](std::size_t l, std::size_t kind, std::size_t k) {
    const auto t0 = static_cast<std::size_t>(plan.local_begin[k]), terms = static_cast<std::size_t>(plan.local_begin[k + 1]) - t0;
    plan.packed[l][kind].append(plan.dest[k], std::span(plan.local_src).subspan(t0, terms),
                                std::span(plan.local_weight).subspan(t0, terms));
  };
  // Row k.
  auto add = [&](std::size_t list, std::size_t k, bool rebuilt) {
    const auto row = static_cast<std::int32_t>(k);
    if (plan.row_stage[k] > 0) {
      into(list, rebuilt, [&](std::size_t l) { pack(l, plan.row_stage[k], k); });
      return;
    }
    // A row with remote terms is summed whole once its messages are in (fill_ghost_lists), its
    // local terms with them: not in the local pass as well.
    if (plan.remote_begin[k + 1] != plan.remote_begin[k]) {
      into(list, rebuilt, [&](std::size_t l) { plan.remote_rows[l].push_back(row); });
      return;
    }
    if (!plan.is_copy(k)) {
      into(list, rebuilt, [&](std::size_t l) { pack(l, 0, k); });
      return;
    }
    const auto t = static_cast<std::size_t>(plan.local_begin[k]);
    add_copies(list, rebuilt, plan.dest[k], plan.local_src[t], 1, plan.local_src_page[t]);
  };
  auto mark_block_begin = [&] {
    for (std::size_t list = 0; list < plan.block_group_begin.size(); ++list) {
      auto& begin = plan.block_group_begin[list];
      begin[0].push_back(static_cast<std::int32_t>(plan.copy_runs[list].size()));
      for (std::size_t kind = 0; kind < 3; ++kind)
        begin[GhostPlan::kPackedGroup[kind]].push_back(static_cast<std::int32_t>(plan.packed[list][kind].rows()));
      begin[2].push_back(static_cast<std::int32_t>(plan.remote_rows[list].size()));
    }
  };
  // The entries in lists 0 and 1 of `count` reused blocks from slot s on, which were
  // consecutive in the old plan from slot o on, taken from it as one range per list and kind
  // (a range per block was most of a rebuild around a moving body): their copies as they were
  // (they read and write block points, addressed by pages, which the blocks and their sources
  // kept); their packed rows with only their references to their own scratch points moved (no
  // other block's rows read them), which is one shift for them all (they hold the same scratch
  // points in both plans). They have no remote rows and none in list 2.
  auto take_old_entries = [&](std::size_t s, std::size_t o, std::size_t count) {
    const GhostPlan& old = *previous;
    const std::int64_t scratch_shift = plan.scratch_of(s) - old.scratch_of(o);
    for (std::size_t list = 0; list < plan.block_group_begin.size(); ++list) {
      const auto& before = old.block_group_begin[list];
      auto& now = plan.block_group_begin[list];
      // Each block's entries begin where the old ones did, moved with the first.
      auto begins = [&](std::size_t group, std::size_t size_now) {
        const auto shift = static_cast<std::int32_t>(size_now) - before[group][o];
        std::transform(before[group].begin() + static_cast<std::ptrdiff_t>(o), before[group].begin() + static_cast<std::ptrdiff_t>(o + count),
                       std::back_inserter(now[group]), [shift](std::int32_t first) { return first + shift; });
        return std::pair(before[group][o], before[group][o + count]);
      };
      const auto [c0, c1] = begins(0, plan.copy_runs[list].size());
      plan.copy_runs[list].insert(plan.copy_runs[list].end(), old.copy_runs[list].begin() + c0, old.copy_runs[list].begin() + c1);
      now[2].insert(now[2].end(), count, static_cast<std::int32_t>(plan.remote_rows[list].size()));
      for (std::size_t kind = 0; kind < 3; ++kind) {
        const auto& from = old.packed[list][kind];
        auto& to = plan.packed[list][kind];
        const auto [r0, r1] = begins(GhostPlan::kPackedGroup[kind], to.rows());
        const auto t0 = from.begin[static_cast<std::size_t>(r0)], t1 = from.begin[static_cast<std::size_t>(r1)];
        const std::size_t first_dest = to.dest.size(), first_src = to.src.size();
        to.dest.insert(to.dest.end(), from.dest.begin() + r0, from.dest.begin() + r1);
        to.src.insert(to.src.end(), from.src.begin() + t0, from.src.begin() + t1);
        to.weight.insert(to.weight.end(), from.weight.begin() + t0, from.weight.begin() + t1);
        const auto term_shift = static_cast<std::int32_t>(first_src) - t0;
        std::transform(from.begin.begin() + r0 + 1, from.begin.begin() + r1 + 1, std::back_inserter(to.begin),
                       [term_shift](std::int32_t first_term) { return first_term + term_shift; });
        shift_scratch_points(std::span(to.dest).subspan(first_dest), old.scratch_start, scratch_shift);
        shift_scratch_points(std::span(to.src).subspan(first_src), old.scratch_start, scratch_shift);
      }
    }
  };
  // A scratch point is filled with the first group that reads it.
  std::vector<std::uint8_t> scratch_group;
  const std::size_t blocks = plan.block_row_begin.size() - 1;
  for (std::size_t s = 0; s < blocks; ++s) {
    if (const std::int32_t o = plan.reused_from[s]; o >= 0) {
      std::size_t last = s;  // the run of blocks reused from consecutive old slots
      while (last + 1 < blocks && plan.reused_from[last + 1] == o + static_cast<std::int32_t>(last + 1 - s)) ++last;
      take_old_entries(s, static_cast<std::size_t>(o), last + 1 - s);
      s = last;
      continue;
    }
    mark_block_begin();
    const auto base = static_cast<std::int64_t>(block_base(s));
    const bool rebuilt = plan.block_rebuilt[s] != 0;
    const auto first_row = static_cast<std::size_t>(plan.block_row_begin[s]);
    const auto end_row = static_cast<std::size_t>(plan.block_row_begin[s + 1]);
    const std::int64_t scratch_base = plan.scratch_start + plan.block_scratch_begin[s];
    scratch_group.assign(static_cast<std::size_t>(plan.block_scratch_begin[s + 1] - plan.block_scratch_begin[s]), 1);
    for (std::size_t k = first_row; k < end_row; ++k) {
      if (plan.row_stage[k] == 0) continue;
      const std::uint8_t group = group_of[static_cast<std::size_t>(plan.dest[k] - base)];
      for (auto t = static_cast<std::size_t>(plan.local_begin[k]); t < static_cast<std::size_t>(plan.local_begin[k + 1]); ++t)
        if (plan.local_src_page[t] == GhostPlan::kScratchPage) {
          auto& to = scratch_group[static_cast<std::size_t>(plan.local_src[t] - scratch_base)];
          to = std::min(to, group);
        }
    }
    // The block's segments, each split where its points change group (along axis 0 a face's
    // ghost layers lie at different depths).
    for (auto e = plan.block_segment_begin[s]; e < plan.block_segment_begin[s + 1]; ++e) {
      const auto& segment = plan.segments[static_cast<std::size_t>(e)];
      const std::uint8_t* group = group_of.data() + (segment.dest - base);
      for (std::int32_t k = 0; k < segment.length;) {
        std::int32_t end = k + 1;
        while (end < segment.length && group[end] == group[k]) ++end;
        add_copies(group[k], rebuilt, segment.dest + k, segment.src + k, end - k, segment.src_page);
        k = end;
      }
    }
    for (std::size_t k = first_row; k < end_row; ++k) {
      const bool in_scratch = plan.dest[k] >= plan.scratch_start;
      add(in_scratch ? scratch_group[static_cast<std::size_t>(plan.dest[k] - scratch_base)]
                     : group_of[static_cast<std::size_t>(plan.dest[k] - base)],
          k, rebuilt);
    }
    close_runs();
  }
  mark_block_begin();
  order_fill_while_writing(plan);
}

template <int Dim>
void AdaptiveGrid<Dim>::order_fill_while_writing(GhostPlan& plan) const {
  // A block's rows read the interiors of its dependencies (the leaves they were resolved from)
  // and its own ghosts and scratch points: it can be filled once the last of them is written.
  const std::size_t n = plan.block_row_begin.size() - 1;
  std::vector<std::int32_t> when(n, -1);
  plan.fill_after_messages.clear();
  for (std::size_t s = 0; s < n; ++s) {
    auto last = static_cast<std::int32_t>(s);
    bool local = plan.block_has_remote[s] == 0;
    for (auto d = plan.block_dependency_begin[s]; d < plan.block_dependency_begin[s + 1] && local; ++d) {
      const std::int32_t read = plan.block_dependencies[static_cast<std::size_t>(d)];
      local = read >= 0;
      last = std::max(last, read);
    }
    if (local) when[s] = last;
    else plan.fill_after_messages.push_back(static_cast<std::int32_t>(s));
  }
  bucket_by_time(std::span<const std::int32_t>(when), n, [](std::size_t s) { return static_cast<std::int32_t>(s); },
                 plan.fill_when_begin, plan.fill_when_written);
  plan.copies_and_sums_ordered = false;
}

template <int Dim>
void AdaptiveGrid<Dim>::order_copies_and_sums_while_writing(GhostPlan& plan) const {
  // Each copy rectangle and sum of a block filled while writing, after the later of its
  // destination and the blocks it reads is written: never after the destination's other rows
  // (what it reads is among the blocks they wait for).
  const std::size_t n = plan.fill_when_begin.size() - 1;
  std::vector<std::int32_t> when(n, -1);  // when each block is filled, -1 after the messages
  for (std::size_t t = 0; t < n; ++t)
    for (auto k = plan.fill_when_begin[t]; k < plan.fill_when_begin[t + 1]; ++k)
      when[static_cast<std::size_t>(plan.fill_when_written[static_cast<std::size_t>(k)])] = static_cast<std::int32_t>(t);
  std::vector<std::int32_t> slot_of_page(pages_, -1);
  for (std::size_t s = 0; s < n; ++s) slot_of_page[static_cast<std::size_t>(page_of_[s])] = static_cast<std::int32_t>(s);
  // Per entry (copy rectangle or sum) of the blocks filled while writing: the later of its
  // destination and the last block it reads (latest_read(k)), -1 for the others.
  auto entry_times = [&](const std::vector<std::int32_t>& begin, std::size_t entries, auto&& latest_read) {
    std::vector<std::int32_t> time(entries, -1);
    for (std::size_t s = 0; s < n; ++s)
      for (auto k = begin[s]; k < begin[s + 1] && when[s] >= 0; ++k) {
        const std::int32_t t = std::max(static_cast<std::int32_t>(s), latest_read(static_cast<std::size_t>(k)));
        if (t > when[s]) throw std::logic_error("AdaptiveGrid: a ghost row reads a block its destination does not wait for");
        time[static_cast<std::size_t>(k)] = t;
      }
    return time;
  };
  const auto& runs = plan.copy_runs[0];
  const auto copy_time = entry_times(plan.block_group_begin[0][0], runs.size(), [&](std::size_t k) {
    return slot_of_page[static_cast<std::size_t>(runs[k].src_page)];
  });
  bucket_by_time(std::span<const std::int32_t>(copy_time), n, [&](std::size_t k) { return runs[k]; }, plan.copy_when_begin,
                 plan.copy_when);
  // The sums: their terms read interior points only (block pages, never scratch points).
  const auto& sums = plan.packed[0][0];
  const auto volume = static_cast<std::int64_t>(block_volume_);
  const auto sum_time = entry_times(plan.block_group_begin[0][GhostPlan::kPackedGroup[0]], sums.rows(), [&](std::size_t k) {
    std::int32_t latest = -1;
    for (auto term = static_cast<std::size_t>(sums.begin[k]); term < static_cast<std::size_t>(sums.begin[k + 1]); ++term) {
      const auto page = static_cast<std::size_t>(sums.src[term] / volume);
      if (page >= slot_of_page.size() || slot_of_page[page] < 0)
        throw std::logic_error("AdaptiveGrid: a sum reads a scratch point or a free page");
      latest = std::max(latest, slot_of_page[page]);
    }
    return latest;
  });
  std::vector<std::int32_t> order;
  bucket_by_time(std::span<const std::int32_t>(sum_time), n, [](std::size_t k) { return static_cast<std::int32_t>(k); },
                 plan.sum_when_begin, order);
  plan.sum_when.clear();
  for (const std::int32_t k : order) {
    const auto row = static_cast<std::size_t>(k);
    const auto t0 = static_cast<std::size_t>(sums.begin[row]), terms = static_cast<std::size_t>(sums.begin[row + 1]) - t0;
    plan.sum_when.append(sums.dest[row], std::span(sums.src).subspan(t0, terms), std::span(sums.weight).subspan(t0, terms));
  }
  plan.copies_and_sums_ordered = true;
}

template <int Dim>
void AdaptiveGrid<Dim>::set_stencil_reach(int along_axis, int across_two_axes) {
  if (along_axis < 0 || along_axis > layout_.ghosts || across_two_axes < 0 || across_two_axes > along_axis)
    throw std::invalid_argument("AdaptiveGrid::set_stencil_reach: need 0 <= corner reach <= axis reach <= ghost layers");
  const std::array<int, 3> reach{along_axis, across_two_axes, 0};
  if (stencil_reach_ == reach) return;
  stencil_reach_ = reach;
  // Grouped afresh from every block's rows, which only a plan built afresh holds (blocks reused
  // by an adaptation keep their grouped entries alone).
  if (plan_) build_ghost_plan();
}

namespace {

/// Packed rows first .. last of local terms (GhostPlan::PackedRows) for kFields consecutive field
/// arrays at once.
/// Each field's sum is accumulated from 0 in term order however many fields go together, so the
/// values are bitwise the same; with the fields side by side a row's indices and weights are
/// read once, and its kFields sums are independent chains (a lone sum waits on each add).
template <int kFields, typename Plan>
void sum_local_rows(const Plan& plan, const typename Plan::PackedRows& rows, std::size_t first, std::size_t last,
                    std::vector<double>* fields) {
  std::array<double*, kFields> u{};
  for (std::size_t f = 0; f < kFields; ++f) u[f] = fields[f].data();
  const auto* begin = rows.begin.data();
  const auto* src = rows.src.data();
  const auto* weight_of = rows.weight.data();
  const double* weights = plan.weights.data();
  for (std::size_t k = first; k < last; ++k) {
    std::array<double, kFields> v{};
    for (auto t = static_cast<std::size_t>(begin[k]); t < static_cast<std::size_t>(begin[k + 1]); ++t) {
      const double weight = weights[weight_of[t]];
      for (std::size_t f = 0; f < kFields; ++f) v[f] += weight * u[f][src[t]];
    }
    for (std::size_t f = 0; f < kFields; ++f) u[f][rows.dest[k]] = v[f];
  }
}

/// The local rows of a ghost plan's list (copies and sums) for kFields consecutive field arrays.
/// Their sources are interior points, so the order of the rows does not matter. A copy is
/// written 0 + u, what the weighted sum gives (-0 becomes +0).
template <int kFields, typename Run>
void copy_runs(std::span<const Run> runs, std::vector<double>* fields) {
  // Rows of one or two values (the side faces' ghosts, injection from finer leaves) without
  // an inner loop; the rectangle's length is one branch for all its rows and fields.
  auto copy_rows = [&](const Run& run, auto copy_row) {
    for (std::size_t f = 0; f < kFields; ++f) {
      double* to = fields[f].data() + run.dest;
      const double* from = fields[f].data() + run.src;
      for (std::int32_t r = 0; r < run.rows; ++r, to += run.dest_stride, from += run.src_stride) copy_row(to, from);
    }
  };
  for (const auto& run : runs) {
    if (run.length == 2)
      copy_rows(run, [](double* to, const double* from) {
        to[0] = 0.0 + from[0];
        to[1] = 0.0 + from[1];
      });
    else if (run.length == 1)
      copy_rows(run, [](double* to, const double* from) { to[0] = 0.0 + from[0]; });
    else
      copy_rows(run, [length = run.length](double* to, const double* from) {
        for (std::int32_t k = 0; k < length; ++k) to[k] = 0.0 + from[k];
      });
  }
}

/// Copy runs, then local sums (packed rows first .. last), for kFields consecutive field
/// arrays: a whole list's, or one block's entries of it.
template <int kFields, typename Plan>
void fill_local_terms(const Plan& plan, std::span<const typename Plan::CopyRun> runs,
                      const typename Plan::PackedRows& sums, std::size_t first, std::size_t last,
                      std::vector<double>* fields) {
  copy_runs<kFields>(runs, fields);
  sum_local_rows<kFields>(plan, sums, first, last, fields);
}

/// The rows with remote terms, all their terms in their order (the leading remote ones, the
/// local ones, the others): the same additions one rank makes.
template <typename Plan>
void sum_remote_rows(const Plan& plan, std::span<const std::int32_t> rows, std::vector<std::vector<double>>& data) {
  for (std::size_t f = 0; f < data.size(); ++f) {
    double* u = data[f].data();
    const double* received = plan.recv_buffer.data() + f;
    auto add_remote = [&](double& v, std::int32_t from, std::int32_t to) {
      for (auto t = static_cast<std::size_t>(from); t < static_cast<std::size_t>(to); ++t)
        v += plan.remote_w[t] * received[plan.remote_src[t]];
    };
    for (const std::int32_t row : rows) {
      const auto k = static_cast<std::size_t>(row);
      const std::int32_t lead = plan.remote_begin[k] + plan.remote_lead[k];
      double v = 0;
      add_remote(v, plan.remote_begin[k], lead);
      for (auto t = static_cast<std::size_t>(plan.local_begin[k]); t < static_cast<std::size_t>(plan.local_begin[k + 1]); ++t)
        v += plan.weights[plan.local_weight[t]] * u[plan.local_src[t]];
      add_remote(v, lead, plan.remote_begin[k + 1]);
      u[plan.dest[k]] = v;
    }
  }
}

}  // namespace

template <int Dim>
void AdaptiveGrid<Dim>::fill_local_ghosts(const GhostPlan& plan, std::size_t list) {
  for_field_groups(data_, [&](auto group, std::vector<double>* fields) {
    fill_local_terms<decltype(group)::value>(plan, std::span(plan.copy_runs[list]), plan.packed[list][0], 0,
                                             plan.packed[list][0].rows(), fields);
  });
}

template <int Dim>
void AdaptiveGrid<Dim>::fill_separable_ghosts(const GhostPlan& plan, std::initializer_list<std::size_t> lists) {
  for (std::size_t stage = 0; stage < 2; ++stage)
    for (const std::size_t list : lists) {
      const auto& rows = plan.packed[list][1 + stage];
      if (rows.rows() == 0) continue;
      for_field_groups(data_, [&](auto group, std::vector<double>* fields) {
        sum_local_rows<decltype(group)::value>(plan, rows, 0, rows.rows(), fields);
      });
    }
}

template <int Dim>
void AdaptiveGrid<Dim>::fill_ghosts() {
  fill_ghost_lists({0, 1});
}

template <int Dim>
void AdaptiveGrid<Dim>::fill_stencil_ghosts() {
  fill_ghost_lists({0});
}

template <int Dim>
std::size_t AdaptiveGrid<Dim>::receive_ghost_values(GhostPlan& plan) {
  const int F = fields();
  std::size_t requests = 0;
  for (std::size_t k = 0; k < plan.recv_rank.size(); ++k)
    MPI_Irecv(plan.recv_buffer.data() + static_cast<std::size_t>(plan.recv_first[k]) * static_cast<std::size_t>(F), plan.recv_count[k] * F,
              MPI_DOUBLE, plan.recv_rank[k], 71, comm_, &plan.requests[requests++]);
  return requests;
}

template <int Dim>
void AdaptiveGrid<Dim>::send_ghost_values(GhostPlan& plan, std::size_t& requests) {
  const int F = fields();
  const auto Fu = static_cast<std::size_t>(F);
  for (std::size_t k = 0; k < plan.send_src.size(); ++k)
    for (std::size_t f = 0; f < Fu; ++f)
      plan.send_buffer[k * Fu + f] = data_[f][static_cast<std::size_t>(plan.send_src[k])];
  for (std::size_t k = 0; k < plan.send_rank.size(); ++k)
    MPI_Isend(plan.send_buffer.data() + static_cast<std::size_t>(plan.send_first[k]) * Fu, plan.send_count[k] * F,
              MPI_DOUBLE, plan.send_rank[k], 71, comm_, &plan.requests[requests++]);
}

template <int Dim>
void AdaptiveGrid<Dim>::fill_ghost_lists(std::initializer_list<std::size_t> lists) {
  GhostPlan& plan = *plan_;
  std::size_t nreq = receive_ghost_values(plan);
  send_ghost_values(plan, nreq);
  // Local contributions while the messages travel (every peer's message is whole: the lists
  // share most of their remote points).
  for (const std::size_t list : lists) fill_local_ghosts(plan, list);
  MPI_Waitall(static_cast<int>(nreq), plan.requests.data(), MPI_STATUSES_IGNORE);
  if (!plan.remote_src.empty())
    for (const std::size_t list : lists) sum_remote_rows(plan, std::span(plan.remote_rows[list]), data_);
  // Last, the rows summed from the ghosts and scratch points filled above.
  fill_separable_ghosts(plan, lists);
}

template <int Dim>
double AdaptiveGrid<Dim>::write_and_fill_stencil_ghosts(const std::function<void(std::size_t)>& write_block) {
  GhostPlan& plan = *plan_;
  const std::size_t n = local_blocks();
  // Block s's entries of list 0 of one kind (copy runs, sums, remote rows, derived stages 1, 2).
  auto entries = [&](const auto& list, std::size_t kind, std::size_t s) {
    const auto& begin = plan.block_group_begin[0][kind];
    return std::span(list).subspan(static_cast<std::size_t>(begin[s]), static_cast<std::size_t>(begin[s + 1] - begin[s]));
  };
  // Block s's range of list 0's packed rows of a kind (sums, derived stages 1, 2).
  auto packed_range = [&](std::size_t kind, std::size_t s) {
    const auto& begin = plan.block_group_begin[0][GhostPlan::kPackedGroup[kind]];
    return std::pair(static_cast<std::size_t>(begin[s]), static_cast<std::size_t>(begin[s + 1]));
  };
  // A block's rows in the order fill_ghost_lists takes them: its local rows, then (after the
  // messages) its remote rows, then those summed from its own ghosts, stage by stage.
  // (The copies and sums of a block filled while writing are made apart: plan.copy_when,
  // plan.sum_when.)
  auto fill_block = [&](std::size_t s, bool remote) {
    if (remote) {
      const auto [first_sum, last_sum] = packed_range(0, s);
      for_field_groups(data_, [&](auto group, std::vector<double>* fields) {
        fill_local_terms<decltype(group)::value>(plan, entries(plan.copy_runs[0], 0, s), plan.packed[0][0], first_sum,
                                                 last_sum, fields);
      });
      sum_remote_rows(plan, entries(plan.remote_rows[0], 2, s), data_);
    }
    for (std::size_t stage = 0; stage < 2; ++stage) {
      const auto [first, last] = packed_range(1 + stage, s);
      if (first == last) continue;
      for_field_groups(data_, [&](auto group, std::vector<double>* fields) {
        sum_local_rows<decltype(group)::value>(plan, plan.packed[0][1 + stage], first, last, fields);
      });
    }
  };
  if (!plan.copies_and_sums_ordered) order_copies_and_sums_while_writing(plan);
  std::size_t nreq = receive_ghost_values(plan);
  // Each block's ghosts right after the last block they read is written, while that block and
  // most of the others are still in cache; its copy rectangles sooner, as soon as their source
  // and the block are both written. The writing is timed apart from the filling on the
  // cycle counter where there is one (a clock read per block would cost a few percent).
  const Stopwatch whole;
  std::uint64_t writing = 0;
  const std::uint64_t start = cycle_count();
  for (std::size_t t = 0; t < n; ++t) {
    const std::uint64_t before = cycle_count();
    write_block(t);
    writing += cycle_count() - before;
    const auto first_copy = static_cast<std::size_t>(plan.copy_when_begin[t]);
    const auto copies = std::span<const typename GhostPlan::CopyRun>(plan.copy_when)
                            .subspan(first_copy, static_cast<std::size_t>(plan.copy_when_begin[t + 1]) - first_copy);
    for_field_groups(data_, [&](auto group, std::vector<double>* fields) {
      fill_local_terms<decltype(group)::value>(plan, copies, plan.sum_when, static_cast<std::size_t>(plan.sum_when_begin[t]),
                                               static_cast<std::size_t>(plan.sum_when_begin[t + 1]), fields);
    });
    for (auto k = plan.fill_when_begin[t]; k < plan.fill_when_begin[t + 1]; ++k)
      fill_block(static_cast<std::size_t>(plan.fill_when_written[static_cast<std::size_t>(k)]), false);
  }
  const std::uint64_t writing_and_filling = cycle_count() - start;
  const double write_seconds =
      writing_and_filling > 0 ? whole.seconds() * static_cast<double>(writing) / static_cast<double>(writing_and_filling) : 0.0;
  send_ghost_values(plan, nreq);  // every block written
  MPI_Waitall(static_cast<int>(nreq), plan.requests.data(), MPI_STATUSES_IGNORE);
  for (const std::int32_t s : plan.fill_after_messages) fill_block(static_cast<std::size_t>(s), true);
  return write_seconds;
}

template <int Dim>
GhostKind AdaptiveGrid<Dim>::ghost_kind(std::size_t slot, std::ptrdiff_t array_index) const {
  return static_cast<GhostKind>(plan_->kind[slot * block_volume_ + static_cast<std::size_t>(array_index)]);
}

template <int Dim>
std::array<std::int64_t, 4> AdaptiveGrid<Dim>::ghost_counts() const {
  // Every point of a block's array is a ghost of some kind but its interior points, which are
  // marked kSameLevel.
  std::array<std::int64_t, 4> n{};
  for (const std::uint8_t kind : plan_->kind) ++n[kind];
  n[static_cast<std::size_t>(GhostKind::kSameLevel)] -= static_cast<std::int64_t>(local_blocks() * interior_points_);
  return n;
}

template <int Dim>
GhostPlanStats AdaptiveGrid<Dim>::ghost_plan_stats() const {
  // From the grouped rows, which every block has (a block reused by an adaptation has no rows):
  // lists 0 and 1 hold each ghost and scratch point once.
  const GhostPlan& plan = *plan_;
  GhostPlanStats stats;
  auto weighted_row = [&](std::int64_t dest, int terms) {
    ++stats.rows;
    stats.scratch_points += dest >= plan.scratch_start ? 1 : 0;
    stats.weighted_terms += terms;
    stats.longest_row = std::max(stats.longest_row, terms);
  };
  for (std::size_t list = 0; list < 2; ++list) {
    for (const auto& run : plan.copy_runs[list]) stats.copies += static_cast<std::int64_t>(run.length) * run.rows;
    for (const auto& rows : plan.packed[list])
      for (std::size_t r = 0; r < rows.rows(); ++r) weighted_row(rows.dest[r], rows.begin[r + 1] - rows.begin[r]);
    for (const std::int32_t row : plan.remote_rows[list]) {
      const auto k = static_cast<std::size_t>(row);
      weighted_row(plan.dest[k], plan.local_begin[k + 1] - plan.local_begin[k] + plan.remote_begin[k + 1] - plan.remote_begin[k]);
    }
  }
  stats.rows += stats.copies;
  if (stats.copies > 0) stats.longest_row = std::max(stats.longest_row, 1);
  stats.copy_rectangles = static_cast<std::int64_t>(plan.copy_runs[0].size() + plan.copy_runs[1].size());
  stats.reused_blocks = std::ranges::count_if(plan.reused_from, [](std::int32_t o) { return o >= 0; });
  return stats;
}

// ---------------------------------------------------------------------------------------------
// Wavelet coefficients.

template <int Dim>
const double* AdaptiveGrid<Dim>::predict_array(const double* u, const DetailStencils& stencils) const {
  // d = u - P u_{j-1} in separable form, every coefficient bitwise the point-by-point one. The
  // general path, for block_details (all the coefficients); tagging needs only their maxima and
  // takes DetailKernels.cpp, which the test LargestDetailsMatchBlockDetails holds to this path
  // bitwise.
  return separable_tensor_sums<Dim>(u, config_.block_size + 2 * layout_.ghosts, stencils.axis, config_.block_size, stage_);
}

template <int Dim>
void AdaptiveGrid<Dim>::block_details(int field, std::size_t slot, std::span<double> out) const {
  const auto& stencils = block_detail_stencils(slot);
  const double* u = block(field, slot).data();
  const double* predicted = predict_array(u, stencils);
  const auto& st = stencils.axis;
  const auto ubs = static_cast<std::size_t>(config_.block_size);
  for_each_interior_line<Dim>(config_.block_size, layout_.ghosts, [&](std::size_t at, std::size_t p, std::size_t j, std::size_t k) {
    bool line_even = true;
    if constexpr (Dim >= 2) line_even = st[1][j].size == 1;
    if constexpr (Dim == 3) line_even = line_even && st[2][k].size == 1;
    for (std::size_t i = 0; i < ubs; ++i)
      out[p + i] = line_even && st[0][i].size == 1 ? 0.0 : u[at + i] - predicted[p + i];
  });
}

template <int Dim>
DetailMaxima AdaptiveGrid<Dim>::largest_details(int field, std::size_t slot) const {
  return detail_maxima(block(field, slot).data(), block_detail_stencils(slot));
}

template <int Dim>
DetailMaxima AdaptiveGrid<Dim>::detail_maxima(const double* u, const DetailStencils& stencils) const {
  // The stages' scratch: x-predicted lines, then (3D) y-predicted planes, then the last axis.
  const auto ubs = static_cast<std::size_t>(config_.block_size);
  const auto uw = ubs + 2 * static_cast<std::size_t>(layout_.ghosts);
  std::size_t lines = 1;
  for (int a = 1; a < Dim; ++a) lines *= uw;
  stage_[0].resize(lines * ubs);
  if constexpr (Dim >= 2) stage_[Dim - 1].resize(Dim == 2 ? ubs : uw * ubs * ubs + ubs * ubs);
  const DetailRows<Dim> rows{config_.block_size, layout_.ghosts,   config_.order, stencils.centred_weights,
                             stencils.centred,   stencils.axis,    stencils.near};
  return block_detail_maxima(u, rows, stage_[0].data(), Dim >= 2 ? stage_[Dim - 1].data() : nullptr);
}

template <int Dim>
std::vector<double> AdaptiveGrid<Dim>::field_scales(const ThresholdConfig& th,
                                                    std::vector<std::pair<double, double>>* ranges,
                                                    std::span<const char> tested) const {
  const auto F = static_cast<std::size_t>(fields());
  std::vector<double> scale(F, 1.0);
  if (ranges) ranges->clear();
  maxima_ahead_.clear();
  if (th.normalisation == Normalisation::kAbsolute) return scale;
  std::vector<double> local(F, 0.0), global(F, 0.0);
  // Max is exact: any order gives the same. The same pass gives each block's range of values
  // for the tagging's range bound, which would otherwise read the blocks again: of the blocks
  // whose bound will be tried, since reading the ghosts too costs more than the interiors (most
  // of a 16^2 block array is ghosts), where the bound rests (block_significance) their range is
  // NaN.
  if (ranges) ranges->assign(F * local_blocks(), {std::nan(""), std::nan("")});
  // The detail maxima block_significance will want are taken here, where the block is read
  // anyway (their own read would come from L2 or L3: after a step the data are not in L1), and
  // give the interior's magnitude in the same read.
  const bool ahead = ranges && tested.size() == local_blocks() && fields_computed_.size() == local_blocks();
  maxima_ahead_.assign(ahead ? F * local_blocks() : 0, DetailMaxima{std::nan(""), 0, 0});
  for (std::size_t f = 0; f < F; ++f)
    for (std::size_t s = 0; s < local_blocks(); ++s) {
      const double* u = data_[f].data() + block_base(s);
      if (!ranges || !range_bound_tried(s)) {  // the interiors only
        if (ahead && tested[s] && f < 32 && (fields_computed_[s] >> f & 1u)) {
          const DetailMaxima& found = maxima_ahead_[f * local_blocks() + s] = detail_maxima(u, block_detail_stencils(s));
          local[f] = std::max(local[f], found.magnitude);
          continue;
        }
        local[f] = std::max(local[f], interior_largest_magnitude(u, Dim, config_.block_size, layout_.ghosts));
        continue;
      }
      const BlockExtent e = block_extent(u, Dim, config_.block_size, layout_.ghosts);
      local[f] = std::max(local[f], e.interior_magnitude);
      (*ranges)[f * local_blocks() + s] = {e.low, e.high};
    }
  MPI_Allreduce(local.data(), global.data(), static_cast<int>(F), MPI_DOUBLE, MPI_MAX, comm_);
  for (std::size_t f = 0; f < F; ++f) {
    double m = global[f];
    if (!th.groups.empty())
      for (std::size_t o = 0; o < F; ++o)
        if (th.groups[o] == th.groups[f]) m = std::max(m, global[o]);
    scale[f] = m > 0 ? m : 1.0;  // a zero field has no significant coefficients either way
  }
  return scale;
}

template <int Dim>
std::int64_t AdaptiveGrid<Dim>::significant_points(const ThresholdConfig& th) const {
  const auto scale = field_scales(th);
  std::vector<double> d(interior_points_);
  std::vector<char> significant(interior_points_);
  std::int64_t count = 0;
  for (std::size_t s = 0; s < local_blocks(); ++s) {
    std::fill(significant.begin(), significant.end(), 0);
    for (int f = 0; f < fields(); ++f) {
      if (!th.groups.empty() && th.groups[static_cast<std::size_t>(f)] < 0) continue;
      block_details(f, s, d);
      for (std::size_t p = 0; p < d.size(); ++p)
        if (std::abs(d[p]) > th.epsilon * scale[static_cast<std::size_t>(f)]) significant[p] = 1;
    }
    count += std::count(significant.begin(), significant.end(), 1);
  }
  std::int64_t total = 0;
  MPI_Allreduce(&count, &total, 1, MPI_INT64_T, MPI_SUM, comm_);
  return total;
}

// ---------------------------------------------------------------------------------------------
// Adaptation.

template <int Dim>
void AdaptiveGrid<Dim>::gather_leaf_flags(std::span<const char> local, std::span<char> all) const {
  std::vector<int> counts(static_cast<std::size_t>(ranks_)), firsts(static_cast<std::size_t>(ranks_));
  for (std::size_t r = 0; r < counts.size(); ++r) {
    counts[r] = static_cast<int>(offsets_[r + 1] - offsets_[r]);
    firsts[r] = static_cast<int>(offsets_[r]);
  }
  MPI_Allgatherv(local.data(), static_cast<int>(local.size()), MPI_CHAR, all.data(), counts.data(), firsts.data(),
                 MPI_CHAR, comm_);
}

template <int Dim>
std::pair<bool, bool> AdaptiveGrid<Dim>::block_significance(std::size_t slot, const ThresholdConfig& th,
                                                            std::span<const double> scale,
                                                            std::span<const std::pair<double, double>> ranges,
                                                            double any_fraction) const {
  bool any = false, near = false, bound_decided = false;
  // Where the range bound decided nothing last time (every field's coefficients were computed),
  // it is not tried for the next few calls: it rarely decides sooner on such a block, and costs
  // a pass over the block's values per field. Each failure in a row doubles the rest, from 8
  // to 128 calls: on a smooth flow it fails on nearly every block every time (the vortex: 30%
  // of its coefficient computations followed a failed try, each after its own pass for the
  // range), while a block it decides for is tried again after 8.
  if (bound_rest_.size() != local_blocks()) bound_rest_.assign(local_blocks(), {});
  const bool try_bound = range_bound_tried(slot);
  if (!try_bound) --bound_rest_[slot].rest;
  // The fields are tried from the one that settled the block last time: the answer is an OR
  // over the fields, so the order changes nothing but how many are computed before it is known.
  if (first_field_.size() != local_blocks()) first_field_.assign(local_blocks(), 0);
  if (fields_computed_.size() != local_blocks()) fields_computed_.assign(local_blocks(), 0);
  fields_computed_[slot] = 0;
  const int F = fields(), first = first_field_[slot];
  for (int k = 0; k < F && !(any && near); ++k) {
    const int f = (first + k) % F;
    if (!th.groups.empty() && th.groups[static_cast<std::size_t>(f)] < 0) continue;
    const double threshold = th.epsilon * scale[static_cast<std::size_t>(f)];
    const double threshold_any = any_fraction * threshold;
    // A block whose whole range of values bounds every coefficient below the threshold is
    // insignificant without computing them (most of a far field). The margin covers the
    // rounding of the computed coefficients, so no decision differs from computing them.
    if (try_bound) {
      const auto at = static_cast<std::size_t>(f) * local_blocks() + slot;
      const auto [low, high] = ranges.empty() || std::isnan(ranges[at].first) ? block_bounds(f, slot) : ranges[at];
      const double rounding = 1e-12 * std::max(std::abs(low), std::abs(high));
      if (block_detail_stencils(slot).bound * (high - low) * (1 + 1e-12) + rounding < std::min(threshold, threshold_any)) {
        bound_decided = true;
        continue;
      }
    }
    if (f < 32) fields_computed_[slot] |= 1u << f;
    DetailMaxima maxima{std::nan(""), 0, 0};
    if (!maxima_ahead_.empty()) std::swap(maxima, maxima_ahead_[static_cast<std::size_t>(f) * local_blocks() + slot]);
    if (std::isnan(maxima.largest)) maxima = detail_maxima(block(f, slot).data(), block_detail_stencils(slot));
    any = any || maxima.largest > threshold_any;
    near = near || maxima.largest_near > threshold;
    if (any && near) first_field_[slot] = f;
  }
  if (try_bound) {
    auto& [rest, failures] = bound_rest_[slot];
    failures = bound_decided ? 0 : static_cast<std::uint8_t>(std::min(failures + 1, 5));
    rest = failures == 0 ? 0 : static_cast<std::uint8_t>(8 << (failures - 1));
  }
  return {any, near};
}

template <int Dim>
bool AdaptiveGrid<Dim>::parent_significant(const Key& parent, const ThresholdConfig& th,
                                           std::span<const double> scale) const {
  // The parent's array as coarsening would make it: its interior points are the children's
  // all-even points (injection), and the ghost layers the children's ghosts reach are their
  // ghosts' all-even points. Each such ghost is the value at the same point of the level the
  // parent's own ghost would resolve to (a finer leaf injects it, a coarser one predicts it),
  // so the near coefficients come out bitwise as the refine pass will compute them on the
  // parent (unless a neighbour coarsens in the same pass). Points no child reaches are 0 and
  // unread by near rows.
  const int bs = config_.block_size, g = layout_.ghosts;
  const auto shape = layout_.shape();
  const DetailStencils& stencils = detail_stencils_of(parent);
  std::array<std::size_t, Key::kChildren> child_slot{};
  for (int k = 0; k < Key::kChildren; ++k) {
    const std::size_t leaf = *forest_.find(parent.child(k));
    if (leaf < first_leaf_ || leaf >= first_leaf_ + local_blocks())
      throw std::logic_error("AdaptiveGrid: a family of leaves is split across ranks");
    child_slot[static_cast<std::size_t>(k)] = leaf - first_leaf_;
  }
  parent_array_.resize(block_volume_);
  if (parent_sources_.empty()) {
    // Per array point: the child and its array index, or child -1 where no child reaches.
    parent_sources_.assign(block_volume_, {-1, 0});
    for (std::size_t p = 0; p < block_volume_; ++p) {
      const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      int child = 0;
      Index q{};
      bool reached = true;
      for (int a = 0; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        const int fine = 2 * (i[au] - g);  // index along a in the family, children's level
        const int side = fine >= bs ? 1 : 0;
        const int local = fine - side * bs;
        reached = reached && local >= -g && local < bs + g;
        child |= side << a;
        q[au] = local + g;
      }
      if (reached) parent_sources_[p] = {child, shape.index(q)};
    }
  }
  for (int f = 0; f < fields(); ++f) {
    if (!th.groups.empty() && th.groups[static_cast<std::size_t>(f)] < 0) continue;
    std::array<const double*, Key::kChildren> from{};
    for (std::size_t k = 0; k < from.size(); ++k)
      from[k] = data_[static_cast<std::size_t>(f)].data() + block_base(child_slot[k]);
    for (std::size_t p = 0; p < block_volume_; ++p) {
      const auto [child, at] = parent_sources_[p];
      parent_array_[p] = child < 0 ? 0.0 : from[static_cast<std::size_t>(child)][at];
    }
    if (detail_maxima(parent_array_.data(), stencils).largest_near > th.epsilon * scale[static_cast<std::size_t>(f)]) return true;
  }
  return false;
}

template <int Dim>
AdaptCounts AdaptiveGrid<Dim>::adapt(const ThresholdConfig& th, AdaptPass pass, const ForcedRegion<Dim>& forced) {
  return adapt_pass(th, pass, forced, false, nullptr, nullptr);
}

template <int Dim>
AdaptCounts AdaptiveGrid<Dim>::adapt_cycle(const ThresholdConfig& th, const ForcedRegion<Dim>& forced) {
  // The refine pass's significance is computed in the coarsen pass's sweep (one prediction per
  // block and field gives both maxima). It is still valid if the coarsen pass changed nothing,
  // the usual case once the grid has settled (the coarsen pass keeps what the refine pass would
  // add again); otherwise the refine pass computes it afresh.
  // So is the forced region's verdict on each leaf (the caller's predicate, often the costlier
  // part of a pass around moving bodies).
  std::vector<char> near_sig, forced_leaves;
  const AdaptCounts coarsened = adapt_pass(th, AdaptPass::kCoarsen, forced, true, &near_sig, &forced_leaves);
  const bool unchanged = coarsened.refined == 0 && coarsened.coarsened == 0;
  const AdaptCounts refined = adapt_pass(th, AdaptPass::kRefine, forced, true, unchanged ? &near_sig : nullptr,
                                         unchanged ? &forced_leaves : nullptr);
  return {coarsened.refined + refined.refined, coarsened.coarsened + refined.coarsened};
}

template <int Dim>
AdaptCounts AdaptiveGrid<Dim>::adapt_pass(const ThresholdConfig& th, AdaptPass pass, const ForcedRegion<Dim>& forced,
                                          bool cycle, std::vector<char>* refine_sig, std::vector<char>* forced_leaves) {
  const std::size_t n = forest_.size();
  const auto leaves = forest_.leaves();
  std::vector<char> force(n, 0), near_sig(n, 0);
  if (forced_leaves && forced_leaves->size() == n) force = *forced_leaves;
  else if (forced)
    for (std::size_t l = 0; l < n; ++l) {
      const Point lo = origin(leaves[l]), h = spacing(leaves[l].level);
      Point hi{};
      for (int a = 0; a < Dim; ++a)
        hi[static_cast<std::size_t>(a)] = lo[static_cast<std::size_t>(a)] + config_.block_size * h[static_cast<std::size_t>(a)];
      force[l] = forced(lo, hi);
    }
  if (forced_leaves && forced_leaves->size() != n) *forced_leaves = force;
  // A leaf's significance decides its own tag only if the pass can change it (below the finest
  // level and not forced when refining, above the coarsest and not forced when coarsening), and
  // a neighbour's only through the adjacent zone. Leaves it can decide nothing for are not
  // tested: the tags come out the same, without computing coefficients the pass cannot use
  // (typically a far field at the coarsest level, in the coarsen pass).
  std::vector<Neighbour<Dim>> around;
  // They depend on the layout, the forced leaves and the adjacency only: a settled grid's cycles
  // take them from the last cycle (finding them again, through every leaf's neighbours, was
  // 4 us of the vortex's 45 us settled cycle).
  if (needed_cache_.layout != layout_serial_ || needed_cache_.adjacent != th.adjacent_blocks || needed_cache_.force != force) {
    needed_cache_.layout = layout_serial_;
    needed_cache_.adjacent = th.adjacent_blocks;
    needed_cache_.force = force;
    needed_cache_.known = {false, false};
  }
  auto needed_in = [&](AdaptPass p) -> const std::vector<char>& {
    const std::size_t kind = p == AdaptPass::kRefine ? 1 : 0;
    std::vector<char>& needed = needed_cache_.needed[kind];
    if (needed_cache_.known[kind]) return needed;
    auto own_tag_open = [&](std::size_t l) {
      return !force[l] && (p == AdaptPass::kRefine ? leaves[l].level < config_.max_level
                                                   : leaves[l].level > config_.min_level);
    };
    needed.assign(n, 0);
    for (std::size_t l = first_leaf_; l < first_leaf_ + local_blocks(); ++l) {
      needed[l] = own_tag_open(l);
      if (needed[l] || !th.adjacent_blocks) continue;
      for (const auto& nb : forest_.leaf_neighbours(l))
        if ((p == AdaptPass::kCoarsen || nb.level_difference <= 0) && own_tag_open(nb.leaf)) {
          needed[l] = 1;
          break;
        }
    }
    needed_cache_.known[kind] = true;
    return needed;
  };

  // 1. Tag: significance of this rank's blocks, gathered so every rank sees every leaf. In a
  // cycle, the refine pass counts only the `near` points (see parent_significant): its tags are
  // then the ones the coarsen pass can foresee, and what that coarsens stays coarse.
  const bool reuse = cycle && pass == AdaptPass::kRefine && refine_sig && refine_sig->size() == n;
  const bool share = cycle && pass == AdaptPass::kCoarsen && refine_sig;
  std::vector<double> scale;
  std::vector<char> sig(n, 0);
  if (reuse) {
    sig = *refine_sig;
  } else {
    const std::vector<char> none;
    const auto& needed = needed_in(pass);
    const auto& needed_later = share ? needed_in(AdaptPass::kRefine) : none;
    std::vector<char> tested(local_blocks());
    for (std::size_t s = 0; s < local_blocks(); ++s)
      tested[s] = needed[first_leaf_ + s] != 0 || (share && needed_later[first_leaf_ + s] != 0);
    std::vector<std::pair<double, double>> ranges;
    scale = field_scales(th, &ranges, tested);
    std::vector<char> local_sig(local_blocks(), 0), local_near(share ? local_blocks() : 0, 0);
    for (std::size_t s = 0; s < local_blocks(); ++s) {
      const bool now = needed[first_leaf_ + s] != 0, later = share && needed_later[first_leaf_ + s] != 0;
      if (!tested[s]) continue;
      const auto [any, near] =
          block_significance(s, th, scale, ranges, pass == AdaptPass::kCoarsen ? th.coarsen_fraction : 1.0);
      local_sig[s] = cycle && pass == AdaptPass::kRefine ? near : now && any;
      if (later) local_near[s] = near;
    }
    maxima_ahead_.clear();  // what the blocks' tests did not take is not for a later pass
    gather_leaf_flags(local_sig, sig);
    if (share) {
      refine_sig->assign(n, 0);
      gather_leaf_flags(local_near, *refine_sig);
    }
  }

  if (th.adjacent_blocks)
    for (std::size_t l = 0; l < n; ++l) {
      if (!sig[l]) continue;
      for (const auto& nb : forest_.leaf_neighbours(l))
        if (pass == AdaptPass::kCoarsen || nb.level_difference <= 0) near_sig[nb.leaf] = 1;
    }
  std::vector<AdaptTag> tags(n, AdaptTag::kKeep);
  for (std::size_t l = 0; l < n; ++l) {
    if (pass == AdaptPass::kRefine) {
      if (sig[l] || force[l] || near_sig[l]) tags[l] = AdaptTag::kRefine;
    } else if (!sig[l] && !force[l] && !near_sig[l] && leaves[l].level > config_.min_level) {
      tags[l] = AdaptTag::kCoarsen;
    }
  }
  if (cycle && pass == AdaptPass::kCoarsen) {
    // Adjacency in scale: a family whose parent the cycle's refine pass would refine is kept
    // (a lone coarsen pass, as adapt_to_function makes, keeps only what is significant). The
    // partition never splits a family of leaves, so each is judged by the rank holding it.
    std::vector<char> local_keep(local_blocks(), 0), keep(n, 0);
    // A family with a finer neighbour stays whatever its tags say (2:1 balance; nothing refines
    // in a coarsen pass). Its parent's significance then matters only through the neighbours
    // it keeps below, and only to those in a family that could coarsen: only then is it
    // computed. The tags come out the same, without the coefficients of parents that cannot
    // form (most families around a moving fine band). Flags at each family's first member.
    enum : char { kNotAsking, kBalanceKeeps, kMayCoarsen };
    std::vector<char> family(n, kNotAsking);
    for (std::size_t l = 0; l < n; ++l)
      if (forest_.family_asks_to_coarsen(l, tags))
        family[l] = forest_.family_touches_finer(l) ? kBalanceKeeps : kMayCoarsen;
    // The leaves around a family's parent no finer than its children (those the loop below
    // keeps) are the members' neighbours no finer than them: the members tile the parent. A
    // balance-kept family's parent matters where one of those is in a family that may coarsen.
    std::vector<char> beside_may_coarsen;  // only read with the adjacent zone
    if (th.adjacent_blocks) {
      std::vector<char> may_coarsen(n, 0);
      for (std::size_t l = 0; l < n; ++l) may_coarsen[l] = family[l] == kMayCoarsen;
      beside_may_coarsen = forest_.families_beside(may_coarsen);
    }
    for (std::size_t l = first_leaf_; l < first_leaf_ + local_blocks(); ++l) {
      if (family[l] == kNotAsking) continue;
      if (family[l] == kBalanceKeeps && (!th.adjacent_blocks || !beside_may_coarsen[l])) continue;
      if (parent_significant(leaves[l].parent(), th, scale)) local_keep[l - first_leaf_] = 1;
    }
    gather_leaf_flags(local_keep, keep);
    // Adjacency in space: the refine pass also refines the same-or-coarser neighbours of a
    // block it refines for significance, so the families holding them are kept as well (the
    // leaves facing a kept parent whose parent is no finer than it). Every rank has every flag.
    std::vector<char> kept(n, 0);
    for (std::size_t l = 0; l < n; ++l) {
      if (!keep[l]) continue;
      const Key parent = leaves[l].parent();
      kept[l] = 1;
      if (!th.adjacent_blocks) continue;
      forest_.neighbours(parent, around);
      for (const auto& nb : around)
        if (nb.key.level >= 1 && nb.key.level <= parent.level + 1) kept[nb.leaf] = 1;
    }
    for (std::size_t l = 0; l < n; ++l)
      if (kept[l]) tags[l] = AdaptTag::kKeep;  // one member kept: the family stays
  }
  // 2-6. Refine, coarsen, balance, repartition, ghosts.
  return adapt_with_tags(tags);
}

template <int Dim>
AdaptCounts AdaptiveGrid<Dim>::adapt_with_tags(std::span<const AdaptTag> tags) {
  // Nothing to refine (below the finest level) and nothing to coarsen: the forest stays as it
  // is, without copying it to find out.
  // A coarsen tag changes something only if the leaf's whole family asks for it (a settled
  // cycle's coarsen pass tags many leaves whose families it keeps).
  bool may_change = tags.size() != forest_.size();
  for (std::size_t l = 0; l < tags.size() && !may_change; ++l)
    may_change = forest_.family_asks_to_coarsen(l, tags) ||
                 (tags[l] == AdaptTag::kRefine && forest_.leaves()[l].level < config_.max_level);
  if (!may_change) return {};
  // Decided on the forest as it is (no copy of it and its index when nothing changes).
  std::vector<Key> next;
  const AdaptCounts counts = forest_.adapted_leaves(tags, next);  // refine, coarsen, 2:1 balance
  if (counts.refined == 0 && counts.coarsened == 0) return counts;  // same blocks, same ghosts
  forest_.assign_leaves(std::move(next));
  const std::vector<Key> old_keys = local_keys_;
  const std::vector<std::int32_t> old_page = page_of_;
  refresh_partition();
  // Pages (data_): a block that stays on this rank unchanged keeps its page, array and ghosts
  // (most blocks: nothing of theirs is copied); a new one takes a page nobody held before this
  // cycle, from the free list or added at the arrays' end (a quarter more at a time). The pages
  // of the blocks that went are read below and given back at the end. Every interior point of a
  // new block is written below, and its ghosts by the fill of the rebuilt rows.
  page_of_.assign(local_keys_.size(), -1);
  std::vector<char> kept(old_keys.size(), 0);
  for (std::size_t s = 0; s < old_keys.size(); ++s)
    if (const auto leaf = forest_.find(old_keys[s]); leaf && owner(*leaf) == rank_) {
      page_of_[*leaf - first_leaf_] = old_page[s];
      kept[s] = 1;
    }
  const auto needed = static_cast<std::size_t>(std::count(page_of_.begin(), page_of_.end(), -1));
  if (needed > free_pages_.size()) {
    const std::size_t grown = std::max(pages_ + needed - free_pages_.size(), pages_ + pages_ / 4);
    for (std::size_t page = grown; page-- > pages_;) free_pages_.push_back(static_cast<std::int32_t>(page));
    pages_ = grown;
    for (auto& field : data_) field.resize(pages_ * block_volume_);  // the scratch points are placed again
  }
  for (auto& page : page_of_)
    if (page < 0) {
      page = free_pages_.back();
      free_pages_.pop_back();
    }

  // New blocks from the old ones on the old owner: unchanged (copy), refined (children by
  // prediction from the ghosted parent) or coarsened (each child injects its quarter of the
  // parent). Messages: header (leaf, part), then fields x values.
  const int bs = config_.block_size, g = layout_.ghosts;
  const int F = fields();
  const auto shape = layout_.shape();
  const auto P = static_cast<std::size_t>(ranks_);
  std::vector<std::vector<std::int64_t>> head(P);
  std::vector<std::vector<double>> body(P);
  std::array<std::array<AxisStencil, kMaxBlockSize>, Dim> st;
  // Writes a new block's interior values (fields x interior points, interior order) from
  // `values` into local slot `slot`: its whole interior (part < 0) or the quarter (eighth) of a
  // coarsened parent that child `part` gives, its all-even points. Values for a block of this
  // rank are written at once, the others' sent in these blocks' messages.
  auto write_new_block = [&](std::size_t slot, int part, const double*& values) {
    for (int f = 0; f < F; ++f) {
      double* u = data_[static_cast<std::size_t>(f)].data() + block_base(slot);
      if (part < 0) {
        for_each_interior<Dim>(bs, g, shape, [&](std::size_t, const Index&, std::ptrdiff_t at) { u[at] = *values++; });
      } else {
        for_each_interior<Dim>(bs / 2, 0, ArrayShape<Dim>{}, [&](std::size_t, const Index& i, std::ptrdiff_t) {
          Index q{};
          for (int a = 0; a < Dim; ++a)
            q[static_cast<std::size_t>(a)] = i[static_cast<std::size_t>(a)] + ((part >> a) & 1) * bs / 2 + g;
          u[shape.index(q)] = *values++;
        });
      }
    }
  };
  std::vector<double> values;  // one new block's
  std::array<std::vector<double>, Dim> stages;  // separable_tensor_sums' scratch
  for (std::size_t s = 0; s < old_keys.size(); ++s) {
    const Key key = old_keys[s];
    if (const auto leaf = forest_.find(key)) {
      if (owner(*leaf) == rank_) continue;  // unchanged and still here, in its page
      auto& out = body[static_cast<std::size_t>(owner(*leaf))];
      head[static_cast<std::size_t>(owner(*leaf))].insert(head[static_cast<std::size_t>(owner(*leaf))].end(),
                                                          {static_cast<std::int64_t>(*leaf), -1});
      for (int f = 0; f < F; ++f) {
        const double* u = data_[static_cast<std::size_t>(f)].data() + static_cast<std::size_t>(old_page[s]) * block_volume_;
        for_each_interior<Dim>(bs, g, shape, [&](std::size_t, const Index&, std::ptrdiff_t at) { out.push_back(u[at]); });
      }
    } else if (forest_.find(key.child(0))) {
      for (int k = 0; k < Key::kChildren; ++k) {
        const std::size_t child_leaf = *forest_.find(key.child(k));
        const auto who = static_cast<std::size_t>(owner(child_leaf));
        child_stencils<Dim>(key, k, config_, g, st);
        values.resize(static_cast<std::size_t>(F) * interior_points_);
        for (int f = 0; f < F; ++f) {
          const double* child = separable_tensor_sums<Dim>(data_[static_cast<std::size_t>(f)].data() + static_cast<std::size_t>(old_page[s]) * block_volume_,
                                                           bs + 2 * g, st, bs, stages);
          std::copy_n(child, interior_points_, values.begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(f) * interior_points_));
        }
        const double* from = values.data();
        if (static_cast<int>(who) == rank_) {
          write_new_block(child_leaf - first_leaf_, -1, from);
          continue;
        }
        head[who].insert(head[who].end(), {static_cast<std::int64_t>(child_leaf), -1});
        body[who].insert(body[who].end(), values.begin(), values.end());
      }
    } else {
      const auto parent = forest_.find(key.parent());
      if (!parent) throw std::logic_error("AdaptiveGrid: a block changed by more than one level");
      const auto who = static_cast<std::size_t>(owner(*parent));
      values.clear();
      for (int f = 0; f < F; ++f) {
        const double* u = data_[static_cast<std::size_t>(f)].data() + static_cast<std::size_t>(old_page[s]) * block_volume_;
        // The parent's points in this child's region are the child's all-even points.
        for_each_interior<Dim>(bs / 2, 0, ArrayShape<Dim>{}, [&](std::size_t, const Index& i, std::ptrdiff_t) {
          Index q{};
          for (int a = 0; a < Dim; ++a) q[static_cast<std::size_t>(a)] = 2 * i[static_cast<std::size_t>(a)] + g;
          values.push_back(u[shape.index(q)]);
        });
      }
      const double* from = values.data();
      if (static_cast<int>(who) == rank_) {
        write_new_block(*parent - first_leaf_, key.child_index(), from);
        continue;
      }
      head[who].insert(head[who].end(), {static_cast<std::int64_t>(*parent), key.child_index()});
      body[who].insert(body[who].end(), values.begin(), values.end());
    }
  }
  std::vector<int> hs(P), hr(P), bsend(P), brecv(P), hsf(P + 1, 0), hrf(P + 1, 0), bsf(P + 1, 0), brf(P + 1, 0);
  for (std::size_t r = 0; r < P; ++r) {
    hs[r] = static_cast<int>(head[r].size());
    bsend[r] = static_cast<int>(body[r].size());
  }
  MPI_Alltoall(hs.data(), 1, MPI_INT, hr.data(), 1, MPI_INT, comm_);
  MPI_Alltoall(bsend.data(), 1, MPI_INT, brecv.data(), 1, MPI_INT, comm_);
  for (std::size_t r = 0; r < P; ++r) {
    hsf[r + 1] = hsf[r] + hs[r];
    hrf[r + 1] = hrf[r] + hr[r];
    bsf[r + 1] = bsf[r] + bsend[r];
    brf[r + 1] = brf[r] + brecv[r];
  }
  std::vector<std::int64_t> hflat, hin(static_cast<std::size_t>(hrf[P]));
  std::vector<double> bflat, bin(static_cast<std::size_t>(brf[P]));
  for (std::size_t r = 0; r < P; ++r) {
    hflat.insert(hflat.end(), head[r].begin(), head[r].end());
    bflat.insert(bflat.end(), body[r].begin(), body[r].end());
  }
  MPI_Alltoallv(hflat.data(), hs.data(), hsf.data(), MPI_INT64_T, hin.data(), hr.data(), hrf.data(), MPI_INT64_T, comm_);
  MPI_Alltoallv(bflat.data(), bsend.data(), bsf.data(), MPI_DOUBLE, bin.data(), brecv.data(), brf.data(), MPI_DOUBLE, comm_);

  const double* received = bin.data();
  for (std::size_t k = 0; k < hin.size(); k += 2)
    write_new_block(static_cast<std::size_t>(hin[k]) - first_leaf_, static_cast<int>(hin[k + 1]), received);
  for (std::size_t s = 0; s < old_keys.size(); ++s)
    if (!kept[s]) free_pages_.push_back(old_page[s]);
  // Pages out of slot order cost the passes that go through the blocks in slot order (a settled
  // cycle's tests, the fills) their reads in sequence, where the arrays outgrow the caches: once
  // more than an eighth of the blocks start a new run of pages, and the arrays hold more than
  // GridConfig::pages_in_order_above_bytes, they are written again in slot order, ghosts
  // included, and the ghost plan is built afresh (a fresh plan's rows are those a reused one
  // would have). Around the two moving cylinders that is one changing cycle in about twenty.
  std::size_t breaks = 0;
  for (std::size_t s = 1; s < page_of_.size(); ++s) breaks += page_of_[s] != page_of_[s - 1] + 1 ? 1 : 0;
  if (config_.keep_pages_in_order && breaks * 8 > page_of_.size() &&
      pages_ * block_volume_ * data_.size() * sizeof(double) > config_.pages_in_order_above_bytes) {
    std::vector<std::vector<double>> in_order(data_.size());
    for (std::size_t f = 0; f < data_.size(); ++f) {
      in_order[f].reserve(page_of_.size() * block_volume_);
      for (std::size_t s = 0; s < page_of_.size(); ++s) {
        const auto from = data_[f].begin() + static_cast<std::ptrdiff_t>(block_base(s));
        in_order[f].insert(in_order[f].end(), from, from + static_cast<std::ptrdiff_t>(block_volume_));
      }
    }
    data_ = std::move(in_order);
    pages_in_slot_order();
    build_ghost_plan();
  } else {
    build_ghost_plan(std::move(plan_), old_keys);
  }
  // A block whose rows were copied from the old plan is unchanged, as is every leaf its rows
  // read: its ghosts, kept in its page, already hold what a fill would give them.
  fill_ghost_lists({kRebuiltRows});
  return counts;
}

template <int Dim>
void AdaptiveGrid<Dim>::refine_to_uniform() {
  for (int l = 0; l <= config_.max_level; ++l) {
    std::vector<AdaptTag> all(forest_.size(), AdaptTag::kRefine);
    if (adapt_with_tags(all).refined == 0) break;
  }
}

template <int Dim>
void AdaptiveGrid<Dim>::rebuild(std::span<const Key> target) {
  std::unordered_set<Key, BlockKeyHash<Dim>> ancestors;
  int deepest = 0;
  for (const Key& k : target) {
    deepest = std::max(deepest, k.level);
    for (Key a = k; a.level > 0;) {
      a = a.parent();
      if (!ancestors.insert(a).second) break;
    }
  }
  ForestConfig<Dim> fc = forest_.config();
  forest_ = BlockForest<Dim>(fc);
  // Refining the ancestors level by level reproduces a balanced target without extra blocks.
  for (int l = 0; l < deepest; ++l) {
    std::vector<AdaptTag> tags(forest_.size(), AdaptTag::kKeep);
    for (std::size_t i = 0; i < forest_.size(); ++i)
      if (ancestors.contains(forest_.leaves()[i])) tags[i] = AdaptTag::kRefine;
    forest_.adapt(tags);
  }
  if (forest_.size() != target.size() || !std::equal(target.begin(), target.end(), forest_.leaves().begin()))
    throw std::invalid_argument("AdaptiveGrid::rebuild: the keys are not a balanced forest in curve order");
  refresh_partition();
  allocate_local();
  build_ghost_plan();
}

// ---------------------------------------------------------------------------------------------
// Operators.

template <int Dim>
int AdaptiveGrid<Dim>::edge_class(const Key& key) const {
  int code = key.level;
  for (const auto& [low, high] : bounded_edges(key)) code = code * 4 + (low ? 1 : 0) + (high ? 2 : 0);
  return code;
}

template <int Dim>
const typename AdaptiveGrid<Dim>::DetailStencils& AdaptiveGrid<Dim>::detail_stencils_of(const Key& key) const {
  // Block starts are even (Bs is even), and only blocks on a bounded edge of the domain use
  // one-sided rows, so the stencils in array coordinates depend on the edge class alone.
  auto& cached = detail_stencils_[edge_class(key)];
  if (cached) return *cached;
  cached = std::make_unique<DetailStencils>();
  detail_stencils<Dim>(key, config_, layout_.ghosts, cached->axis);
  // Each 1D row sums to 1 (it reproduces constants), so d = sum_k w_k (u - u_k) and
  // |d| <= sum |w| (max - min); the tensor sum of |w| is the product of the rows' sums.
  const int bs = config_.block_size, g = layout_.ghosts;
  // The children of this block as a family hold its level's points on their interiors and, in
  // their ghosts (g layers of the finer level), floor(g / 2) of its layers below and ceil(g / 2)
  // above (block starts are even); `near` rows read nothing beyond those.
  const int reach_low = g - g / 2, reach_high = g + bs - 1 + (g + 1) / 2;
  for (int a = 0; a < Dim; ++a) {
    const auto& rows = cached->axis[static_cast<std::size_t>(a)];
    double widest = 1;
    for (int i = 0; i < bs; ++i) {
      const AxisStencil& row = rows[static_cast<std::size_t>(i)];
      double sum = 0;
      bool near = true;
      for (int k = 0; k < row.size; ++k) {
        sum += std::abs(row.w[static_cast<std::size_t>(k)]);
        const int at = row.at[static_cast<std::size_t>(k)];
        near = near && at >= reach_low && at <= reach_high;
      }
      widest = std::max(widest, sum);
      cached->near[static_cast<std::size_t>(a)][static_cast<std::size_t>(i)] = near;
    }
    cached->bound *= widest;
  }
  // Which rows are centred (the weights of an odd point far from any edge: dd_line on a
  // periodic line).
  const int order = config_.order;
  cached->centred_weights = dd_line(order, 2 * order + 1, 8 * order, true).weight;
  for (int a = 0; a < Dim; ++a)
    for (int i = 0; i < bs; ++i) {
      const AxisStencil& row = cached->axis[static_cast<std::size_t>(a)][static_cast<std::size_t>(i)];
      bool same = row.size == (i % 2 == 0 ? 1 : order);
      for (int k = 0; k < row.size && same; ++k) {
        const auto ku = static_cast<std::size_t>(k);
        same = i % 2 == 0 ? row.at[ku] == i + g && row.w[ku] == 1.0
                          : row.at[ku] == i + g + 2 * k - (order - 1) && row.w[ku] == cached->centred_weights[ku];
      }
      cached->centred[static_cast<std::size_t>(a)][static_cast<std::size_t>(i)] = same;
    }
  return *cached;
}

template <int Dim>
const typename AdaptiveGrid<Dim>::DetailStencils& AdaptiveGrid<Dim>::block_detail_stencils(std::size_t slot) const {
  if (slot_detail_stencils_.size() != local_keys_.size()) slot_detail_stencils_.assign(local_keys_.size(), nullptr);
  if (const auto* known = slot_detail_stencils_[slot]) return *known;
  return *(slot_detail_stencils_[slot] = &detail_stencils_of(local_keys_[slot]));
}

template <int Dim>
std::pair<double, double> AdaptiveGrid<Dim>::block_bounds(int field, std::size_t slot) const {
  return value_range(data_[static_cast<std::size_t>(field)].data() + block_base(slot), block_volume_);
}

template <int Dim>
const DerivativeOperator<Dim>& AdaptiveGrid<Dim>::derivative_operator(std::size_t slot) const {
  const Key& key = local_keys_[slot];
  auto& op = operators_[edge_class(key)];
  if (op) return *op;
  DerivativeConfig dc;
  dc.accuracy = config_.derivative_accuracy;
  const auto touches = bounded_edges(key);
  for (int a = 0; a < Dim; ++a) dc.one_sided[static_cast<std::size_t>(a)] = touches[static_cast<std::size_t>(a)];
  op = std::make_unique<DerivativeOperator<Dim>>(layout_, spacing(key.level), dc);
  return *op;
}

template <int Dim>
void AdaptiveGrid<Dim>::first_derivative(int field, int axis, int out_field) {
  for (std::size_t s = 0; s < local_blocks(); ++s)
    derivative_operator(s).first(block(field, s), block(out_field, s), axis);
}

template <int Dim>
void AdaptiveGrid<Dim>::second_derivative(int field, int axis, int out_field) {
  for (std::size_t s = 0; s < local_blocks(); ++s)
    derivative_operator(s).second(block(field, s), block(out_field, s), axis);
}

template <int Dim>
std::size_t AdaptiveGrid<Dim>::memory_bytes() const {
  std::size_t bytes = 0;
  for (const auto& f : data_) bytes += f.size() * sizeof(double);
  for (const GhostPlan* p : {plan_.get(), spare_plan_.get()})
    if (p) {
      bytes += p->dest.capacity() * 4 + p->local_src.capacity() * 4 + p->local_weight.capacity() * 2 +
               p->local_src_page.capacity() * 4 + p->remote_src.capacity() * 12 +
               (p->segments.capacity() + p->copy_when.capacity()) * sizeof(typename GhostPlan::CopyRun) +
               p->kind.capacity() + (p->send_buffer.capacity() + p->recv_buffer.capacity()) * 8;
      for (const auto& runs : p->copy_runs) bytes += runs.capacity() * sizeof(typename GhostPlan::CopyRun);
      auto packed_bytes = [](const typename GhostPlan::PackedRows& rows) {
        return (rows.dest.capacity() + rows.begin.capacity() + rows.src.capacity()) * 4 + rows.weight.capacity() * 2;
      };
      for (const auto& list : p->packed)
        for (const auto& rows : list) bytes += packed_bytes(rows);
      bytes += packed_bytes(p->sum_when) + (p->copy_when_begin.capacity() + p->sum_when_begin.capacity()) * 4;
    }
  return bytes;
}

template class AdaptiveGrid<1>;
template class AdaptiveGrid<2>;
template class AdaptiveGrid<3>;

}  // namespace grainwave::wavelet

#pragma once
// Wavelet-adaptive multiresolution grid with field data: the adaptive wavelet collocation method
// (AWCM, Vasilyev & Bowman 2000; Goetsch 2015, 002 §2.2.2) organised in blocks (design.md "The
// adaptive grid").
//
// Grid. Levels Jmin..Jmax; a block at level j holds Bs^Dim collocation points with spacing
// h_j = (hi - lo) / (roots * Bs * 2^j) per axis, non-redundant: block (level j, coords c) holds
// the level-j global indices c*Bs .. c*Bs + Bs - 1, at x = lo + index * h_j. Blocks are keyed by
// (level, Morton) in a BlockForest whose light metadata is replicated on every rank; the field
// data of a block lives only on its owner, the ranks owning contiguous chunks of the forest's
// space-filling curve.
//
// Multiresolution. The points of level j-1 are the level-j points whose indices are all even.
// The wavelet coefficient of a level-j point is
//     d = u - P u_{j-1},
// P the tensor-product Deslauriers-Dubuc interpolation (order 4 or 6, one-sided near
// non-periodic domain edges) along the axes where the index is odd; d = 0 for all-even points
// (they belong to level j-1). The value at any (level, index) of the domain is defined from the
// leaves alone: a leaf at that level holds it, a finer leaf holds it by injection (its point
// coincides), a coarser leaf predicts it by P. Ghost points are filled by this rule, so
// reconstruction is perfect: refining every block by P reproduces the sampled field up to the
// discarded (insignificant) coefficients. A caller may predict ghosts from a coarser leaf with a
// higher order than the wavelets' (GridConfig::ghost_order): that changes only ghosts at odd
// indices, which no wavelet coefficient reads, so the thresholding is the same; derivatives get
// their full order at level interfaces. The rule above then holds for the wavelets' points but not
// for those odd ghosts: a block refined next to a coarser one predicts its new points from them
// (with `order`), so they differ from the ghost values its fine neighbour held there by the
// difference of the two interpolations (O(h^4)).
//
// Adaptation (the cycle is written once, in adapt()): tag -> refine -> coarsen -> 2:1 balance ->
// repartition -> ghost rebuild. Significance: |d| > epsilon * scale(field), scale 1 (absolute)
// or the global max |u| of the field or its group (normalised L-infinity). A block holding a
// significant point, or inside the caller's forced region, is refined (refine pass: the adjacent
// zone in scale); so are, with `adjacent_blocks`, its same-or-coarser neighbours (the adjacent
// zone in space). A block whose points are all insignificant, that no significant block
// touches and that lies outside the forced region, is coarsened (coarsen pass). New points are
// filled by P, removed points restricted by injection.
//
// A time-stepping solver adapts by cycles (adapt_cycle): a coarsen pass, then a refine pass, on
// the same data. Lone passes would coarsen the adjacent zone in scale the refine pass adds
// (its children are insignificant) and add it again the next cycle, rebuilding the same blocks
// and ghost plan every step. In a cycle the coarsen pass keeps a family whose parent the refine
// pass would refine: it can tell from the children alone, because in a cycle the refine pass
// counts only the points whose prediction stencils the children's ghosts reach ("near" points,
// all but the odd points next to an open block edge; a feature there is within the stencils of
// the next near point of this block or its neighbour). It keeps the families beside such a
// family too (the adjacent zone in space). A settled grid then stays as it is, and the error
// control is the coarsen pass's, unchanged.
//
// Storage. Each field is one array of local blocks; a block is an ArrayShape of Bs + 2g points
// per axis (g ghost layers, by default the least that prediction and derivatives read:
// max(order - 1, accuracy / 2)). After the blocks, each array holds the ghost plan's scratch
// points: a ghost predicted from a coarser leaf along several odd axes is summed along one of
// them from predictions along the others (separable prolongation: 6 terms instead of 36 in 2D),
// and those of its intermediate points that are not the block's own ghosts are kept there.
// Ghost exchange across ranks uses non-blocking point-to-point messages with a plan built once
// per adaptation. A caller whose stencils read fewer ghosts than adaptation needs (a solver's
// right-hand side: along the axes, and into corners only as far as its mixed derivatives) states
// that reach (set_stencil_reach) and fills only those (fill_stencil_ghosts). After a rebuild the
// adaptation fills only the blocks whose plan rows it built afresh: every other block, and every
// leaf it reads, came through unchanged, ghosts included.
#include <mpi.h>

#include <array>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "wavelet/AxisStencil.hpp"
#include "wavelet/BlockForest.hpp"
#include "wavelet/Stencils.hpp"

namespace grainwave::wavelet {

inline constexpr int kMaxBlockSize = 32;

template <int Dim>
struct GridConfig {
  std::array<double, Dim> lo{}, hi{};
  std::array<int, Dim> roots{};      ///< root blocks per axis
  std::array<bool, Dim> periodic{};
  int block_size = 8;                ///< Bs: collocation points per block and axis (even, 8..32)
  int min_level = 0;                 ///< Jmin: the grid never coarsens below it
  int max_level = 4;                 ///< Jmax
  int order = 4;                     ///< Deslauriers-Dubuc interpolation order: 4 or 6
  /// Order of the interpolation that fills ghost points from a coarser leaf (4 or 6; 0: `order`).
  /// Only ghosts at odd indices, which derivatives read and wavelet coefficients never do, depend
  /// on it: a derivative of accuracy a at a level interface is of order min(a, p_g - 1) (first)
  /// and min(a, p_g - 2) (second), so 4th-order derivatives everywhere need p_g = 6.
  int ghost_order = 0;
  int ghosts = 0;                    ///< ghost layers; 0 takes the least the stencils need
  int derivative_accuracy = 4;       ///< finite-difference order of the derivative operators
  CurveOrder curve = CurveOrder::kHilbert;
  std::vector<std::string> fields;   ///< named fields held at every point
  /// Write the field arrays again in slot order when adaptations have scattered the blocks'
  /// pages and the arrays outgrow the caches (adapt_with_tags). Tests switch it off to take the
  /// reuse of ghost rows through every cycle.
  bool keep_pages_in_order = true;
  /// ... where the field arrays hold more than this many bytes. Below 4 MB they stay in this
  /// machine's caches (1 MB L2, a shared L3): the isentropic vortex's 1.1 MB of scattered pages
  /// cost its fill 5%, and putting them in order (a fresh ghost plan) its changing cycles 35%.
  std::size_t pages_in_order_above_bytes = std::size_t{4} << 20;
};

enum class Normalisation { kAbsolute, kLinf };

struct ThresholdConfig {
  double epsilon = 1e-3;
  Normalisation normalisation = Normalisation::kLinf;
  /// Field -> group; a group shares one scale (the max over its fields). Empty: every field is
  /// its own group. Fields in group -1 do not take part in the significance test.
  std::vector<int> groups;
  bool adjacent_blocks = true;  ///< adjacent zone in space: neighbours of significant blocks
  /// Hysteresis: a coarsen pass keeps a block whose coefficients exceed coarsen_fraction *
  /// epsilon (refining still takes epsilon). Below 1, a block whose coefficients hover near the
  /// threshold stays put instead of being coarsened and refined again and again, each time
  /// perturbing the solution by up to epsilon; 1: one threshold for both.
  double coarsen_fraction = 1.0;
};

/// Region whose blocks must sit at max_level (e.g. a penalization interface): called with the
/// lower and upper corners of a block.
template <int Dim>
using ForcedRegion = std::function<bool(const std::array<double, Dim>&, const std::array<double, Dim>&)>;

enum class AdaptPass { kRefine, kCoarsen };

/// How a ghost point got its value (for diagnostics and tests).
enum class GhostKind : std::uint8_t { kSameLevel, kFromFiner, kFromCoarser, kOutsideDomain };

/// What block_detail_maxima (DetailKernels.hpp) finds in its one read of a block array.
struct DetailMaxima {
  double largest = 0;       ///< largest |u - P u| over the interior points
  double largest_near = 0;  ///< ... over the near points
  double magnitude = 0;     ///< largest |u| over the interior points (interior_largest_magnitude's)
};

/// What one full ghost fill of this rank computes (AdaptiveGrid::ghost_plan_stats).
struct GhostPlanStats {
  std::int64_t rows = 0;            ///< ghost points and scratch points filled
  std::int64_t scratch_points = 0;  ///< intermediate points of the separable prolongation
  std::int64_t copies = 0;          ///< rows that copy one value
  std::int64_t weighted_terms = 0;  ///< terms of the other rows (local and received)
  int longest_row = 0;              ///< most terms in one row
  /// Rectangles the copies are grouped into (a fill's copy loop runs once per rectangle), over
  /// both reach groups; a copy with a remote source is a row of its own instead.
  std::int64_t copy_rectangles = 0;
  /// Blocks whose entries the last rebuild took from the plan before it (unchanged blocks around
  /// unchanged leaves, after an adaptation) instead of resolving their ghosts again.
  std::int64_t reused_blocks = 0;
};

template <int Dim>
class AdaptiveGrid {
 public:
  using Key = BlockKey<Dim>;
  using Index = std::array<int, Dim>;
  using Point = std::array<double, Dim>;

  /// A uniform grid at min_level; field values zero, ghosts built.
  explicit AdaptiveGrid(GridConfig<Dim> config, MPI_Comm comm = MPI_COMM_WORLD);
  AdaptiveGrid(const AdaptiveGrid&);
  /// Copies grid, fields and ghost plan, reusing this grid's storage where it is large enough
  /// (the solver keeps its last good state this way every step). The fields are written with
  /// non-temporal stores (core/StreamingCopy.hpp): the copy is not for reading soon.
  AdaptiveGrid& operator=(const AdaptiveGrid&);
  ~AdaptiveGrid();

  // --- metadata (replicated) ---
  const GridConfig<Dim>& config() const { return config_; }
  const BlockForest<Dim>& forest() const { return forest_; }
  std::size_t global_blocks() const { return forest_.size(); }
  int owner(std::size_t leaf) const;
  BlockLayout<Dim> layout() const { return layout_; }
  std::size_t points_per_block() const { return interior_points_; }
  Point spacing(int level) const;
  Point origin(const Key& key) const;  ///< position of the block's interior point 0
  /// Points of the uniform grid at max_level (for compression ratios).
  double uniform_points() const;

  // --- local blocks ---
  std::size_t local_blocks() const { return local_keys_.size(); }
  /// Identifies the layout (blocks, their owners and ghost plan): drawn afresh, process-wide,
  /// whenever the layout is built, and shared by copies. Equal serials mean the same layout, so
  /// a user may keep data computed per block (masks, say) while the serial stays.
  std::uint64_t layout_serial() const { return layout_serial_; }
  std::size_t first_leaf() const { return first_leaf_; }  ///< leaf index of local slot 0
  const Key& key(std::size_t slot) const { return local_keys_[slot]; }
  /// Position of point i of a block (i may step into the ghosts).
  Point position(std::size_t slot, const Index& i) const;
  int fields() const { return static_cast<int>(config_.fields.size()); }
  int field_index(const std::string& name) const;  ///< -1 when absent
  std::span<double> block(int field, std::size_t slot);
  std::span<const double> block(int field, std::size_t slot) const;

  /// Sets every field at every interior point of every local block: f(x, values) with values
  /// of size fields(). Ghosts are left stale: call fill_ghosts().
  template <class F>
  void sample(F&& f);

  // --- ghosts ---
  /// Fills every ghost point of the local blocks (from this rank's blocks and, by non-blocking
  /// messages, the other ranks').
  void fill_ghosts();
  /// Fills only the ghost points within the stencil reach (set_stencil_reach); the others keep
  /// their values. For a right-hand side whose stencils read no further: adaptation, refinement
  /// and derivative operators need fill_ghosts().
  void fill_stencil_ghosts();
  /// fill_stencil_ghosts() while the caller writes the interiors: write_block(slot) is called
  /// for every local block in slot order, and each block's ghosts are filled as soon as every
  /// block they read has been written, while those values are still in cache (blocks reading
  /// another rank's values after the messages). The ghosts are bitwise those of
  /// fill_stencil_ghosts() after writing every block. Returns the seconds spent in write_block
  /// (from the cycle counter where there is one), so that a caller can time the two apart.
  double write_and_fill_stencil_ghosts(const std::function<void(std::size_t)>& write_block);
  /// The ghost points a caller's stencils read: up to `along_axis` layers beyond a face (outside
  /// the interior along one axis), up to `across_two_axes` layers along each of two axes (edges
  /// in 3D, corners in 2D), none outside along three. Default: every ghost point.
  void set_stencil_reach(int along_axis, int across_two_axes);
  /// Kind of ghost point `array_index` of a local block (interior points are kSameLevel).
  GhostKind ghost_kind(std::size_t slot, std::ptrdiff_t array_index) const;
  /// Number of ghost points of each kind over local blocks (index: GhostKind).
  std::array<std::int64_t, 4> ghost_counts() const;
  /// The size of this rank's ghost plan: what a full fill computes.
  GhostPlanStats ghost_plan_stats() const;

  // --- wavelet coefficients ---
  /// Writes d (interior points, 0 at all-even ones) of a field of a block into `out`
  /// (Bs^Dim values, interior order).
  void block_details(int field, std::size_t slot, std::span<double> out) const;
  /// Largest |d| of a field of a block, over all its interior points and over its `near` ones
  /// (those whose prediction reads only what a family of children holds): what tagging
  /// compares with the threshold, bitwise the maximum of block_details (ghosts must be filled);
  /// and the largest |u| of its interior points, found in the same read.
  DetailMaxima largest_details(int field, std::size_t slot) const;
  /// Global significance scale per field (1 for absolute, max |u| of the field's group). With
  /// `ranges` (linf normalisation), the same pass also gives each local block's range of values
  /// per field (field-major: field * local_blocks() + slot), ghosts included, as block_bounds
  /// would compute it, for the blocks whose range bound block_significance will try next (NaN
  /// for the others); with absolute normalisation there is no pass and `ranges` is left empty.
  /// `tested` (one flag per local block, with `ranges`): the blocks whose significance the pass
  /// will test. Of those whose range bound rests, the fields block_significance computed last
  /// time have their detail maxima taken in the same read of the block, for it to use.
  std::vector<double> field_scales(const ThresholdConfig& threshold,
                                   std::vector<std::pair<double, double>>* ranges = nullptr,
                                   std::span<const char> tested = {}) const;
  /// Global number of significant coefficients (ghosts must be filled).
  std::int64_t significant_points(const ThresholdConfig& threshold) const;

  // --- adaptation ---
  /// One adaptation pass: tag by significance (and the forced region), then adapt_with_tags.
  /// Ghosts must be filled on entry and are filled on return. Returns the global counts.
  AdaptCounts adapt(const ThresholdConfig& threshold, AdaptPass pass,
                    const ForcedRegion<Dim>& forced = {});
  /// A coarsen pass and then a refine pass on the same data: a time-stepping solver's
  /// adaptation between two steps. Unlike two lone passes, the grid keeps its safety zone in
  /// scale and space: the refine pass tests near points only and the coarsen pass keeps every
  /// family whose parent that would refine, and the families beside it, so a settled grid is
  /// left as it is instead of being
  /// coarsened and refined again every cycle; and the coefficients are computed once when the
  /// coarsen pass changes nothing. Ghosts must be filled on entry and are filled on return.
  AdaptCounts adapt_cycle(const ThresholdConfig& threshold, const ForcedRegion<Dim>& forced = {});
  /// Refine -> coarsen -> balance (BlockForest::adapt) with one tag per global leaf (identical
  /// on all ranks), new points by interpolation / injection, repartition, ghost rebuild.
  AdaptCounts adapt_with_tags(std::span<const AdaptTag> tags);
  /// Refine every block until the grid is uniform at max_level (by interpolation).
  void refine_to_uniform();
  /// Adapts to a function given pointwise (initial conditions): refine passes sampling `f` until
  /// nothing refines, then coarsen passes until nothing coarsens. Returns the passes made.
  template <class F>
  int adapt_to_function(const ThresholdConfig& threshold, F&& f, const ForcedRegion<Dim>& forced = {});

  // --- operators (ghosts must be filled) ---
  void first_derivative(int field, int axis, int out_field);
  void second_derivative(int field, int axis, int out_field);
  const DerivativeOperator<Dim>& derivative_operator(std::size_t slot) const;

  /// Replaces the grid by a given leaf set (sorted along the curve, as written by checkpoints)
  /// with zero fields; throws std::invalid_argument if the keys are not a balanced forest.
  void rebuild(std::span<const Key> leaves);

  std::size_t memory_bytes() const;

 private:
  struct GhostPlan;
  /// The part of a ghost fill that reads this rank's blocks, for one list of rows.
  void fill_local_ghosts(const GhostPlan& plan, std::size_t list);
  /// The rows of the lists summed from other ghost rows (separable prolongation, GhostPlan),
  /// stage by stage: after every other row of the lists.
  void fill_separable_ghosts(const GhostPlan& plan, std::initializer_list<std::size_t> lists);
  /// Fills the rows of the plan's lists: 0 and 1 (fill_ghosts), 0 (fill_stencil_ghosts) or
  /// kRebuiltRows (after an adaptation).
  void fill_ghost_lists(std::initializer_list<std::size_t> lists);
  /// A ghost fill's messages: the receives posted (returns how many requests), and the values
  /// other ranks' rows read packed and sent (requests counts on).
  std::size_t receive_ghost_values(GhostPlan& plan);
  void send_ghost_values(GhostPlan& plan, std::size_t& requests);
  /// Sorts the plan's rows and segments into copy runs, packed sums and remote rows, per list:
  /// 0, within the stencil reach, 1, the others, and kRebuiltRows, the rows of blocks built
  /// afresh. With the plan its blocks were reused from (grouped for the same reach), a reused
  /// block, which has no rows, takes that plan's entries (its packed rows' scratch points moved).
  void group_ghost_rows(GhostPlan& plan, const GhostPlan* previous) const;
  /// The blocks' order for write_and_fill_stencil_ghosts() (GhostPlan::fill_when_written).
  void order_fill_while_writing(GhostPlan& plan) const;
  /// The copy rectangles' and the sums' order for write_and_fill_stencil_ghosts()
  /// (GhostPlan::copy_when, GhostPlan::sum_when).
  void order_copies_and_sums_while_writing(GhostPlan& plan) const;
  static constexpr std::size_t kRebuiltRows = 2;
  void allocate_local();
  /// Block slot s in page s, no page free (a fresh layout, or the arrays written in slot order).
  void pages_in_slot_order();
  /// Builds the ghost plan of the current grid. With the plan of the grid before an adaptation
  /// and that grid's local keys, blocks whose neighbourhood did not change get no rows: they
  /// keep that plan's grouped entries (group_ghost_rows) instead of being resolved again.
  void build_ghost_plan(std::unique_ptr<GhostPlan> previous = nullptr, std::span<const Key> previous_keys = {});
  void refresh_partition();
  /// Per axis, whether the block touches the low / high edge of a bounded (not periodic) axis.
  std::array<std::array<bool, 2>, Dim> bounded_edges(const Key& key) const;

  GridConfig<Dim> config_;
  MPI_Comm comm_;
  int rank_ = 0, ranks_ = 1;
  BlockForest<Dim> forest_;
  std::vector<std::size_t> offsets_;  // partition: rank r owns leaves [offsets_[r], offsets_[r+1])
  std::size_t first_leaf_ = 0;
  std::vector<Key> local_keys_;
  BlockLayout<Dim> layout_;
  std::size_t interior_points_ = 0, block_volume_ = 0;
  // Per field: pages of block_volume_ values, then the ghost plan's scratch points. A block
  // keeps its page while it stays on this rank unchanged, so an adaptation writes only the
  // blocks it changes, and the ghost plan's rows of the blocks it reuses (which address points
  // by page) stay valid as they are; pages given up are reused by later new blocks.
  std::vector<std::vector<double>> data_;
  std::vector<std::int32_t> page_of_;    // per local slot
  std::vector<std::int32_t> free_pages_;
  std::size_t pages_ = 0;                // pages the field arrays hold
  /// Where slot's array starts in the field arrays.
  std::size_t block_base(std::size_t slot) const { return static_cast<std::size_t>(page_of_[slot]) * block_volume_; }
  std::unique_ptr<GhostPlan> plan_;
  std::unique_ptr<GhostPlan> spare_plan_;  ///< the plan the last rebuild replaced: storage for the next
  /// Drawn afresh (process-wide) whenever the ghost plan is built; copies share it, so an
  /// assignment between grids with the same layout copies only the field data.
  std::uint64_t layout_serial_ = 0;
  /// Ghost layers read when outside the interior along 1, 2 and 3 axes (set_stencil_reach).
  std::array<int, 3> stencil_reach_{};
  /// The level and bounded_edges() in one code: what a block's derivative and prediction
  /// stencils depend on.
  int edge_class(const Key& key) const;
  /// A block's prediction stencils per axis, and the bound B of sum |weights| of its tensor
  /// stencils: every coefficient obeys |d| <= B (max u - min u) over the block with ghosts.
  /// `near[a][i]`: the row of interior index i along axis a reads only points a family of
  /// children can supply for this block as their parent (see parent_significant).
  struct DetailStencils {
    std::array<std::array<AxisStencil, kMaxBlockSize>, Dim> axis;
    std::array<std::array<bool, kMaxBlockSize>, Dim> near{};
    double bound = 1;
    /// Per axis and index, whether the row is a centred one: an odd index i reading
    /// i + g + 2m - (order - 1), m < order, with the centred weights below, or an even index
    /// itself. All but the odd rows near a bounded domain edge; detail_maxima computes these
    /// with the offsets fixed (DetailKernels.hpp) and the others from their stencils.
    std::array<std::array<bool, kMaxBlockSize>, Dim> centred{};
    std::array<double, kMaxPredictOrder> centred_weights{};
  };
  const DetailStencils& detail_stencils_of(const Key& key) const;
  const DetailStencils& block_detail_stencils(std::size_t slot) const;
  /// P u at the interior points (interior order) of a block array u with stencils st: the
  /// prediction from its even points, u itself at all-even points. Points into a scratch
  /// buffer, valid until the next call.
  const double* predict_array(const double* u, const DetailStencils& st) const;
  /// Largest |u - P u| over the interior points of a block array, and over its near points
  /// (those whose rows are all `near`), and largest |u| over its interior points.
  DetailMaxima detail_maxima(const double* u, const DetailStencils& st) const;
  /// Whether the parent of a local family of leaves would be significant in the refine pass's
  /// sense (near points only, any field above its threshold), from the children's values and
  /// ghosts alone: the refine pass refines exactly such a parent, so the coarsen pass keeps the
  /// family instead of coarsening it only to see it refined again before the next step.
  bool parent_significant(const Key& parent, const ThresholdConfig& th, std::span<const double> scale) const;
  /// Whether a local block holds a significant point (any field above any_fraction times its
  /// threshold: coarsen_fraction in a coarsen pass), and whether it holds one among its near
  /// points (above the threshold itself: what the refine pass refines).
  /// `ranges`: field_scales' block ranges, or empty (then, or where a range is NaN, block_bounds
  /// reads the block).
  std::pair<bool, bool> block_significance(std::size_t slot, const ThresholdConfig& th, std::span<const double> scale,
                                           std::span<const std::pair<double, double>> ranges,
                                           double any_fraction) const;
  /// One adaptation pass, alone or as part of adapt_cycle (refine_sig: the refine pass's
  /// significance, computed by the coarsen pass, used by the refine pass; forced_leaves: the
  /// forced region's flag per leaf, used if it has one per leaf, stored there otherwise).
  AdaptCounts adapt_pass(const ThresholdConfig& th, AdaptPass pass, const ForcedRegion<Dim>& forced, bool cycle,
                         std::vector<char>* refine_sig, std::vector<char>* forced_leaves);
  /// One flag per local block -> one per global leaf, on every rank.
  void gather_leaf_flags(std::span<const char> local, std::span<char> all) const;
  /// min u and max u of a field over a block's array, ghosts included (NaNs ignored).
  std::pair<double, double> block_bounds(int field, std::size_t slot) const;
  mutable std::map<int, std::unique_ptr<DerivativeOperator<Dim>>> operators_;
  mutable std::map<int, std::unique_ptr<DetailStencils>> detail_stencils_;
  /// The entry of detail_stencils_ of each local slot (cleared when the slots change).
  mutable std::vector<const DetailStencils*> slot_detail_stencils_;
  mutable std::array<std::vector<double>, Dim> stage_;  // partial predictions (predict_array, detail_maxima)
  mutable std::vector<double> parent_array_;             // parent_significant: the assembled parent
  mutable std::vector<std::pair<int, std::ptrdiff_t>> parent_sources_;  // ... and where its points come from
  /// block_significance, per local block: calls left without the range bound, and the failures
  /// of its tries in a row.
  struct BoundSchedule {
    std::uint8_t rest = 0, failures = 0;
  };
  mutable std::vector<BoundSchedule> bound_rest_;
  /// adapt_pass: which leaves each pass tests (coarsen 0, refine 1), for the layout, forced
  /// leaves and adjacency they were found for (layout serials are never reused).
  struct NeededLeaves {
    std::uint64_t layout = 0;
    bool adjacent = false;
    std::vector<char> force;
    std::array<std::vector<char>, 2> needed;
    std::array<bool, 2> known{};
  };
  NeededLeaves needed_cache_;
  /// Whether block_significance's next call on a local block tries the range bound (field_scales
  /// then gives the block's range; not while the bound rests).
  bool range_bound_tried(std::size_t slot) const { return bound_rest_.size() != local_blocks() || bound_rest_[slot].rest == 0; }
  mutable std::vector<int> first_field_;  // block_significance: the field it tries first
  /// block_significance: per local block, a bit per field whose detail maxima its last call
  /// computed (what field_scales computes ahead for the next, where the bound rests).
  mutable std::vector<std::uint32_t> fields_computed_;
  /// Detail maxima field_scales computed ahead (field-major), `largest` NaN where none:
  /// block_significance takes each once.
  mutable std::vector<DetailMaxima> maxima_ahead_;
};

template <int Dim>
template <class F>
void AdaptiveGrid<Dim>::sample(F&& f) {
  std::vector<double> values(static_cast<std::size_t>(fields()));
  const auto shape = layout_.shape();
  for (std::size_t s = 0; s < local_blocks(); ++s) {
    const Point x0 = origin(local_keys_[s]);
    const Point h = spacing(local_keys_[s].level);
    for (std::size_t p = 0; p < interior_points_; ++p) {
      Index i{};
      std::size_t rest = p;
      Point x{};
      for (int a = 0; a < Dim; ++a) {
        const auto au = static_cast<std::size_t>(a);
        i[au] = static_cast<int>(rest % static_cast<std::size_t>(config_.block_size)) + layout_.ghosts;
        rest /= static_cast<std::size_t>(config_.block_size);
        x[au] = x0[au] + (i[au] - layout_.ghosts) * h[au];
      }
      f(x, std::span<double>(values));
      const auto at = static_cast<std::size_t>(shape.index(i)) + block_base(s);
      for (std::size_t k = 0; k < values.size(); ++k) data_[k][at] = values[k];
    }
  }
}

template <int Dim>
template <class F>
int AdaptiveGrid<Dim>::adapt_to_function(const ThresholdConfig& threshold, F&& f,
                                         const ForcedRegion<Dim>& forced) {
  sample(f);
  fill_ghosts();
  int passes = 0;
  for (const AdaptPass pass : {AdaptPass::kRefine, AdaptPass::kCoarsen}) {
    // Each refine pass adds at most one level everywhere, each coarsen pass removes at most one.
    for (int k = 0; k <= config_.max_level - config_.min_level + 1; ++k) {
      const AdaptCounts counts = adapt(threshold, pass, forced);
      ++passes;
      sample(f);
      fill_ghosts();
      if (counts.refined == 0 && counts.coarsened == 0) break;
    }
  }
  return passes;
}

/// Makes `keep` a copy of `grid`, in place (no allocation) when it already holds a grid: how
/// the solvers keep their last good state every step.
template <int Dim>
void keep_copy(std::unique_ptr<AdaptiveGrid<Dim>>& keep, const AdaptiveGrid<Dim>& grid) {
  if (keep) *keep = grid;
  else keep = std::make_unique<AdaptiveGrid<Dim>>(grid);
}

extern template class AdaptiveGrid<1>;
extern template class AdaptiveGrid<2>;
extern template class AdaptiveGrid<3>;

}  // namespace grainwave::wavelet

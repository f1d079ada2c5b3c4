#pragma once
// Topology of the block forest (metadata only, no field data): which blocks exist, who their
// neighbours are across faces, edges and corners, how tags refine and coarsen them under 2:1
// balance, and how they are ordered along a space-filling curve and cut into contiguous chunks
// for P ranks (design.md "The adaptive grid"; the p4est/WABBIT model of a replicated light
// forest whose block data is distributed along the curve).
//
// Conventions (see BlockKey.hpp for coordinates):
// - The domain is a box of roots[0] x ... root blocks, each axis periodic or not.
// - `leaves()` is always sorted along the configured curve (Morton or Hilbert over the anchors
//   of the blocks at max_level); indices into it are the "leaf indices" used by tags and owners.
// - A direction is a vector in {-1, 0, 1}^Dim, not all zero: one nonzero entry is a face, two an
//   edge (3D) or corner (2D), three a corner (3D).
// - 2:1 balance: leaves that touch (across faces, edges or corners, periodic images included)
//   differ by at most one level. Every public mutation keeps it.
#include "wavelet/BlockKey.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace grainwave::wavelet {

enum class CurveOrder { kMorton, kHilbert };

/// Per-leaf adaptation request. Coarsening happens only for complete families of leaves that
/// all ask for it and whose parent would stay 2:1 balanced; refinement may spread to coarser
/// neighbours to keep the balance.
enum class AdaptTag : std::int8_t { kCoarsen = -1, kKeep = 0, kRefine = 1 };

template <int Dim>
struct ForestConfig {
  std::array<int, Dim> roots{};     ///< root blocks per axis (all >= 1)
  std::array<bool, Dim> periodic{};
  int max_level = 4;                ///< finest block level (root level is 0)
  CurveOrder curve = CurveOrder::kHilbert;
};

template <int Dim>
struct Neighbour {
  BlockKey<Dim> key;
  int level_difference = 0;  ///< neighbour level minus own level: -1 coarser, 0 same, +1 finer
  std::array<int, Dim> direction{};
  std::size_t leaf = 0;  ///< its index in BlockForest::leaves()
};

struct AdaptCounts {
  int refined = 0;    ///< leaves replaced by their children
  int coarsened = 0;  ///< families replaced by their parent
};

/// Key -> leaf index, open addressing with linear probing over a power-of-two table at most half
/// full: a lookup is a hash, a mask and usually one 16-byte slot. (std::unordered_map's prime
/// modulo and node chase made its lookups a tenth of an adaptation cycle around moving bodies.)
template <int Dim>
class LeafIndex {
 public:
  void clear(std::size_t expected) {
    std::size_t capacity = 16;
    while (capacity < 2 * expected) capacity *= 2;
    slots_.assign(capacity, Slot{});
    mask_ = capacity - 1;
    size_ = 0;
  }
  /// Adds key -> leaf unless the key is there already (then the first stays, and size() shows
  /// the duplicate: tiles_domain() relies on it). At most the count given to clear().
  void insert(const BlockKey<Dim>& key, std::size_t leaf) {
    std::size_t at = BlockKeyHash<Dim>{}(key) & mask_;
    for (; slots_[at].level >= 0; at = (at + 1) & mask_)
      if (slots_[at].level == key.level && slots_[at].morton == key.morton) return;
    slots_[at] = Slot{key.morton, key.level, static_cast<std::uint32_t>(leaf)};
    ++size_;
  }
  std::optional<std::size_t> find(const BlockKey<Dim>& key) const {
    for (std::size_t at = BlockKeyHash<Dim>{}(key) & mask_;; at = (at + 1) & mask_) {
      const Slot& slot = slots_[at];
      if (slot.level < 0) return std::nullopt;
      if (slot.level == key.level && slot.morton == key.morton) return slot.leaf;
    }
  }
  std::size_t size() const { return size_; }

 private:
  struct Slot {
    std::uint64_t morton = 0;
    std::int32_t level = -1;  ///< -1: empty
    std::uint32_t leaf = 0;
  };
  std::vector<Slot> slots_{16};
  std::size_t mask_ = 15;
  std::size_t size_ = 0;
};

template <int Dim>
class BlockForest {
 public:
  using Key = BlockKey<Dim>;

  /// The root forest: every root block a leaf at level 0.
  explicit BlockForest(ForestConfig<Dim> config);

  const ForestConfig<Dim>& config() const { return config_; }
  std::span<const Key> leaves() const { return leaves_; }
  std::size_t size() const { return leaves_.size(); }
  std::optional<std::size_t> find(const Key& key) const;
  bool is_leaf(const Key& key) const { return index_.find(key).has_value(); }

  /// Blocks along axis a at a level, and the same-level key shifted by `direction` (wrapped on
  /// periodic axes; empty when it leaves a non-periodic domain).
  std::uint32_t blocks_along(int axis, int level) const {
    return static_cast<std::uint32_t>(config_.roots[static_cast<std::size_t>(axis)]) << level;
  }
  std::optional<Key> shifted(const Key& key, const std::array<int, Dim>& direction) const;

  /// All neighbouring leaves of a leaf across faces, edges and corners (up to 2^(Dim-1) finer
  /// ones per face). Relies on 2:1 balance. `out` is cleared and reused.
  void neighbours(const Key& leaf, std::vector<Neighbour<Dim>>& out) const;
  std::vector<Neighbour<Dim>> neighbours(const Key& leaf) const {
    std::vector<Neighbour<Dim>> out;
    neighbours(leaf, out);
    return out;
  }
  /// neighbours() of leaves()[leaf], computed once per leaf until the leaves change: every pass
  /// of an adaptation cycle (tagging, the adjacent zone, balance) asks for the same ones.
  const std::vector<Neighbour<Dim>>& leaf_neighbours(std::size_t leaf) const;

  /// Whether 2:1 balance keeps a family of leaves (its members' indices) from coarsening: a
  /// member has a finer neighbour, or a same-level one flagged in `refine` (one flag per leaf;
  /// empty: nothing refines).
  bool balance_keeps_family(const std::array<std::size_t, Key::kChildren>& members, std::span<const char> refine = {}) const;

  /// Families whose members are all leaves, found once per leaf set (every coarsen pass asks
  /// about them, leaf by leaf, through the leaf index): for a leaf, its family's child 0 as a
  /// leaf index, or kNoFamily when the leaf is at level 0 or a sibling is not a leaf.
  static constexpr std::size_t kNoFamily = static_cast<std::size_t>(-1);
  std::size_t family_first(std::size_t leaf) const;
  /// The members of the family whose child 0 is leaf `first` (family_first(first) == first), in
  /// child order.
  const std::array<std::size_t, BlockKey<Dim>::kChildren>& family_members(std::size_t first) const;
  /// balance_keeps_family(family_members(first)) with nothing refining: a member has a finer
  /// neighbour (`first` as for family_members).
  bool family_touches_finer(std::size_t first) const;

  /// The families (flags at their child 0, one per leaf) one of whose members has a neighbour
  /// no finer than itself in a family flagged in `flagged` (one flag per leaf, read at each
  /// family's child 0; throws std::invalid_argument for another length). Found from the
  /// flagged families' side (a member's neighbours no coarser than it are those whose
  /// neighbour it is, no finer than them): cheap where few are flagged.
  std::vector<char> families_beside(std::span<const char> flagged) const;

  /// Refine/coarsen by one tag per leaf (in leaves() order), then enforce 2:1 balance.
  AdaptCounts adapt(std::span<const AdaptTag> tags);
  /// What adapt(tags) would do, without doing it: the counts, and the leaves after it in
  /// `next` (unsorted; left empty when nothing would change).
  AdaptCounts adapted_leaves(std::span<const AdaptTag> tags, std::vector<Key>& next) const;
  /// Replaces the leaves by `next` (adapted_leaves' list).
  void assign_leaves(std::vector<Key> next);
  /// Whether leaf i is child 0 of a family whose members are all leaves tagged kCoarsen (what
  /// a coarsening needs, before balance); their leaf indices go to `members` if given.
  bool family_asks_to_coarsen(std::size_t i, std::span<const AdaptTag> tags,
                              std::array<std::size_t, BlockKey<Dim>::kChildren>* members = nullptr) const;

  /// Independent checks (used by tests): 2:1 balance found without assuming it, and the leaves
  /// tile the domain exactly once.
  bool is_balanced() const;
  bool tiles_domain() const;

  /// Position along the configured curve, comparable across levels.
  std::uint64_t curve_index(const Key& key) const;
  /// curve_index of leaf `leaf`: leaves are sorted by (curve index, key).
  std::uint64_t leaf_curve_index(std::size_t leaf) const { return curve_[leaf]; }
  /// P+1 offsets into leaves(): rank r owns [offsets[r], offsets[r+1]); equal chunks but for
  /// cuts moved to the nearer end of a family of leaves they would split (at most 2^Dim / 2).
  std::vector<std::size_t> partition(int ranks) const;

 private:
  void sort_and_index();

  ForestConfig<Dim> config_;
  int curve_bits_ = 0;  // bits per axis of anchors at max_level
  std::vector<Key> leaves_;
  LeafIndex<Dim> index_;
  std::vector<std::uint64_t> curve_;  // per leaf, its curve_index
  mutable std::vector<std::vector<Neighbour<Dim>>> leaf_neighbours_;  // leaf_neighbours' cache
  mutable std::vector<char> leaf_neighbours_known_;
  /// family_first's, family_members' and family_touches_finer's tables (per leaf; the last two
  /// at each family's child 0), built on first use after the leaves change (the last filled in
  /// as families are asked about).
  struct Families {
    bool known = false;
    std::vector<std::size_t> first;
    std::vector<std::array<std::size_t, BlockKey<Dim>::kChildren>> members;
    std::vector<char> touches_finer;
  };
  mutable Families families_;
  const Families& families() const;
};

/// Hilbert index of a point with `bits` bits per coordinate (Skilling's transpose method,
/// AIP Conf. Proc. 707, 2004). Dim = 1 returns the coordinate.
template <int Dim>
std::uint64_t hilbert_index(std::array<std::uint32_t, Dim> point, int bits);

extern template class BlockForest<1>;
extern template class BlockForest<2>;
extern template class BlockForest<3>;

}  // namespace grainwave::wavelet

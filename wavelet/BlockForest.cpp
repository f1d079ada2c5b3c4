#include "wavelet/BlockForest.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace grainwave::wavelet {

namespace {

// The 3^Dim - 1 directions, faces first (fewest nonzero entries), then edges, then corners.
template <int Dim>
std::vector<std::array<int, Dim>> make_directions() {
  std::vector<std::array<int, Dim>> dirs;
  int total = 1;
  for (int a = 0; a < Dim; ++a) total *= 3;
  for (int code = 0; code < total; ++code) {
    std::array<int, Dim> d{};
    int rest = code;
    for (int a = 0; a < Dim; ++a) {
      d[static_cast<std::size_t>(a)] = rest % 3 - 1;
      rest /= 3;
    }
    if (std::any_of(d.begin(), d.end(), [](int v) { return v != 0; })) dirs.push_back(d);
  }
  std::stable_sort(dirs.begin(), dirs.end(), [](const auto& x, const auto& y) {
    auto nonzero = [](const auto& v) { return std::count_if(v.begin(), v.end(), [](int c) { return c != 0; }); };
    return nonzero(x) < nonzero(y);
  });
  return dirs;
}

template <int Dim>
const std::vector<std::array<int, Dim>>& directions() {
  static const auto dirs = make_directions<Dim>();
  return dirs;
}

// Child k of the block beyond `direction` touches the block we came from: along each axis the
// child must sit on the side facing back.
template <int Dim>
bool child_faces_back(int k, const std::array<int, Dim>& direction) {
  for (int a = 0; a < Dim; ++a) {
    const int bit = (k >> a) & 1;
    const int d = direction[static_cast<std::size_t>(a)];
    if ((d == 1 && bit != 0) || (d == -1 && bit != 1)) return false;
  }
  return true;
}

}  // namespace

template <int Dim>
std::uint64_t hilbert_index(std::array<std::uint32_t, Dim> x, int bits) {
  if constexpr (Dim == 1) {
    return x[0];
  } else {
    if (bits <= 0) return 0;
    const std::uint32_t top = 1u << (bits - 1);
    // Undo the excess rotations/reflections from the top bit down (Skilling's AxesToTranspose).
    for (std::uint32_t q = top; q > 1; q >>= 1) {
      const std::uint32_t low = q - 1;
      for (int i = 0; i < Dim; ++i) {
        if (x[static_cast<std::size_t>(i)] & q) {
          x[0] ^= low;
        } else {
          const std::uint32_t swap = (x[0] ^ x[static_cast<std::size_t>(i)]) & low;
          x[0] ^= swap;
          x[static_cast<std::size_t>(i)] ^= swap;
        }
      }
    }
    for (int i = 1; i < Dim; ++i) x[static_cast<std::size_t>(i)] ^= x[static_cast<std::size_t>(i - 1)];
    std::uint32_t gray = 0;
    for (std::uint32_t q = top; q > 1; q >>= 1)
      if (x[Dim - 1] & q) gray ^= q - 1;
    for (auto& c : x) c ^= gray;
    // The transposed form holds the index bits spread over the axes: read them out top-down.
    std::uint64_t h = 0;
    for (int b = bits - 1; b >= 0; --b)
      for (int i = 0; i < Dim; ++i) h = (h << 1) | ((x[static_cast<std::size_t>(i)] >> b) & 1u);
    return h;
  }
}

template <int Dim>
BlockForest<Dim>::BlockForest(ForestConfig<Dim> config) : config_(config) {
  int max_roots = 1;
  for (int r : config.roots) {
    if (r < 1) throw std::invalid_argument("BlockForest: every axis needs at least one root block");
    max_roots = std::max(max_roots, r);
  }
  if (config.max_level < 0) throw std::invalid_argument("BlockForest: negative max_level");
  curve_bits_ = config.max_level + std::bit_width(static_cast<unsigned>(max_roots - 1));
  if (curve_bits_ > Key::kBitsPerAxis || (Dim > 1 && curve_bits_ * Dim > 64))
    throw std::invalid_argument("BlockForest: max_level " + std::to_string(config.max_level) + " with " +
                                std::to_string(max_roots) + " roots per axis does not fit a 64-bit key");
  std::array<std::uint32_t, Dim> c{};
  std::size_t total = 1;
  for (int r : config.roots) total *= static_cast<std::size_t>(r);
  for (std::size_t n = 0; n < total; ++n) {
    std::size_t rest = n;
    for (int a = 0; a < Dim; ++a) {
      const auto r = static_cast<std::size_t>(config.roots[static_cast<std::size_t>(a)]);
      c[static_cast<std::size_t>(a)] = static_cast<std::uint32_t>(rest % r);
      rest /= r;
    }
    leaves_.push_back(Key::from_coords(0, c));
  }
  sort_and_index();
}

template <int Dim>
std::optional<std::size_t> BlockForest<Dim>::find(const Key& key) const {
  return index_.find(key);
}

template <int Dim>
std::optional<BlockKey<Dim>> BlockForest<Dim>::shifted(const Key& key, const std::array<int, Dim>& direction) const {
  auto c = key.coords();
  for (int a = 0; a < Dim; ++a) {
    const auto n = static_cast<std::int64_t>(blocks_along(a, key.level));
    std::int64_t v = static_cast<std::int64_t>(c[static_cast<std::size_t>(a)]) + direction[static_cast<std::size_t>(a)];
    if (v < 0 || v >= n) {
      if (!config_.periodic[static_cast<std::size_t>(a)]) return std::nullopt;
      v = (v % n + n) % n;
    }
    c[static_cast<std::size_t>(a)] = static_cast<std::uint32_t>(v);
  }
  return Key::from_coords(key.level, c);
}

template <int Dim>
void BlockForest<Dim>::neighbours(const Key& leaf, std::vector<Neighbour<Dim>>& out) const {
  out.clear();
  for (const auto& dir : directions<Dim>()) {
    const auto beyond = shifted(leaf, dir);
    if (!beyond) continue;
    if (const auto same = find(*beyond)) {
      out.push_back({*beyond, 0, dir, *same});
    } else if (const auto coarser = leaf.level > 0 ? find(beyond->parent()) : std::nullopt) {
      out.push_back({beyond->parent(), -1, dir, *coarser});
    } else if (leaf.level < config_.max_level) {
      for (int k = 0; k < Key::kChildren; ++k)
        if (child_faces_back<Dim>(k, dir))
          if (const auto finer = find(beyond->child(k))) out.push_back({beyond->child(k), +1, dir, *finer});
    }
  }
}

template <int Dim>
const std::vector<Neighbour<Dim>>& BlockForest<Dim>::leaf_neighbours(std::size_t leaf) const {
  if (leaf_neighbours_known_.size() != leaves_.size()) {  // emptied by sort_and_index
    leaf_neighbours_known_.assign(leaves_.size(), 0);
    if (leaf_neighbours_.size() < leaves_.size()) leaf_neighbours_.resize(leaves_.size());
  }
  if (!leaf_neighbours_known_[leaf]) {
    neighbours(leaves_[leaf], leaf_neighbours_[leaf]);
    leaf_neighbours_known_[leaf] = 1;
  }
  return leaf_neighbours_[leaf];
}

template <int Dim>
const typename BlockForest<Dim>::Families& BlockForest<Dim>::families() const {
  Families& f = families_;
  if (f.known) return f;
  const std::size_t n = leaves_.size();
  f.first.assign(n, kNoFamily);
  f.members.resize(n);
  f.touches_finer.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Key& leaf = leaves_[i];
    if (leaf.level == 0 || leaf.child_index() != 0) continue;
    auto& members = f.members[i];
    bool complete = true;
    for (int k = 0; k < Key::kChildren && complete; ++k) {
      const auto j = find(leaf.parent().child(k));
      complete = j.has_value();
      if (complete) members[static_cast<std::size_t>(k)] = *j;
    }
    if (!complete) continue;
    for (const std::size_t m : members) f.first[m] = i;
  }
  f.known = true;
  return f;
}

template <int Dim>
std::size_t BlockForest<Dim>::family_first(std::size_t leaf) const {
  return families().first[leaf];
}

template <int Dim>
const std::array<std::size_t, BlockKey<Dim>::kChildren>& BlockForest<Dim>::family_members(std::size_t first) const {
  return families().members[first];
}

template <int Dim>
bool BlockForest<Dim>::family_touches_finer(std::size_t first) const {
  const Families& f = families();
  char& known = families_.touches_finer[first];  // 0 not asked yet, 1 no, 2 yes
  if (known == 0) known = balance_keeps_family(f.members[first]) ? 2 : 1;
  return known == 2;
}

template <int Dim>
std::vector<char> BlockForest<Dim>::families_beside(std::span<const char> flagged) const {
  if (flagged.size() != leaves_.size())
    throw std::invalid_argument("BlockForest::families_beside: " + std::to_string(flagged.size()) + " flags for " +
                                std::to_string(leaves_.size()) + " leaves");
  std::vector<char> beside(leaves_.size(), 0);
  for (std::size_t b = 0; b < flagged.size(); ++b) {
    if (!flagged[b] || family_first(b) != b) continue;
    for (const std::size_t m : family_members(b))
      for (const auto& nb : leaf_neighbours(m)) {
        const std::size_t first = nb.level_difference >= 0 ? family_first(nb.leaf) : kNoFamily;
        if (first != kNoFamily) beside[first] = 1;
      }
  }
  return beside;
}

template <int Dim>
bool BlockForest<Dim>::family_asks_to_coarsen(std::size_t i, std::span<const AdaptTag> tags,
                                              std::array<std::size_t, Key::kChildren>* members) const {
  if (tags[i] != AdaptTag::kCoarsen || family_first(i) != i) return false;
  const auto& family = families().members[i];
  for (const std::size_t m : family)
    if (tags[m] != AdaptTag::kCoarsen) return false;
  if (members) *members = family;
  return true;
}

template <int Dim>
AdaptCounts BlockForest<Dim>::adapt(std::span<const AdaptTag> tags) {
  std::vector<Key> next;
  const AdaptCounts counts = adapted_leaves(tags, next);
  if (counts.refined + counts.coarsened > 0) assign_leaves(std::move(next));
  return counts;
}

template <int Dim>
void BlockForest<Dim>::assign_leaves(std::vector<Key> next) {
  leaves_ = std::move(next);
  sort_and_index();
}

template <int Dim>
bool BlockForest<Dim>::balance_keeps_family(const std::array<std::size_t, Key::kChildren>& members,
                                            std::span<const char> refine) const {
  // The parent would touch something finer than the family's level after this refinement.
  for (const std::size_t m : members)
    for (const auto& nb : leaf_neighbours(m))
      if (nb.level_difference == +1 || (nb.level_difference == 0 && !refine.empty() && refine[nb.leaf])) return true;
  return false;
}

template <int Dim>
AdaptCounts BlockForest<Dim>::adapted_leaves(std::span<const AdaptTag> tags, std::vector<Key>& next) const {
  next.clear();
  if (tags.size() != leaves_.size())
    throw std::invalid_argument("BlockForest::adapt: " + std::to_string(tags.size()) + " tags for " +
                                std::to_string(leaves_.size()) + " leaves");
  const std::size_t n = leaves_.size();
  std::vector<char> refine(n, 0);
  std::vector<std::size_t> work;
  for (std::size_t i = 0; i < n; ++i)
    if (tags[i] == AdaptTag::kRefine && leaves_[i].level < config_.max_level) {
      refine[i] = 1;
      work.push_back(i);
    }
  // A refined leaf would sit two levels above a coarser neighbour: refine that one too, and so on.
  while (!work.empty()) {
    const std::size_t i = work.back();
    work.pop_back();
    for (const auto& nb : leaf_neighbours(i)) {
      if (nb.level_difference != -1) continue;
      const std::size_t j = nb.leaf;
      if (!refine[j]) {
        refine[j] = 1;
        work.push_back(j);
      }
    }
  }

  // A family coarsens when all its members are leaves asking for it, none is refined, and the
  // parent would not touch anything finer than the family's level after this refinement.
  std::vector<char> coarsen(n, 0);
  AdaptCounts counts;
  for (std::size_t i = 0; i < n; ++i) {
    std::array<std::size_t, Key::kChildren> members{};
    if (!family_asks_to_coarsen(i, tags, &members)) continue;
    const bool ok = std::none_of(members.begin(), members.end(), [&](std::size_t j) { return refine[j] != 0; }) &&
                    !balance_keeps_family(members, refine);
    if (!ok) continue;
    for (std::size_t j : members) coarsen[j] = 1;
    ++counts.coarsened;
  }

  const auto refined = static_cast<std::size_t>(std::count(refine.begin(), refine.end(), 1));
  if (counts.coarsened == 0 && refined == 0) return counts;  // `next` stays empty
  next.reserve(n + refined * Key::kChildren);
  for (std::size_t i = 0; i < n; ++i) {
    if (refine[i]) {
      for (int k = 0; k < Key::kChildren; ++k) next.push_back(leaves_[i].child(k));
      ++counts.refined;
    } else if (coarsen[i]) {
      if (leaves_[i].child_index() == 0) next.push_back(leaves_[i].parent());
    } else {
      next.push_back(leaves_[i]);
    }
  }
  return counts;
}

template <int Dim>
bool BlockForest<Dim>::is_balanced() const {
  for (const Key& leaf : leaves_) {
    for (const auto& dir : directions<Dim>()) {
      const auto beyond = shifted(leaf, dir);
      if (!beyond) continue;
      int found = -1;
      Key probe = *beyond;
      for (int level = leaf.level; level >= 0; --level, probe = probe.parent()) {
        if (is_leaf(probe)) {
          found = level;
          break;
        }
      }
      if (found >= 0) {
        if (leaf.level - found > 1) return false;
        continue;
      }
      // Covered by finer leaves: those touching us must be leaves one level down, no deeper.
      if (leaf.level == config_.max_level) return false;
      for (int k = 0; k < Key::kChildren; ++k)
        if (child_faces_back<Dim>(k, dir) && !is_leaf(beyond->child(k))) return false;
    }
  }
  return true;
}

template <int Dim>
bool BlockForest<Dim>::tiles_domain() const {
  // Volume in root-block units must add up to the number of roots, and no leaf may lie inside
  // another (an ancestor that is also a leaf), nor outside the box.
  std::vector<double> per_level(static_cast<std::size_t>(config_.max_level + 1), 0.0);
  for (const Key& leaf : leaves_) {
    if (leaf.level < 0 || leaf.level > config_.max_level) return false;
    const auto c = leaf.coords();
    for (int a = 0; a < Dim; ++a)
      if (c[static_cast<std::size_t>(a)] >= blocks_along(a, leaf.level)) return false;
    for (Key up = leaf; up.level > 0;) {
      up = up.parent();
      if (is_leaf(up)) return false;
    }
    per_level[static_cast<std::size_t>(leaf.level)] += 1.0;
  }
  double volume = 0.0;
  for (int l = 0; l <= config_.max_level; ++l) volume += std::ldexp(per_level[static_cast<std::size_t>(l)], -Dim * l);
  double roots = 1.0;
  for (int r : config_.roots) roots *= r;
  return volume == roots && index_.size() == leaves_.size();
}

template <int Dim>
std::uint64_t BlockForest<Dim>::curve_index(const Key& key) const {
  auto anchor = key.coords();
  for (auto& c : anchor) c <<= (config_.max_level - key.level);
  if (config_.curve == CurveOrder::kMorton) return Key::from_coords(config_.max_level, anchor).morton;
  return hilbert_index<Dim>(anchor, curve_bits_);
}

template <int Dim>
std::vector<std::size_t> BlockForest<Dim>::partition(int ranks) const {
  if (ranks < 1) throw std::invalid_argument("BlockForest::partition: need at least one rank");
  std::vector<std::size_t> offsets(static_cast<std::size_t>(ranks) + 1);
  const std::size_t n = leaves_.size();
  auto siblings = [&](std::size_t i) {  // leaves i - 1 and i are siblings
    return leaves_[i].level > 0 && leaves_[i - 1].level == leaves_[i].level && leaves_[i - 1].parent() == leaves_[i].parent();
  };
  for (int r = 0; r <= ranks; ++r) {
    const std::size_t even = n * static_cast<std::size_t>(r) / static_cast<std::size_t>(ranks);
    // Siblings are consecutive on the curve; a cut between two of them moves to the nearer end
    // of their run, so a family of leaves is never split (the coarsen pass of a cycle judges a
    // family's parent from the children's data on one rank, as p4est's partition for
    // coarsening does).
    const std::size_t floor = r > 0 ? offsets[static_cast<std::size_t>(r) - 1] : 0;
    std::size_t at = even;
    if (at > 0 && at < n && siblings(at)) {
      std::size_t back = at, ahead = at;
      while (back > 0 && siblings(back)) --back;
      while (ahead < n && siblings(ahead)) ++ahead;
      at = ahead - at < at - back || back < floor ? ahead : back;
    }
    offsets[static_cast<std::size_t>(r)] = at;
  }
  return offsets;
}

template <int Dim>
void BlockForest<Dim>::sort_and_index() {
  std::vector<std::pair<std::uint64_t, Key>> order;
  order.reserve(leaves_.size());
  for (const Key& k : leaves_) order.emplace_back(curve_index(k), k);
  std::sort(order.begin(), order.end());
  index_.clear(order.size());
  // The leaves' indices change: every cached list is stale, but keeps its storage (a moving
  // grid changes its leaves most cycles, and a fresh list per leaf was a tenth of a 1D cycle).
  // (leaf_neighbours() marks them unknown and sizes the cache on its next call.)
  leaf_neighbours_known_.clear();
  families_.known = false;
  curve_.resize(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    leaves_[i] = order[i].second;
    curve_[i] = order[i].first;
    index_.insert(leaves_[i], i);
  }
}

template std::uint64_t hilbert_index<1>(std::array<std::uint32_t, 1>, int);
template std::uint64_t hilbert_index<2>(std::array<std::uint32_t, 2>, int);
template std::uint64_t hilbert_index<3>(std::array<std::uint32_t, 3>, int);
template class BlockForest<1>;
template class BlockForest<2>;
template class BlockForest<3>;

}  // namespace grainwave::wavelet

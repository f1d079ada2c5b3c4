#pragma once
// The distinct interpolation weights of a ghost plan (AdaptiveGrid::GhostPlan), numbered: a plan
// stores a 16-bit index per term instead of the 8-byte weight. Its terms are products of
// Deslauriers-Dubuc weights and their merged sums, so few are distinct (82 over the 2.1 million
// terms of a 3D sphere's grid), and a fill reads every term's weight: a smaller plan is a
// faster fill where the plan outgrows the caches (docs/design/adaptive-grid-costs.md, stop 44).
#include <bit>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

namespace grainwave::wavelet {

/// Each distinct weight numbered once, in the order first seen: index_of(w) finds or adds w (an
/// open-addressing table on the weight's bits, so a rebuild pays a few nanoseconds a term).
/// Weight 1 is index kOne. A plan built on another takes its table over (build_ghost_plan),
/// so the rows it copies keep their indices.
class WeightTable {
 public:
  static constexpr std::uint16_t kOne = 0;
  WeightTable() { index_of(1.0); }
  double operator[](std::uint16_t index) const { return values_[index]; }
  const double* data() const { return values_.data(); }
  std::uint16_t index_of(double weight) {
    const auto bits = std::bit_cast<std::uint64_t>(weight);
    for (std::size_t at = slot(bits);; at = (at + 1) & (keys_.size() - 1)) {
      if (index_[at] != kNone) {
        if (keys_[at] == bits) return index_[at];
        continue;
      }
      if (values_.size() >= kNone)
        throw std::length_error("AdaptiveGrid: more than 65535 distinct ghost interpolation weights");
      keys_[at] = bits;
      index_[at] = static_cast<std::uint16_t>(values_.size());
      values_.push_back(weight);
      if (2 * values_.size() > keys_.size()) grow();
      return static_cast<std::uint16_t>(values_.size() - 1);
    }
  }

 private:
  static constexpr std::uint16_t kNone = 0xffff;
  std::size_t slot(std::uint64_t bits) const {
    return static_cast<std::size_t>((bits * 0x9e3779b97f4a7c15ULL) >> 40) & (keys_.size() - 1);
  }
  void grow() {
    const std::vector<double> values = std::move(values_);
    keys_.assign(2 * keys_.size(), 0);
    index_.assign(keys_.size(), kNone);
    values_.clear();
    for (const double w : values) index_of(w);
  }
  std::vector<double> values_;
  std::vector<std::uint64_t> keys_ = std::vector<std::uint64_t>(256, 0);
  std::vector<std::uint16_t> index_ = std::vector<std::uint16_t>(256, kNone);
};

}  // namespace grainwave::wavelet

#pragma once
// The rectangular box particles live in, and what happens at each of its six faces.
// Shared by the hard-sphere collider and the DEM. In 2D the z faces are ignored.
#include <Eigen/Core>

#include <array>
#include <limits>

namespace grainwave::particles {

enum class FaceKind {
  kPeriodic,  ///< leaves through this face, re-enters through the opposite one
  kWall,      ///< a rigid plane of infinite mass (collides with particles)
  kOpen,      ///< a particle whose centre leaves the box is removed (and counted)
};

struct Domain {
  int dimension = 3;
  Eigen::Vector3d lo = Eigen::Vector3d::Zero();
  Eigen::Vector3d hi = Eigen::Vector3d::Ones();
  /// face[axis][0] is the low face, face[axis][1] the high face. Periodic faces come in pairs.
  std::array<std::array<FaceKind, 2>, 3> face{{{FaceKind::kPeriodic, FaceKind::kPeriodic},
                                               {FaceKind::kPeriodic, FaceKind::kPeriodic},
                                               {FaceKind::kPeriodic, FaceKind::kPeriodic}}};

  Eigen::Vector3d length() const { return hi - lo; }
  bool periodic(int axis) const { return face[static_cast<std::size_t>(axis)][0] == FaceKind::kPeriodic; }

  /// The minimum image of a difference of positions, with the box read once: for the loops over
  /// many pairs (separation() builds one per call). A component beyond half the period on a
  /// periodic axis moves by one period; the other axes have an infinite half period and never
  /// move. Selects rather than branches: the same values, and no branch to mispredict.
  struct MinimumImage {
    std::array<double, 3> period{0.0, 0.0, 0.0};
    std::array<double, 3> half{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                               std::numeric_limits<double>::infinity()};
    Eigen::Vector3d operator()(Eigen::Vector3d d) const {
      for (int k = 0; k < 3; ++k) {
        const auto ax = static_cast<std::size_t>(k);
        d[k] = d[k] > half[ax] ? d[k] - period[ax] : (d[k] < -half[ax] ? d[k] + period[ax] : d[k]);
      }
      return d;
    }
  };
  MinimumImage minimum_image() const {
    MinimumImage image;
    for (int k = 0; k < dimension; ++k)
      if (periodic(k)) {
        const auto ax = static_cast<std::size_t>(k);
        image.period[ax] = hi[k] - lo[k];
        image.half[ax] = 0.5 * image.period[ax];
      }
    return image;
  }
  /// Minimum-image separation b - a across periodic axes.
  Eigen::Vector3d separation(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const {
    return minimum_image()(b - a);
  }

  /// Maps a position back into [lo, hi) along periodic axes.
  void wrap(Eigen::Vector3d& x) const {
    for (int k = 0; k < dimension; ++k) {
      if (!periodic(k)) continue;
      const double L = hi[k] - lo[k];
      while (x[k] >= hi[k]) x[k] -= L;
      while (x[k] < lo[k]) x[k] += L;
    }
  }

  /// Where wrap() leaves a position as it is: [lo, hi) on the periodic axes, everything on the
  /// others. For a loop over many positions: `if (box.outside(x)) domain.wrap(x)` does what
  /// wrap() does, with three comparisons for the positions that stay (almost all of them)
  /// instead of wrap()'s per-axis loop.
  struct WrapFreeBox {
    Eigen::Vector3d lo, hi;
    bool outside(const Eigen::Vector3d& x) const {
      return ((x.array() < lo.array()) || (x.array() >= hi.array())).any();
    }
  };
  WrapFreeBox wrap_free_box() const {
    WrapFreeBox box{Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity()),
                    Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity())};
    for (int k = 0; k < dimension; ++k)
      if (periodic(k)) {
        box.lo[k] = lo[k];
        box.hi[k] = hi[k];
      }
    return box;
  }
};

}  // namespace grainwave::particles

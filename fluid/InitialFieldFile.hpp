#pragma once
// Initial fields read from a file: density, velocity and pressure sampled on a uniform grid (from
// another code, an experiment's reconstruction, or a script), interpolated onto the adaptive grid.
//
// File format (HDF5, every name at the root):
//   integer attributes  nx, ny (2D, 3D), nz (3D)            samples per axis
//   real attributes     x_lo, x_hi, y_lo, y_hi, z_lo, z_hi  positions of the first and last
//                                                           sample along each axis used
//   real datasets       rho, u, v (2D, 3D), w (3D), p       1D, nx * ny * nz values, x fastest
// An axis with one sample is constant along that axis (a 1D profile fills a 2D domain).
//
// Interpolation: tensor-product Lagrange through the 4 samples around the point (cubic, 4th
// order, matching the solver's 4th-order derivatives), the stencil shifted inwards near the
// first and last samples, fewer points where an axis has fewer than 4 samples; multilinear where
// the cubic would give rho <= 0 or p <= 0 (next to a jump in the data). The samples must cover
// the domain box [lo, hi] of every axis (checked when the file is read, identically on every
// rank, so no rank fails alone later). On a periodic axis the samples may instead be one period
// without the repeated end point (n samples spaced L / n); the stencils then wrap around. The
// thresholding then decides where the adaptive grid needs the detail.
#include <array>
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "core/Error.hpp"

namespace grainwave::fluid {

class InitialFieldFile {
 public:
  /// Reads and checks the file for a `dimension`-D scene on the box [lo, hi] (periodic axes as
  /// flagged); all ranks read it whole. `where` and `key` name the scene entry that gave the path.
  /// Throws InputError (exit code 2) for a missing or malformed file, a missing or mistyped
  /// dataset or attribute, a wrong length, a sample with rho <= 0 or p <= 0 (naming its indices),
  /// or samples that do not cover the box.
  InitialFieldFile(const std::filesystem::path& path, int dimension, const std::array<double, 3>& lo,
                   const std::array<double, 3>& hi, const std::array<bool, 3>& periodic, const InputLocation& where,
                   const std::string& key);

  /// rho, u_0 .. u_{dimension-1}, p at x (x has `dimension` coordinates).
  std::array<double, 5> at(const double* x) const;

  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void fail(const std::string& message) const;
  /// Tensor-product Lagrange through `points` (<= 4) samples per axis around x.
  std::array<double, 5> interpolate(const double* x, int points) const;

  void read(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const std::array<bool, 3>& periodic);

  std::filesystem::path path_;
  std::string key_;
  int dimension_;
  std::array<bool, 3> wrap_{};  ///< periodic axis sampled as one period without its end point
  std::array<int, 3> n_{1, 1, 1};
  std::array<double, 3> lo_{}, hi_{};
  /// Per sample (x fastest): rho, u_0 .. u_{dimension-1}, p, packed.
  std::vector<double> values_;
  int components_ = 3;
};

}  // namespace grainwave::fluid

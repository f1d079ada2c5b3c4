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
// the cubic would give rho <= 0 or p <= 0 (next to a jump in the data). A point outside
// the sampled box (beyond a round-off) is an input error naming the file and the point: the file
// must cover the domain. The thresholding then decides where the adaptive grid needs the detail.
#include <array>
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "core/Error.hpp"

namespace grainwave::fluid {

class InitialFieldFile {
 public:
  /// Reads and checks the file for a `dimension`-D scene (all ranks read it whole). `where` and
  /// `key` name the scene entry that gave the path, for errors about the file as a whole.
  /// Throws InputError (exit code 2) for a missing or malformed file, a missing dataset or
  /// attribute, a wrong length, or a sample with rho <= 0 or p <= 0 (naming its indices).
  InitialFieldFile(const std::filesystem::path& path, int dimension, const InputLocation& where,
                   const std::string& key);

  /// rho, u_0 .. u_{dimension-1}, p at x (x has `dimension` coordinates).
  std::array<double, 5> at(const double* x) const;

  const std::filesystem::path& path() const { return path_; }

 private:
  [[noreturn]] void fail(const std::string& message) const;
  /// Tensor-product Lagrange through `points` (<= 4) samples per axis around x.
  std::array<double, 5> interpolate(const double* x, int points) const;

  std::filesystem::path path_;
  int dimension_;
  std::array<int, 3> n_{1, 1, 1};
  std::array<double, 3> lo_{}, hi_{};
  /// Per sample (x fastest): rho, u_0 .. u_{dimension-1}, p, packed.
  std::vector<double> values_;
  int components_ = 3;
};

}  // namespace grainwave::fluid

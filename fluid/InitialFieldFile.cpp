#include "fluid/InitialFieldFile.hpp"

#include <fmt/format.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>

#include "io/Hdf5.hpp"

namespace grainwave::fluid {

namespace {

constexpr std::array<const char*, 3> kAxis{"x", "y", "z"};
constexpr std::array<const char*, 3> kVelocity{"u", "v", "w"};

}  // namespace

InitialFieldFile::InitialFieldFile(const std::filesystem::path& path, int dimension, const InputLocation& where,
                                   const std::string& key)
    : path_(path), dimension_(dimension), components_(dimension + 2) {
  if (!std::filesystem::exists(path)) throw InputError(where, key, fmt::format("no such file: {}", path.string()));
  // Each rank reads the whole file on its own (initial data are read once).
  const auto file = io::Hdf5File::open_read(path, MPI_COMM_SELF);
  const auto& root = file.root();
  for (int a = 0; a < dimension_; ++a) {
    const auto au = static_cast<std::size_t>(a);
    const std::string count = fmt::format("n{}", kAxis[au]);
    const std::string first = fmt::format("{}_lo", kAxis[au]), last = fmt::format("{}_hi", kAxis[au]);
    for (const auto& name : {count, first, last})
      if (!root.has_attribute(name)) fail(fmt::format("no attribute '{}' (a {}D scene needs n, _lo and _hi for each of its axes)", name, dimension_));
    const auto n = root.integer_attribute(count);
    if (n < 1 || n > (std::int64_t{1} << 30)) fail(fmt::format("attribute '{}' = {} is not a sample count", count, n));
    n_[au] = static_cast<int>(n);
    lo_[au] = root.real_attribute(first);
    hi_[au] = root.real_attribute(last);
    if (!(std::isfinite(lo_[au]) && std::isfinite(hi_[au])) || (n > 1 && !(hi_[au] > lo_[au])))
      fail(fmt::format("'{}' = {} and '{}' = {} do not span an interval", first, lo_[au], last, hi_[au]));
  }
  const std::size_t samples = static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(n_[2]);
  std::vector<std::string> names{"rho"};
  for (int a = 0; a < dimension_; ++a) names.emplace_back(kVelocity[static_cast<std::size_t>(a)]);
  names.emplace_back("p");
  values_.assign(samples * static_cast<std::size_t>(components_), 0.0);
  for (std::size_t c = 0; c < names.size(); ++c) {
    if (!root.has(names[c])) fail(fmt::format("no dataset '{}' (a {}D scene needs {})", names[c], dimension_, fmt::join(names, ", ")));
    const auto shape = root.shape(names[c]);
    if (shape.size() != 1 || shape[0] != samples)
      fail(fmt::format("dataset '{}' must be 1D with nx * ny * nz = {} values", names[c], samples));
    const auto column = root.read_rows_real(names[c], 0, samples);
    for (std::size_t k = 0; k < samples; ++k) values_[k * static_cast<std::size_t>(components_) + c] = column[k];
  }
  for (std::size_t k = 0; k < samples; ++k) {
    const double* w = &values_[k * static_cast<std::size_t>(components_)];
    bool finite = true;
    for (int c = 0; c < components_; ++c) finite = finite && std::isfinite(w[c]);
    if (finite && w[0] > 0 && w[components_ - 1] > 0) continue;
    const std::size_t i = k % static_cast<std::size_t>(n_[0]);
    const std::size_t j = k / static_cast<std::size_t>(n_[0]) % static_cast<std::size_t>(n_[1]);
    const std::size_t l = k / (static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1]));
    fail(fmt::format("sample (i, j, k) = ({}, {}, {}) has {}", i, j, l,
                     !finite ? "a value that is not finite" : w[0] <= 0 ? "rho <= 0" : "p <= 0"));
  }
}

void InitialFieldFile::fail(const std::string& message) const {
  throw InputError({path_.string(), 0}, "", message);
}

std::array<double, 5> InitialFieldFile::at(const double* x) const {
  // Cubics may undershoot next to a jump in the data; where that makes rho or p non-positive,
  // the point takes the (positive) multilinear value instead.
  const auto cubic = interpolate(x, 4);
  if (cubic[0] > 0 && cubic[static_cast<std::size_t>(components_ - 1)] > 0) return cubic;
  return interpolate(x, 2);
}

std::array<double, 5> InitialFieldFile::interpolate(const double* x, int points) const {
  // Per axis: the first sample of the stencil and its Lagrange weights.
  constexpr int kPoints = 4;
  std::array<int, 3> first{}, count{1, 1, 1};
  std::array<std::array<double, kPoints>, 3> weight{};
  for (int a = 0; a < 3; ++a) {
    const auto au = static_cast<std::size_t>(a);
    weight[au] = {1, 0, 0, 0};
    if (a >= dimension_ || n_[au] == 1) continue;
    const double h = (hi_[au] - lo_[au]) / (n_[au] - 1);
    const double s = (x[a] - lo_[au]) / h;  // in sample spacings
    const double slack = 1e-9 * n_[au];
    if (!(s >= -slack && s <= n_[au] - 1 + slack)) {
      std::string point;
      for (int b = 0; b < dimension_; ++b) point += fmt::format("{}{:.9g}", b ? ", " : "", x[b]);
      fail(fmt::format("the domain point ({}) lies outside the sampled box along {} ([{:.9g}, {:.9g}]): the file "
                       "must cover the domain", point, kAxis[au], lo_[au], hi_[au]));
    }
    count[au] = std::min(points, n_[au]);
    first[au] = std::clamp(static_cast<int>(std::floor(s)) - (count[au] - 1) / 2, 0, n_[au] - count[au]);
    for (int m = 0; m < count[au]; ++m) {
      double w = 1;
      for (int q = 0; q < count[au]; ++q)
        if (q != m) w *= (s - (first[au] + q)) / static_cast<double>(m - q);
      weight[au][static_cast<std::size_t>(m)] = w;
    }
  }
  std::array<double, 5> out{};
  for (int k = 0; k < count[2]; ++k)
    for (int j = 0; j < count[1]; ++j)
      for (int i = 0; i < count[0]; ++i) {
        const double w = weight[0][static_cast<std::size_t>(i)] * weight[1][static_cast<std::size_t>(j)] *
                         weight[2][static_cast<std::size_t>(k)];
        const std::size_t sample =
            (static_cast<std::size_t>(first[2] + k) * static_cast<std::size_t>(n_[1]) + static_cast<std::size_t>(first[1] + j)) *
                static_cast<std::size_t>(n_[0]) +
            static_cast<std::size_t>(first[0] + i);
        const double* v = &values_[sample * static_cast<std::size_t>(components_)];
        for (int c = 0; c < components_; ++c) out[static_cast<std::size_t>(c)] += w * v[c];
      }
  return out;
}

}  // namespace grainwave::fluid

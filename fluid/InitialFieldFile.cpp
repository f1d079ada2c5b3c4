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

InitialFieldFile::InitialFieldFile(const std::filesystem::path& path, int dimension, const std::array<double, 3>& lo,
                                   const std::array<double, 3>& hi, const std::array<bool, 3>& periodic,
                                   const InputLocation& where, const std::string& key)
    : path_(path), key_(key), dimension_(dimension), components_(dimension + 2) {
  if (!std::filesystem::exists(path)) throw InputError(where, key, fmt::format("no such file: {}", path.string()));
  try {
    read(lo, hi, periodic);
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {  // HDF5 type conversions, allocation
    fail(fmt::format("cannot read the fields ({})", e.what()));
  }
}

void InitialFieldFile::read(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                            const std::array<bool, 3>& periodic) {
  // Each rank reads the whole file on its own (initial data are read once) and runs the same
  // checks on it, so a bad file stops every rank with the same message.
  const auto file = io::Hdf5File::open_read(path_, MPI_COMM_SELF);
  const auto& root = file.root();
  std::size_t samples = 1;
  for (int a = 0; a < dimension_; ++a) {
    const auto au = static_cast<std::size_t>(a);
    const std::string count = fmt::format("n{}", kAxis[au]);
    const std::string first = fmt::format("{}_lo", kAxis[au]), last = fmt::format("{}_hi", kAxis[au]);
    for (const auto& name : {count, first, last})
      if (!root.has_attribute(name)) fail(fmt::format("no attribute '{}' (a {}D scene needs n, _lo and _hi for each of its axes)", name, dimension_));
    const auto n = root.integer_attribute(count);
    if (n < 1 || n > (std::int64_t{1} << 24)) fail(fmt::format("attribute '{}' = {} is not a sample count (1 .. 2^24)", count, n));
    n_[au] = static_cast<int>(n);
    samples *= static_cast<std::size_t>(n);
    lo_[au] = root.real_attribute(first);
    hi_[au] = root.real_attribute(last);
    if (!(std::isfinite(lo_[au]) && std::isfinite(hi_[au])) || (n > 1 && !(hi_[au] > lo_[au])))
      fail(fmt::format("'{}' = {} and '{}' = {} do not span an interval", first, lo_[au], last, hi_[au]));
    // Coverage of the domain box [lo, hi], up to a round-off of its length.
    const double length = hi[au] - lo[au], slack = 1e-9 * length;
    const double spacing = n > 1 ? (hi_[au] - lo_[au]) / static_cast<double>(n - 1) : 0.0;
    wrap_[au] = periodic[au] && n > 1 && std::abs(static_cast<double>(n) * spacing - length) <= slack &&
                std::abs(lo_[au] - lo[au]) <= slack;
    const bool covers = n == 1 || wrap_[au] || (lo_[au] <= lo[au] + slack && hi_[au] >= hi[au] - slack);
    if (!covers)
      fail(fmt::format("the samples along {} span [{:.9g}, {:.9g}], which does not cover the domain's [{:.9g}, {:.9g}]"
                       "{}", kAxis[au], lo_[au], hi_[au], lo[au], hi[au],
                       periodic[au] ? " (or one period from it without the end point)" : ""));
  }
  if (samples > (std::size_t{1} << 31)) fail(fmt::format("{} samples: more than this reader takes (2^31)", samples));
  std::vector<std::string> names{"rho"};
  for (int a = 0; a < dimension_; ++a) names.emplace_back(kVelocity[static_cast<std::size_t>(a)]);
  names.emplace_back("p");
  for (const auto& name : names) {
    if (!root.has(name)) fail(fmt::format("no dataset '{}' (a {}D scene needs {})", name, dimension_, fmt::join(names, ", ")));
    const auto shape = root.shape(name);
    if (shape.size() != 1 || shape[0] != samples)
      fail(fmt::format("dataset '{}' must be 1D with nx * ny * nz = {} values", name, samples));
  }
  values_.assign(samples * static_cast<std::size_t>(components_), 0.0);
  for (std::size_t c = 0; c < names.size(); ++c) {
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
  throw InputError({path_.string(), 0}, key_, message);
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
    // The constructor checked that the samples cover the domain: points a round-off outside
    // the sampled range are clamped; on a wrapped axis the position is taken modulo the period.
    double s = (x[a] - lo_[au]) / h;  // in sample spacings
    if (wrap_[au]) s -= n_[au] * std::floor(s / n_[au]);
    else s = std::clamp(s, 0.0, static_cast<double>(n_[au] - 1));
    count[au] = std::min(points, n_[au]);
    first[au] = static_cast<int>(std::floor(s)) - (count[au] - 1) / 2;
    if (!wrap_[au]) first[au] = std::clamp(first[au], 0, n_[au] - count[au]);
    for (int m = 0; m < count[au]; ++m) {
      double w = 1;
      for (int q = 0; q < count[au]; ++q)
        if (q != m) w *= (s - (first[au] + q)) / static_cast<double>(m - q);
      weight[au][static_cast<std::size_t>(m)] = w;
    }
  }
  auto index = [&](int axis, int offset) {  // sample index along an axis, wrapped if periodic
    const auto au = static_cast<std::size_t>(axis);
    const int at = first[au] + offset;
    return static_cast<std::size_t>(wrap_[au] ? (at % n_[au] + n_[au]) % n_[au] : at);
  };
  std::array<double, 5> out{};
  for (int k = 0; k < count[2]; ++k)
    for (int j = 0; j < count[1]; ++j)
      for (int i = 0; i < count[0]; ++i) {
        const double w = weight[0][static_cast<std::size_t>(i)] * weight[1][static_cast<std::size_t>(j)] *
                         weight[2][static_cast<std::size_t>(k)];
        const std::size_t sample =
            (index(2, k) * static_cast<std::size_t>(n_[1]) + index(1, j)) * static_cast<std::size_t>(n_[0]) + index(0, i);
        const double* v = &values_[sample * static_cast<std::size_t>(components_)];
        for (int c = 0; c < components_; ++c) out[static_cast<std::size_t>(c)] += w * v[c];
      }
  return out;
}

}  // namespace grainwave::fluid

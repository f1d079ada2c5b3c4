#include "particles/dem/BinStatistics.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace grainwave::particles::dem {

double particle_volume(int dimension, double r) {
  return dimension == 2 ? std::numbers::pi * r * r : 4.0 / 3.0 * std::numbers::pi * r * r * r;
}

BinStatistics::BinStatistics(const Layout& layout) : layout_(layout) {
  const auto n = static_cast<std::size_t>(layout.count[0] * layout.count[1]);
  for (auto* v : {&count_, &volume_, &su_, &sv_, &suu_, &svv_}) v->assign(n, 0.0);
}

double BinStatistics::bin_centre(int axis, long index) const {
  const auto a = static_cast<std::size_t>(axis);
  const double width = (layout_.hi[a] - layout_.lo[a]) / static_cast<double>(layout_.count[a]);
  return layout_.lo[a] + (static_cast<double>(index) + 0.5) * width;
}

void BinStatistics::add_sample(const ParticleStore& store, int dimension,
                               const std::vector<Vec3>& velocity,
                               const std::vector<std::uint8_t>& use) {
  const double wx = (layout_.hi[0] - layout_.lo[0]) / static_cast<double>(layout_.count[0]);
  const double wy = (layout_.hi[1] - layout_.lo[1]) / static_cast<double>(layout_.count[1]);
  for (std::size_t i = 0; i < store.size(); ++i) {
    if (!use[i] || store.is_fixed(i)) continue;
    const Vec3& x = store.position[i];
    const double fx = (x.x() - layout_.lo[0]) / wx, fy = (x.y() - layout_.lo[1]) / wy;
    if (fx < 0 || fy < 0) continue;
    const auto ix = static_cast<long>(fx), iy = static_cast<long>(fy);
    if (ix >= layout_.count[0] || iy >= layout_.count[1]) continue;
    const auto b = static_cast<std::size_t>(iy * layout_.count[0] + ix);
    const Vec3& v = velocity[i];
    count_[b] += 1;
    volume_[b] += particle_volume(dimension, store.radius[i]);
    su_[b] += v.x();
    sv_[b] += v.y();
    suu_[b] += v.x() * v.x();
    svv_[b] += v.y() * v.y();
  }
  ++samples_;
}

double BinStatistics::beta(std::size_t b) const {
  const double wx = (layout_.hi[0] - layout_.lo[0]) / static_cast<double>(layout_.count[0]);
  const double wy = (layout_.hi[1] - layout_.lo[1]) / static_cast<double>(layout_.count[1]);
  return samples_ > 0 ? volume_[b] / (static_cast<double>(samples_) * wx * wy * layout_.depth) : 0.0;
}
double BinStatistics::mean_u(std::size_t b) const { return count_[b] > 0 ? su_[b] / count_[b] : 0.0; }
double BinStatistics::mean_v(std::size_t b) const { return count_[b] > 0 ? sv_[b] / count_[b] : 0.0; }
double BinStatistics::rms_u(std::size_t b) const {
  if (count_[b] <= 0) return 0.0;
  const double m = mean_u(b);
  return std::sqrt(std::max(0.0, suu_[b] / count_[b] - m * m));
}
double BinStatistics::rms_v(std::size_t b) const {
  if (count_[b] <= 0) return 0.0;
  const double m = mean_v(b);
  return std::sqrt(std::max(0.0, svv_[b] / count_[b] - m * m));
}

std::string BinStatistics::csv() const {
  std::string out = "x,y,beta,u_mean,v_mean,u_rms,v_rms,count\n";
  for (long iy = 0; iy < layout_.count[1]; ++iy)
    for (long ix = 0; ix < layout_.count[0]; ++ix) {
      const auto b = static_cast<std::size_t>(iy * layout_.count[0] + ix);
      out += fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{}\n", bin_centre(0, ix),
                         bin_centre(1, iy), beta(b), mean_u(b), mean_v(b), rms_u(b), rms_v(b),
                         static_cast<long>(count_[b]));
    }
  return out;
}

std::vector<double> BinStatistics::raw() const {
  std::vector<double> out;
  for (std::size_t b = 0; b < count_.size(); ++b)
    out.insert(out.end(), {count_[b], volume_[b], su_[b], sv_[b], suu_[b], svv_[b]});
  return out;
}

void BinStatistics::restore(long samples, const std::vector<double>& raw) {
  samples_ = samples;
  for (std::size_t b = 0; b < count_.size() && 6 * b + 5 < raw.size(); ++b) {
    count_[b] = raw[6 * b];
    volume_[b] = raw[6 * b + 1];
    su_[b] = raw[6 * b + 2];
    sv_[b] = raw[6 * b + 3];
    suu_[b] = raw[6 * b + 4];
    svv_[b] = raw[6 * b + 5];
  }
}

}  // namespace grainwave::particles::dem

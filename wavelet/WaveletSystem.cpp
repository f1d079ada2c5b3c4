#include "wavelet/WaveletSystem.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include "core/Mpi.hpp"
#include "io/AtomicFile.hpp"
#include "io/Xdmf.hpp"
#include "wavelet/AdaptiveGrid.hpp"
#include "wavelet/GridCounts.hpp"

namespace grainwave::wavelet {

namespace {

/// The translating profile and its exact x-derivative, with periodic images on periodic axes.
template <int Dim>
struct Profile {
  bool planar = false;  // front: r is the signed distance along x
  std::array<double, Dim> centre{}, velocity{}, length{};
  std::array<bool, Dim> periodic{};
  double radius = 0.25, width = 0.02;

  /// Offset from the centre at time t (minimum image on periodic axes).
  std::array<double, Dim> offset(const std::array<double, Dim>& x, double t) const {
    std::array<double, Dim> d{};
    for (int a = 0; a < Dim; ++a) {
      const auto au = static_cast<std::size_t>(a);
      d[au] = x[au] - (centre[au] + velocity[au] * t);
      if (periodic[au]) d[au] -= length[au] * std::round(d[au] / length[au]);
    }
    return d;
  }
  double distance(const std::array<double, Dim>& x, double t) const {
    const auto d = offset(x, t);
    if (planar) return d[0];
    double r2 = 0;
    for (double c : d) r2 += c * c;
    return std::sqrt(r2) - radius;
  }
  double value(const std::array<double, Dim>& x, double t) const {
    return 0.5 * (1 - std::tanh(distance(x, t) / width));
  }
  double ddx(const std::array<double, Dim>& x, double t) const {
    const double s = 1 / std::cosh(distance(x, t) / width);
    const auto d = offset(x, t);
    double dr_dx = 1;
    if (!planar) {
      double r2 = 0;
      for (double c : d) r2 += c * c;
      dr_dx = r2 > 0 ? d[0] / std::sqrt(r2) : 0;
    }
    return -0.5 * s * s / width * dr_dx;
  }
};

template <int Dim>
class WaveletModel : public io::System {
 public:
  WaveletModel(const Scene& scene);

  std::string describe() const override;
  double max_stable_dt() const override;
  void advance(double t, double dt) override;
  std::optional<std::string> check_state() const override;
  void save_good_state() override {
    keep_copy(good_, *grid_);
    good_stats_ = stats_;
  }
  void restore_good_state() override {
    grid_ = std::make_unique<AdaptiveGrid<Dim>>(*good_);
    stats_ = good_stats_;
  }
  std::vector<io::OutputGrid> write_output(io::Hdf5File& file, const std::string& file_name) override;
  void write_checkpoint(io::Hdf5Group& group) override;
  void read_checkpoint(const io::Hdf5Group& group) override;
  void report(io::Json& counts, io::Json& metrics, double step_wall_s, long steps) const override;
  std::size_t memory_bytes() const override { return 2 * grid_->memory_bytes(); }
  std::string progress_note() const override;

 private:
  struct RunStats {
    double t = 0;
    std::int64_t blocks_max = 0;
    double interface_finest_min = 1;  ///< smallest fraction of interface blocks at max_level
  };
  void after_change();
  double interface_finest_fraction() const;
  ForcedRegion<Dim> forced_region() const;
  void compute_derivative();

  GridConfig<Dim> config_;
  ThresholdConfig threshold_;
  Profile<Dim> profile_;
  bool force_interface_ = false;
  std::unique_ptr<AdaptiveGrid<Dim>> grid_, good_;
  RunStats stats_, good_stats_;
};

template <int Dim>
std::array<double, Dim> head(const std::vector<double>& v) {
  std::array<double, Dim> out{};
  for (int a = 0; a < Dim; ++a) out[static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
  return out;
}

template <int Dim>
WaveletModel<Dim>::WaveletModel(const Scene& scene) {
  const auto& s = scene.section("wavelet");
  config_.lo = head<Dim>(s.reals("lo"));
  config_.hi = head<Dim>(s.reals("hi"));
  const auto& roots = s.integers("roots");
  const auto& bounds = s.texts("boundaries");
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    if (!(config_.hi[au] > config_.lo[au])) s.fail("hi", "the domain needs hi > lo along every axis");
    config_.roots[au] = static_cast<int>(roots[au]);
    config_.periodic[au] = bounds[au] == "periodic";
  }
  config_.block_size = static_cast<int>(s.integer("block_size"));
  if (config_.block_size % 2 != 0) s.fail("block_size", "the block size must be even");
  config_.min_level = static_cast<int>(s.integer("min_level"));
  config_.max_level = static_cast<int>(s.integer("max_level"));
  if (config_.min_level > config_.max_level) s.fail("min_level", "min_level must not exceed max_level");
  config_.order = static_cast<int>(s.integer("order"));
  if (config_.order != 4 && config_.order != 6) s.fail("order", "the interpolation order is 4 or 6");
  config_.derivative_accuracy = static_cast<int>(s.integer("derivative_accuracy"));
  if (config_.derivative_accuracy % 2 != 0) s.fail("derivative_accuracy", "use 2, 4 or 6");
  config_.curve = s.text("curve") == "morton" ? CurveOrder::kMorton : CurveOrder::kHilbert;
  config_.fields = {"u", "dudx"};

  threshold_.epsilon = s.real("epsilon");
  threshold_.normalisation = s.text("normalisation") == "absolute" ? Normalisation::kAbsolute : Normalisation::kLinf;
  threshold_.groups = {0, -1};  // du/dx is diagnosed, not adapted to
  threshold_.adjacent_blocks = s.flag("adjacent_zone");

  profile_.planar = s.text("profile") == "front";
  profile_.centre = head<Dim>(s.reals("centre"));
  profile_.velocity = head<Dim>(s.reals("velocity"));
  profile_.radius = s.real("radius");
  profile_.width = s.real("width");
  for (int a = 0; a < Dim; ++a) {
    const auto au = static_cast<std::size_t>(a);
    profile_.length[au] = config_.hi[au] - config_.lo[au];
    profile_.periodic[au] = config_.periodic[au];
  }
  force_interface_ = s.flag("force_interface");
  try {
    grid_ = std::make_unique<AdaptiveGrid<Dim>>(config_);
  } catch (const std::invalid_argument& e) {
    s.fail("block_size", e.what());
  }
  grid_->adapt_to_function(threshold_, [&](const auto& x, std::span<double> v) { v[0] = profile_.value(x, 0.0); v[1] = 0; },
                           forced_region());
  after_change();
}

template <int Dim>
ForcedRegion<Dim> WaveletModel<Dim>::forced_region() const {
  if (!force_interface_) return {};
  // Blocks within one interface width of the front (the penalization-interface use case).
  return [this](const std::array<double, Dim>& lo, const std::array<double, Dim>& hi) {
    std::array<double, Dim> mid{};
    double half_diagonal = 0;
    for (int a = 0; a < Dim; ++a) {
      const auto au = static_cast<std::size_t>(a);
      mid[au] = 0.5 * (lo[au] + hi[au]);
      half_diagonal += 0.25 * (hi[au] - lo[au]) * (hi[au] - lo[au]);
    }
    return std::abs(profile_.distance(mid, stats_.t)) <= std::sqrt(half_diagonal) + profile_.width;
  };
}

template <int Dim>
void WaveletModel<Dim>::compute_derivative() {
  ScopedTimer timer(timers_, "derivative");
  grid_->first_derivative(0, 0, 1);
}

template <int Dim>
void WaveletModel<Dim>::after_change() {
  compute_derivative();
  stats_.blocks_max = std::max<std::int64_t>(stats_.blocks_max, static_cast<std::int64_t>(grid_->global_blocks()));
  stats_.interface_finest_min = std::min(stats_.interface_finest_min, interface_finest_fraction());
}

template <int Dim>
double WaveletModel<Dim>::interface_finest_fraction() const {
  // Blocks holding a point of the steep part of the profile (0.1 < u < 0.9, exact profile).
  std::int64_t steep = 0, finest = 0;
  const auto shape = grid_->layout().shape();
  const int g = grid_->layout().ghosts;
  for (std::size_t s = 0; s < grid_->local_blocks(); ++s) {
    bool holds = false;
    for (std::size_t p = 0; p < shape.size() && !holds; ++p) {
      auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      bool interior = true;
      for (int& c : i) {
        interior = interior && c >= g && c < g + config_.block_size;
        c -= g;
      }
      if (!interior) continue;
      const double u = profile_.value(grid_->position(s, i), stats_.t);
      holds = u > 0.1 && u < 0.9;
    }
    steep += holds;
    finest += holds && grid_->key(s).level == config_.max_level;
  }
  steep = mpi::sum(steep);
  finest = mpi::sum(finest);
  return steep ? static_cast<double>(finest) / static_cast<double>(steep) : 1.0;
}

template <int Dim>
std::string WaveletModel<Dim>::describe() const {
  return fmt::format("wavelet: {}D adaptive grid, {} {}, blocks of {}^{}, levels {}..{}, DD order {}, "
                     "eps {} ({}), {} blocks",
                     Dim, profile_.planar ? "front" : (Dim == 3 ? "sphere" : "disc"), "translating",
                     config_.block_size, Dim, config_.min_level, config_.max_level, config_.order, threshold_.epsilon,
                     threshold_.normalisation == Normalisation::kLinf ? "normalised" : "absolute", grid_->global_blocks());
}

template <int Dim>
double WaveletModel<Dim>::max_stable_dt() const {
  // The adjacent zone reaches one block ahead: the front may cross at most one finest block.
  double speed = 0;
  for (double v : profile_.velocity) speed = std::max(speed, std::abs(v));
  if (speed == 0) return std::numeric_limits<double>::infinity();
  const auto h = grid_->spacing(config_.max_level);
  return config_.block_size * *std::min_element(h.begin(), h.end()) / speed;
}

template <int Dim>
void WaveletModel<Dim>::advance(double t, double dt) {
  stats_.t = t;
  {
    ScopedTimer timer(timers_, "refine");
    grid_->adapt(threshold_, AdaptPass::kRefine, forced_region());
  }
  stats_.t = t + dt;
  {
    ScopedTimer timer(timers_, "sample");
    grid_->sample([&](const auto& x, std::span<double> v) { v[0] = profile_.value(x, t + dt); v[1] = 0; });
    grid_->fill_ghosts();
  }
  {
    ScopedTimer timer(timers_, "coarsen");
    grid_->adapt(threshold_, AdaptPass::kCoarsen, forced_region());
  }
  after_change();
}

template <int Dim>
std::optional<std::string> WaveletModel<Dim>::check_state() const {
  const auto shape = grid_->layout().shape();
  for (std::size_t s = 0; s < grid_->local_blocks(); ++s) {
    const auto u = grid_->block(0, s);
    for (std::size_t p = 0; p < u.size(); ++p)
      if (!std::isfinite(u[p])) {
        const auto x = grid_->position(s, shape.coords(static_cast<std::ptrdiff_t>(p)));
        return fmt::format("non-finite u in block (level {}, morton {}) near x = {}", grid_->key(s).level,
                           grid_->key(s).morton, x[0]);
      }
  }
  return std::nullopt;
}

/// This rank's blocks of one field, interior points only: rows of Bs^Dim values.
template <int Dim>
std::vector<double> interior_rows(const AdaptiveGrid<Dim>& grid, int field) {
  std::vector<double> rows;
  rows.reserve(grid.local_blocks() * grid.points_per_block());
  const auto shape = grid.layout().shape();
  const int g = grid.layout().ghosts, bs = grid.config().block_size;
  for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
    const auto u = grid.block(field, s);
    for (std::size_t p = 0; p < shape.size(); ++p) {
      const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      bool interior = true;
      for (int c : i) interior = interior && c >= g && c < g + bs;
      if (interior) rows.push_back(u[p]);
    }
  }
  return rows;
}

template <int Dim>
void set_interior_rows(AdaptiveGrid<Dim>& grid, int field, const std::vector<double>& rows) {
  const auto shape = grid.layout().shape();
  const int g = grid.layout().ghosts, bs = grid.config().block_size;
  std::size_t k = 0;
  for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
    auto u = grid.block(field, s);
    for (std::size_t p = 0; p < shape.size(); ++p) {
      const auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
      bool interior = true;
      for (int c : i) interior = interior && c >= g && c < g + bs;
      if (interior) u[p] = rows[k++];
    }
  }
}

/// One block as an XDMF uniform patch whose node arrays are rows of [blocks, Bs^Dim] datasets
/// (HyperSlab selections, so a whole output is a handful of datasets). 1D blocks are shown as
/// one-point-thick 2D patches (XDMF has no 1D structured mesh).
template <int Dim>
std::string block_patch(const AdaptiveGrid<Dim>& grid, std::size_t leaf, const std::string& base,
                        const std::vector<std::pair<std::string, std::string>>& arrays) {
  const auto key = grid.forest().leaves()[leaf];
  const auto x0 = grid.origin(key);
  const auto h = grid.spacing(key.level);
  const int bs = grid.config().block_size;
  const std::size_t n = grid.global_blocks(), per_block = grid.points_per_block();
  std::string dims, org, sp;
  for (int a = std::max(Dim, 2) - 1; a >= 0; --a) {
    const bool real_axis = a < Dim;
    const auto au = static_cast<std::size_t>(std::min(a, Dim - 1));
    dims += fmt::format("{}{}", dims.empty() ? "" : " ", real_axis ? bs : 1);
    org += fmt::format("{}{}", org.empty() ? "" : " ", real_axis ? x0[au] : 0.0);
    sp += fmt::format("{}{}", sp.empty() ? "" : " ", real_axis ? h[au] : 1.0);
  }
  const int shown = std::max(Dim, 2);
  std::string xml = fmt::format(
      "    <Grid Name=\"block_{}\" GridType=\"Uniform\">\n"
      "      <Topology TopologyType=\"{}\" Dimensions=\"{}\"/>\n"
      "      <Geometry GeometryType=\"{}\">\n"
      "        <DataItem Dimensions=\"{}\" Format=\"XML\">{}</DataItem>\n"
      "        <DataItem Dimensions=\"{}\" Format=\"XML\">{}</DataItem>\n"
      "      </Geometry>\n",
      leaf, shown == 3 ? "3DCoRectMesh" : "2DCoRectMesh", dims, shown == 3 ? "ORIGIN_DXDYDZ" : "ORIGIN_DXDY", shown,
      org, shown, sp);
  for (const auto& [name, type] : arrays)
    xml += fmt::format(
        "      <Attribute Name=\"{}\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        "        <DataItem ItemType=\"HyperSlab\" Dimensions=\"{}\" Type=\"HyperSlab\">\n"
        "          <DataItem Dimensions=\"3 2\" Format=\"XML\">{} 0 1 1 1 {}</DataItem>\n"
        "          <DataItem Dimensions=\"{} {}\" NumberType=\"{}\" Precision=\"8\" Format=\"HDF\">{}{}</DataItem>\n"
        "        </DataItem>\n"
        "      </Attribute>\n",
        name, dims, leaf, per_block, n, per_block, type, base, name);
  return xml + "    </Grid>\n";
}

template <int Dim>
std::vector<io::OutputGrid> WaveletModel<Dim>::write_output(io::Hdf5File& file, const std::string& file_name) {
  ScopedTimer timer(timers_, "output");
  auto g = file.root().create_group("wavelet");
  const std::size_t local = grid_->local_blocks(), per_block = grid_->points_per_block();
  for (int f = 0; f < grid_->fields(); ++f) {
    const auto rows = interior_rows(*grid_, f);
    g.write_rows(config_.fields[static_cast<std::size_t>(f)], rows.data(), local, per_block);
  }
  // Per-point copies of the block's level, leaf index and owner, so ParaView can colour by them.
  std::vector<std::int64_t> level, block, rank;
  level.reserve(local * per_block);
  for (std::size_t s = 0; s < local; ++s)
    for (std::size_t p = 0; p < per_block; ++p) {
      level.push_back(grid_->key(s).level);
      block.push_back(static_cast<std::int64_t>(grid_->first_leaf() + s));
      rank.push_back(mpi::rank());
    }
  g.write_rows("level", level.data(), local, per_block);
  g.write_rows("block", block.data(), local, per_block);
  g.write_rows("rank", rank.data(), local, per_block);
  g.set_attribute("dimension", static_cast<std::int64_t>(Dim));
  g.set_attribute("blocks", static_cast<std::int64_t>(grid_->global_blocks()));
  const std::vector<std::pair<std::string, std::string>> arrays = {
      {"u", "Float"}, {"dudx", "Float"}, {"level", "Int"}, {"block", "Int"}, {"rank", "Int"}};
  // All patches go to a sidecar of this output file; the time series only includes it, which
  // keeps the series (stored in checkpoints as an attribute of bounded size) small.
  const std::filesystem::path sidecar = std::filesystem::path(file_name).stem().string() + ".wavelet.xmf";
  if (mpi::is_root()) {
    std::string xml = "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n";
    std::vector<std::string> patches;
    patches.reserve(grid_->global_blocks());
    for (std::size_t l = 0; l < grid_->global_blocks(); ++l)
      patches.push_back(block_patch(*grid_, l, file_name + ":/wavelet/", arrays));
    xml += io::spatial_collection("blocks", patches) + "  </Domain>\n</Xdmf>\n";
    io::write_text_atomically(file.path().parent_path() / sidecar, xml);
  }
  const std::string include = fmt::format(
      "    <Grid Name=\"wavelet\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
      "      <xi:include xmlns:xi=\"http://www.w3.org/2001/XInclude\" href=\"{}\" "
      "xpointer=\"xpointer(//Xdmf/Domain/Grid)\"/>\n"
      "    </Grid>\n",
      sidecar.string());
  return {{"fields", include}};
}

template <int Dim>
void WaveletModel<Dim>::write_checkpoint(io::Hdf5Group& group) {
  auto g = group.create_group("wavelet");
  std::vector<std::int64_t> level, morton;
  for (std::size_t s = 0; s < grid_->local_blocks(); ++s) {
    level.push_back(grid_->key(s).level);
    morton.push_back(static_cast<std::int64_t>(grid_->key(s).morton));  // bit pattern kept
  }
  g.write_rows("key_level", level.data(), level.size());
  g.write_rows("key_morton", morton.data(), morton.size());
  for (int f = 0; f < grid_->fields(); ++f) {
    const auto rows = interior_rows(*grid_, f);
    g.write_rows(config_.fields[static_cast<std::size_t>(f)], rows.data(), grid_->local_blocks(),
                 grid_->points_per_block());
  }
  g.set_attribute("t", stats_.t);
  g.set_attribute("blocks_max", stats_.blocks_max);
  g.set_attribute("interface_finest_min", stats_.interface_finest_min);
}

template <int Dim>
void WaveletModel<Dim>::read_checkpoint(const io::Hdf5Group& group) {
  const auto g = group.open_group("wavelet");
  const auto n = g.shape("key_level")[0];
  const auto level = g.read_rows_integer("key_level", 0, n);
  const auto morton = g.read_rows_integer("key_morton", 0, n);
  std::vector<BlockKey<Dim>> keys(n);
  for (std::size_t k = 0; k < n; ++k)
    keys[k] = {static_cast<int>(level[k]), static_cast<std::uint64_t>(morton[k])};
  grid_->rebuild(keys);
  for (int f = 0; f < grid_->fields(); ++f) {
    const auto rows = g.read_rows_real(config_.fields[static_cast<std::size_t>(f)], grid_->first_leaf(),
                                       grid_->local_blocks());
    set_interior_rows(*grid_, f, rows);
  }
  grid_->fill_ghosts();
  stats_.t = g.real_attribute("t");
  stats_.blocks_max = g.integer_attribute("blocks_max");
  stats_.interface_finest_min = g.real_attribute("interface_finest_min");
}

template <int Dim>
void WaveletModel<Dim>::report(io::Json& counts, io::Json& metrics, double step_wall_s, long steps) const {
  const double uniform = grid_->uniform_points();
  const double points = wavelet::report_grid_counts(*grid_, counts);
  // Error control: reconstruct to the uniform finest grid by prediction, compare with the profile
  // (skipped, reported as -1, where that grid would not fit: over kMaxReconstructionPoints).
  constexpr double kMaxReconstructionPoints = 3e7;
  double err = -1, derr = 0;
  const auto shape = grid_->layout().shape();
  const int g = grid_->layout().ghosts, bs = config_.block_size;
  auto interior_max = [&](const AdaptiveGrid<Dim>& grid, int field, auto&& exact) {
    double m = 0;
    for (std::size_t s = 0; s < grid.local_blocks(); ++s) {
      const auto u = grid.block(field, s);
      for (std::size_t p = 0; p < shape.size(); ++p) {
        auto i = shape.coords(static_cast<std::ptrdiff_t>(p));
        bool interior = true;
        for (int& c : i) {
          interior = interior && c >= g && c < g + bs;
          c -= g;
        }
        if (interior) m = std::max(m, std::abs(u[p] - exact(grid.position(s, i))));
      }
    }
    return mpi::max(m);
  };
  if (uniform <= kMaxReconstructionPoints) {
    AdaptiveGrid<Dim> uniform_grid(*grid_);
    uniform_grid.refine_to_uniform();
    err = interior_max(uniform_grid, 0, [&](const auto& x) { return profile_.value(x, stats_.t); });
  }
  derr = interior_max(*grid_, 1, [&](const auto& x) { return profile_.ddx(x, stats_.t); });
  metrics.set("reconstruction_error", err);
  metrics.set("reconstruction_error_over_eps", err < 0 ? -1.0 : err / threshold_.epsilon);
  metrics.set("derivative_error", derr);
  metrics.set("significant_fraction", static_cast<double>(grid_->significant_points(threshold_)) / uniform);
  metrics.set("points_fraction", points / uniform);
  metrics.set("blocks_max", stats_.blocks_max);
  metrics.set("interface_finest_fraction_min", stats_.interface_finest_min);
  metrics.set("point_steps_per_s", step_wall_s > 0 ? points * static_cast<double>(steps) / step_wall_s : 0.0);
}

template <int Dim>
std::string WaveletModel<Dim>::progress_note() const {
  return fmt::format("blocks {}", grid_->global_blocks());
}

const std::vector<std::string> kBoundaries = {"periodic", "bounded"};

}  // namespace

void WaveletSystem::declare(SceneSchema& schema) {
  auto& s = schema.section("wavelet",
                           "Wavelet-adaptive multiresolution grid alone: a translating front or "
                           "disc/sphere, adapted every step; builds the grid system.");
  s.integer("dimension", 2, "1, 2 or 3").in_range(1, 3);
  s.reals("lo", std::vector<double>{0, 0, 0}, "lower corner of the domain (x, y, z)").of_length(3);
  s.reals("hi", std::vector<double>{1, 1, 1}, "upper corner of the domain").of_length(3);
  s.integers("roots", std::vector<std::int64_t>{1, 1, 1}, "root blocks per axis").of_length(3).in_range(1, 64);
  s.texts("boundaries", std::vector<std::string>{"periodic", "periodic", "periodic"},
          "per axis: periodic, or bounded (one-sided stencils at the edges)")
      .one_of(kBoundaries)
      .of_length(3);
  s.integer("block_size", 8, "collocation points per block and axis (even)").in_range(8, kMaxBlockSize);
  s.integer("min_level", 0, "coarsest level Jmin").in_range(0, 20);
  s.integer("max_level", 4, "finest level Jmax").in_range(0, 20);
  s.integer("order", 4, "Deslauriers-Dubuc interpolation order (4 or 6)").in_range(4, 6);
  s.integer("derivative_accuracy", 4, "order of the finite-difference derivatives (2, 4, 6)").in_range(2, 6);
  s.text("curve", "hilbert", "space-filling curve distributing blocks over ranks").one_of({"hilbert", "morton"});
  s.real("epsilon", 1e-3, "wavelet threshold: significant if |d| > epsilon * scale").above(0).below(1);
  s.text("normalisation", "linf", "scale: linf (global max |u|) or absolute (1)").one_of({"linf", "absolute"});
  s.flag("adjacent_zone", true, "also refine / keep the neighbours of significant blocks");
  s.flag("force_interface", false, "force the blocks on the interface to max_level");
  s.text("profile", "disc", "front (planar tanh along x) or disc (disc in 2D, sphere in 3D)")
      .one_of({"front", "disc"});
  s.reals("centre", std::vector<double>{0.5, 0.5, 0.5}, "initial centre (front: x position)").of_length(3);
  s.reals("velocity", std::vector<double>{0, 0, 0}, "translation velocity").of_length(3);
  s.real("radius", 0.25, "disc/sphere radius").above(0);
  s.real("width", 0.02, "interface thickness w in (1 - tanh(d / w)) / 2").above(0);
}

std::unique_ptr<io::System> WaveletSystem::create(const Scene& scene) {
  switch (scene.section("wavelet").integer("dimension")) {
    case 1: return std::make_unique<WaveletModel<1>>(scene);
    case 2: return std::make_unique<WaveletModel<2>>(scene);
    default: return std::make_unique<WaveletModel<3>>(scene);
  }
}

}  // namespace grainwave::wavelet

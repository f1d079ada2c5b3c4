#include "particles/dem/DemSystem.hpp"

#include "particles/BoxParameters.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <type_traits>

#include "core/Mpi.hpp"
#include "io/AtomicFile.hpp"
#include "io/Xdmf.hpp"
#include "particles/dem/Filling.hpp"
#include "particles/dem/SizeDistribution.hpp"

namespace grainwave::particles::dem {

namespace {


Vec3 vec3(const std::vector<double>& v) { return {v[0], v[1], v[2]}; }

/// Scene keys each law reads, in the LawParameters spelling (scene key -> law key). A law not
/// listed here cannot be configured from a scene yet.
struct LawKeys {
  const char* law;
  std::vector<std::pair<const char*, const char*>> keys;
};
const std::vector<LawKeys> kNormalKeys = {
    {"linear_spring_dashpot", {{"stiffness", "stiffness"}, {"restitution", "restitution"}}},
    {"hertz",
     {{"youngs_modulus", "youngs_modulus"}, {"poisson_ratio", "poisson_ratio"},
      {"restitution", "restitution"}, {"reference_velocity", "reference_velocity"}}}};
const std::vector<LawKeys> kTangentialKeys = {
    {"static_friction", {{"friction", "friction"}, {"regularization_speed", "regularization_speed"}}},
    {"coulomb_spring",
     {{"tangential_stiffness", "stiffness"}, {"friction", "friction"},
      {"tangential_damping", "damping_factor"}}},
    {"mindlin",
     {{"youngs_modulus", "youngs_modulus"}, {"poisson_ratio", "poisson_ratio"},
      {"friction", "friction"}, {"tangential_damping", "damping_factor"}}}};

LawParameters law_parameters(const SceneSection& s, const std::vector<LawKeys>& table,
                             const std::string& law, const char* law_key) {
  for (const auto& entry : table) {
    if (law != entry.law) continue;
    LawParameters p;
    for (const auto& [scene_key, law_name] : entry.keys) {
      double value = s.real(scene_key);
      // k_t = 2/7 k_n by default: tangential and normal oscillations then share one period
      // for a sphere (the usual choice for glass beads, 002 Table 3.1).
      if (std::string(scene_key) == "tangential_stiffness" && value == 0)
        value = 2.0 / 7.0 * s.real("stiffness");
      p.set(law_name, value);
    }
    return p;
  }
  s.fail(law_key, "no scene keys are declared for contact law '" + law + "'");
}

std::vector<std::string> law_names(const std::vector<LawKeys>& table) {
  std::vector<std::string> names;
  for (const auto& e : table) names.emplace_back(e.law);
  return names;
}

double particle_mass(int dimension, double radius, double density) {
  return density * particle_volume(dimension, radius);
}

/// Part of a sphere (3D) or disk (2D, unit depth) of radius r centred at height yc that lies
/// between the planes y = a and y = b.
double volume_in_slab(int dimension, double yc, double r, double a, double b) {
  const double lo = std::max(a, yc - r) - yc, hi = std::min(b, yc + r) - yc;
  if (hi <= lo) return 0.0;
  if (dimension == 3) {
    auto primitive = [r](double s) { return std::numbers::pi * (r * r * s - s * s * s / 3.0); };
    return primitive(hi) - primitive(lo);
  }
  auto primitive = [r](double s) {  // ∫ 2 sqrt(r² − s²) ds
    const double c = std::clamp(s / r, -1.0, 1.0);
    return s * std::sqrt(std::max(0.0, r * r - s * s)) + r * r * std::asin(c);
  };
  return primitive(hi) - primitive(lo);
}

/// Rows of a replicated array: every rank passes the same data, rank 0 writes. An empty array
/// is not written (HDF5 datasets here have at least one row); readers treat absence as empty.
void write_replicated(io::Hdf5Group& g, const std::string& name, const std::vector<double>& flat,
                      std::size_t components) {
  if (flat.empty()) return;
  g.write_rows(name, flat.data(), mpi::is_root() ? flat.size() / components : 0, components);
}
void write_replicated(io::Hdf5Group& g, const std::string& name,
                      const std::vector<std::int64_t>& flat, std::size_t components) {
  if (flat.empty()) return;
  g.write_rows(name, flat.data(), mpi::is_root() ? flat.size() / components : 0, components);
}
/// Rows of an array of which each rank holds its own part (the particles of a distributed
/// store): every rank writes its rows. Not written when empty on every rank.
template <class T>
void write_distributed(io::Hdf5Group& g, const std::string& name, const std::vector<T>& flat,
                       std::size_t components) {
  if (mpi::sum(static_cast<std::int64_t>(flat.size())) == 0) return;
  g.write_rows(name, flat.data(), flat.size() / components, components);
}
/// Replicated or distributed, as the store is.
template <class T>
void write_array(io::Hdf5Group& g, const std::string& name, const std::vector<T>& flat,
                 std::size_t components, bool distributed) {
  if (distributed) write_distributed(g, name, flat, components);
  else write_replicated(g, name, flat, components);
}
std::vector<double> read_all_real(const io::Hdf5Group& g, const std::string& name) {
  if (!g.has(name)) return {};
  return g.read_rows_real(name, 0, g.shape(name)[0]);
}
std::vector<std::int64_t> read_all_integer(const io::Hdf5Group& g, const std::string& name) {
  if (!g.has(name)) return {};
  return g.read_rows_integer(name, 0, g.shape(name)[0]);
}
std::vector<double> flatten(const std::vector<Vec3>& v) {
  std::vector<double> out;
  out.reserve(3 * v.size());
  for (const Vec3& x : v) out.insert(out.end(), {x.x(), x.y(), x.z()});
  return out;
}
std::vector<Vec3> unflatten(const std::vector<double>& flat) {
  std::vector<Vec3> out(flat.size() / 3);
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = Vec3(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
  return out;
}
}  // namespace

void DemSystem::declare(SceneSchema& schema) {
  auto& s = schema.section("dem",
                           "Soft-sphere DEM (002 ch. 3): contact laws, walls, hopper gate, "
                           "settling, recycling drag, flow statistics; SI units.");
  declare_box(s, {" [m]", {0, -9.81, 0}});
  s.text("normal_law", "linear_spring_dashpot", "normal contact law").one_of(law_names(kNormalKeys));
  s.text("tangential_law", "static_friction", "tangential contact law")
      .one_of(law_names(kTangentialKeys));
  s.real("stiffness", 1.0e5, "normal stiffness k_n of the linear law [N/m]").above(0);
  s.real("restitution", 0.9, "coefficient of restitution e (normal laws)").in_range(1e-6, 1);
  s.real("youngs_modulus", 6.3e10, "Young's modulus E (hertz, mindlin) [Pa]").above(0);
  s.real("poisson_ratio", 0.22, "Poisson ratio (hertz, mindlin)").in_range(0, 0.5);
  s.real("reference_velocity", 1.0,
         "impact speed the Hertz contact duration (time step) is sized for [m/s]")
      .above(0);
  s.real("friction", 0.0, "Coulomb friction coefficient mu").at_least(0);
  s.real("tangential_stiffness", 0.0, "k_t of coulomb_spring [N/m]; 0: 2/7 k_n").at_least(0);
  s.real("tangential_damping", 0.0, "tangential damping factor gamma_t (history laws)").at_least(0);
  s.real("regularization_speed", 0.0, "slip speed below which static friction is linear [m/s]")
      .at_least(0);
  s.text("integrator", "velocity_verlet",
         "velocity_verlet (energy-accurate) or runge_kutta2 (002 §3.2.3)")
      .one_of({"velocity_verlet", "runge_kutta2"});
  s.integer("steps_per_collision", 50,
            "N in dt = tau/N, tau the contact duration (Eq. 3.17) of the stiffest, lightest pair")
      .at_least(5);
  s.real("density", 2500.0, "particle material density [kg/m^3]").above(0);
  s.real("diameter", 3.0e-3, "mean particle diameter D [m]").above(0);
  s.real("diameter_std", 0.0, "standard deviation of the Gaussian diameters, cut at ±2 sigma [m]")
      .at_least(0);
  s.text("placement", "random",
         "collision (a head-on pair or particle-wall impact), lattice (square/cubic), "
         "lattice_dense (triangular/fcc), or random (RSA) in the fill box")
      .one_of({"collision", "lattice", "lattice_dense", "random"});
  s.integer("count", 0, "number of particles to place in the fill box").at_least(0);
  s.reals("fill_lo", std::vector<double>{0, 0, 0}, "lower corner of the fill box [m]").of_length(3);
  s.reals("fill_hi", std::vector<double>{0, 0, 0}, "upper corner of the fill box [m]").of_length(3);
  s.integer("seed", 2024, "random seed for sizes and placement");
  s.text("collision_partner", "particle",
         "collision placement: a second particle (x periodic) or the x walls (x faces walls)")
      .one_of({"particle", "wall"});
  s.real("impact_speed", 1.0, "collision placement: normal approach speed [m/s]").above(0);
  s.real("collision_gap", 0.1, "collision placement: initial surface gap over the diameter")
      .above(0);
  s.real("settle_time", 0.0, "settling lasts at least this long before the gate opens [s]")
      .at_least(0);
  s.real("settle_speed", 0.0,
         "settling ends when the rms particle speed is below this (kinetic energy < 1/2 M v^2) "
         "[m/s]")
      .at_least(0);
  s.real("settle_damping", 0.0,
         "viscous damping rate c of the extra force -c m v while settling [1/s]")
      .at_least(0);
  s.real("terminal_velocity", 0.0,
         "recycling drag zone (Eq. 3.18): terminal speed; 0 for no drag zone [m/s]")
      .at_least(0);
  s.reals("drag_lo", std::vector<double>{0, 0, 0}, "lower corner of the drag zone [m]").of_length(3);
  s.reals("drag_hi", std::vector<double>{0, 0, 0}, "upper corner of the drag zone [m]").of_length(3);
  s.real("flow_plane_y", 0.0, "height of the plane the mass flow rate is measured through [m]");
  s.flag("measure_flow", false, "measure the mass flow rate through flow_plane_y (kg/s; per metre in 2D)");
  s.real("flow_start", 0.0, "mass flow measured from this long after the gate opened [s]")
      .at_least(0);
  s.real("flow_end", 0.0, "... until this long after; 0: to the end [s]").at_least(0);
  s.real("flow_record_interval", 0.01,
         "time between rows of flow.csv (t, mass through the plane, mass above it, fill top) "
         "[s]")
      .above(0);
  s.reals("packing_y", std::vector<double>{0, 0},
          "y range of the slab whose solid fraction is reported as packing_fraction (equal: "
          "none) [m]")
      .of_length(2);
  s.real("max_overlap", 0.5, "largest overlap over the radius before the run stops as failed")
      .above(0);
  s.real("neighbour_skin", 0.1,
         "Verlet list: pairs closer than contact plus this fraction of the largest diameter are "
         "listed, and the list is rebuilt only once a particle has moved half of it (0: cell "
         "search at every step)")
      .at_least(0)
      .at_most(1);
  s.text("decomposition", "slabs",
         "on more than one MPI rank: slabs (each rank owns the particles of a slab along "
         "decomposition_axis, with ghosts of its neighbours) or replicated (every rank steps all)")
      .one_of({"slabs", "replicated"});
  s.text("decomposition_axis", "x", "axis cut into slabs (balanced by particle count)")
      .one_of({"x", "y", "z"});
  s.integer("rebalance_every", 1000,
            "slabs: steps between re-cuts balancing the particle count (0: only at the start)")
      .at_least(0);

  auto& w = schema.section("dem_wall",
                           "A wall of the DEM: an infinite plane or a segment of the x-y plane "
                           "(extruded through z), smooth or rough, possibly the removable gate.",
                           true);
  w.text("kind", "segment", "segment (from a to b in x-y) or plane (point, normal)")
      .one_of({"segment", "plane"});
  w.reals("a", std::vector<double>{0, 0}, "segment start (x, y) [m]").of_length(2);
  w.reals("b", std::vector<double>{1, 0}, "segment end (x, y) [m]").of_length(2);
  w.reals("point", std::vector<double>{0, 0, 0}, "a point of the plane [m]").of_length(3);
  w.reals("normal", std::vector<double>{0, 1, 0}, "plane normal, towards the particles")
      .of_length(3);
  w.flag("gate", false, "the plate closing the hopper: removed when the fill has settled");
  w.flag("rough", false, "a layer of fixed particles on the segment instead of a smooth wall");
  w.real("rough_diameter", 0.0, "diameter of the rough-wall particles; 0: dem.diameter")
      .at_least(0);

  auto& st = schema.section("dem_statistics",
                            "Time-averaged bin statistics of the DEM flow (beta, <u>, <v>, u', "
                            "v'); written to HDF5 and statistics.csv.");
  st.reals("lo", std::nullopt, "lower corner (x, y) of the bins [m]").of_length(2);
  st.reals("hi", std::nullopt, "upper corner (x, y) of the bins [m]").of_length(2);
  st.integers("bins", std::vector<std::int64_t>{20, 20}, "bins along x and y").of_length(2);
  st.real("start", 0.0, "first sample this long after the gate opened [s]").at_least(0);
  st.real("interval", 1.0 / 30.0, "time between samples (the camera interval, 30 fps) [s]")
      .above(0);
  st.text("velocity", "displacement",
          "instantaneous velocities, or displacements over one sample interval (PTV)")
      .one_of({"instantaneous", "displacement"});
  st.reals("beta_window", std::vector<double>{0, 0, 0, 0},
           "x0, x1, y0, y1 of the window whose mean solid fraction is beta_below_slit [m]")
      .of_length(4);

  auto& c = schema.section("dem_curtain",
                           "Writes curtain_state.h5 (particles in a window below the slit + the "
                           "bin profiles) with every output after the gate opened.");
  c.reals("window", std::nullopt, "y range (low, high) of the particles written [m]").of_length(2);
}

DemSystem::DemSystem(const Scene& scene) : scene_(scene) {
  const auto& s = scene.section("dem");
  domain_ = read_box(s, gravity_);
  if (domain_.dimension == 2) domain_.lo.z() = domain_.hi.z() = 0.0;  // disks live at z = 0
  density_ = s.real("density");
  read_contact_model(s);
  runge_kutta_ = s.text("integrator") == "runge_kutta2";
  steps_per_collision_ = static_cast<int>(s.integer("steps_per_collision"));
  settle_time_ = s.real("settle_time");
  settle_speed_ = s.real("settle_speed");
  settle_damping_ = s.real("settle_damping");
  measure_flow_ = s.flag("measure_flow");
  flow_plane_ = s.real("flow_plane_y");
  flow_start_ = s.real("flow_start");
  flow_end_ = s.real("flow_end");
  flow_record_interval_ = s.real("flow_record_interval");
  flow_csv_ = "t,drained_mass,mass_above_plane,fill_top\n";
  max_overlap_ratio_ = s.real("max_overlap");
  const auto& packing = s.reals("packing_y");
  if (packing[1] > packing[0]) packing_window_ = std::array<double, 2>{packing[0], packing[1]};

  ContactForceSettings settings;
  settings.gravity = gravity_;
  if (s.real("terminal_velocity") > 0) {
    if (gravity_.norm() == 0) s.fail("terminal_velocity", "the drag zone needs gravity");
    const Vec3 lo = vec3(s.reals("drag_lo")), hi = vec3(s.reals("drag_hi"));
    bool empty = false;
    for (int k = 0; k < domain_.dimension; ++k) empty = empty || hi[k] <= lo[k];
    if (empty)
      s.fail("drag_hi", "the drag zone needs drag_hi > drag_lo along every axis");
    settings.drag_zones.push_back(RecyclingDragZone::from_terminal_velocity(
        lo, hi, gravity_.norm(), s.real("terminal_velocity")));
  }
  field_ = std::make_unique<ContactForceField>(model_, domain_, settings);
  build_walls(scene);
  place_particles(scene);
  if (mobile_count() == 0) s.fail("count", "the scene places no moving particle");
  dt_ = stable_time_step(store_, *model_.normal, steps_per_collision_);

  if (scene.has("dem_statistics")) {
    const auto& st = scene.section("dem_statistics");
    BinStatistics::Layout layout;
    for (std::size_t a = 0; a < 2; ++a) {
      layout.lo[a] = st.reals("lo")[a];
      layout.hi[a] = st.reals("hi")[a];
      layout.count[a] = st.integers("bins")[a];
      if (layout.count[a] < 1) st.fail("bins", "needs at least one bin per axis");
      if (layout.hi[a] <= layout.lo[a]) st.fail("hi", "needs hi > lo");
    }
    layout.depth = domain_.dimension == 3 ? domain_.length().z() : 1.0;
    bins_ = BinStatistics(layout);
    statistics_ = true;
    stats_start_ = st.real("start");
    stats_interval_ = st.real("interval");
    displacement_velocity_ = st.text("velocity") == "displacement";
    const auto& wnd = st.reals("beta_window");
    std::copy(wnd.begin(), wnd.end(), beta_window_.begin());
    if (beta_window_[1] < beta_window_[0] || beta_window_[3] < beta_window_[2])
      st.fail("beta_window", "needs x0 <= x1 and y0 <= y1");
  }
  if (scene.has("dem_curtain")) {
    const auto& c = scene.section("dem_curtain");
    curtain_ = true;
    curtain_window_ = {c.reals("window")[0], c.reals("window")[1]};
    if (curtain_window_[1] <= curtain_window_[0]) c.fail("window", "needs low < high");
    if (!statistics_) c.fail("window", "the curtain state needs a [dem_statistics] section");
  }

  // Settling phase: while the gate is closed or a settling criterion is set.
  const bool settles = has_gate_ || settle_time_ > 0 || settle_speed_ > 0;
  tally_.settling = settles ? 1 : 0;
  tally_.opened_at = settles ? -1 : 0;
  if (settles && settle_speed_ == 0 && settle_time_ == 0)
    s.fail("settle_time", "a gate needs settle_time or settle_speed to know when to open");
  apply_settling_forces();
  initial_energy_ = mobile_kinetic_energy();
  initial_mobile_ = mobile_count();
  global_mobile_ = initial_mobile_;
  initial_fixed_ = static_cast<std::int64_t>(store_.size()) - initial_mobile_;

  // The cell grid is fixed by the whole fill, so that every rank, and any number of ranks,
  // searches on the grid of the serial run (and so meets the pairs in its order).
  double largest = 0;
  for (double r : store_.radius) largest = std::max(largest, r);
  field_->settings().cell_width = 2 * largest;
  field_->settings().grid_particles = store_.size();
  skin_ = s.real("neighbour_skin") * 2 * largest;
  field_->settings().verlet_skin = skin_;
  field_->settings().verlet_managed = skin_ > 0;
  const bool slabs = s.text("decomposition") == "slabs";
  if (mpi::size() > 1 && slabs && placement_ != Placement::kCollision) {
    const std::string axis_name = s.text("decomposition_axis");
    const int axis = axis_name[0] - 'x';
    if (axis >= domain_.dimension)
      s.fail("decomposition_axis", "a 2D scene is cut along x or y");
    auto cuts = SlabDecomposition::balanced_cuts(domain_, axis, store_, mpi::size());
    // A Verlet list keeps its ghosts until the next build: they reach a skin further.
    decomposition_ = SlabDecomposition(domain_, axis, cuts, 2 * largest + skin_);
    decomposition_.keep_owned(store_);
    distributed_ = true;
    rebalance_every_ = s.integer("rebalance_every");
    std::string list;
    for (double c : cuts) list += fmt::format("{}{:.4g}", list.empty() ? "" : ", ", c);
    decomposition_note_ = fmt::format(", {} slabs along {} (cuts {})", mpi::size(), axis_name, list);
  } else if (mpi::size() > 1) {
    decomposition_note_ = placement_ == Placement::kCollision
                              ? ", replicated on every rank (collision placement)"
                              : ", replicated on every rank";
  }
  y_before_.reserve(store_.size());
}

void DemSystem::read_contact_model(const SceneSection& s) {
  normal_name_ = s.text("normal_law");
  tangential_name_ = s.text("tangential_law");
  restitution_target_ = s.real("restitution");
  model_ = make_contact_model(normal_name_, law_parameters(s, kNormalKeys, normal_name_, "normal_law"),
                              tangential_name_,
                              law_parameters(s, kTangentialKeys, tangential_name_, "tangential_law"));
}

void DemSystem::build_walls(const Scene& scene) {
  const auto& s = scene.section("dem");
  const double depth = domain_.dimension == 3 ? domain_.length().z() : 0.0;
  const double z_mid = 0.5 * (domain_.lo.z() + domain_.hi.z());
  for (const auto& e : scene.entries("dem_wall")) {
    if (e.text("kind") == "plane") {
      PlaneWall wall;
      wall.point = vec3(e.reals("point"));
      const Vec3 n = vec3(e.reals("normal"));
      if (n.norm() == 0) e.fail("normal", "the plane normal must not be zero");
      wall.normal = n.normalized();
      if (e.flag("rough")) e.fail("rough", "rough walls are segments");
      if (e.flag("gate")) e.fail("gate", "the gate is a segment");
      field_->plane_walls().push_back(wall);
      continue;
    }
    const Vec3 a(e.reals("a")[0], e.reals("a")[1], domain_.dimension == 3 ? z_mid : 0.0);
    const Vec3 b(e.reals("b")[0], e.reals("b")[1], domain_.dimension == 3 ? z_mid : 0.0);
    if ((b - a).norm() == 0) e.fail("b", "the segment has zero length");
    if (e.flag("rough")) {
      if (e.flag("gate")) e.fail("rough", "the gate must be smooth");
      const double d = e.real("rough_diameter") > 0 ? e.real("rough_diameter") : s.real("diameter");
      const double r = 0.5 * d;
      Vec3 origin = a;
      if (domain_.dimension == 3) origin.z() = domain_.lo.z() + 0.5 * r;
      // Rough walls carry ids from 2^40 on, far above any fill, in wall order.
      const std::int64_t first_id = (std::int64_t{1} << 40) + static_cast<std::int64_t>(store_.size());
      add_rough_wall_layer(store_, domain_.dimension, origin, (b - a).normalized(), Vec3::UnitZ(),
                           (b - a).norm(), domain_.dimension == 3 ? depth - r : 0.0, r,
                           particle_mass(domain_.dimension, r, density_), first_id);
      rough_segments_.push_back({a, b, r});
      continue;
    }
    FiniteWall wall = domain_.dimension == 3
                          ? FiniteWall::rectangle(0.5 * (a + b), b - a, Vec3::UnitZ(),
                                                  (b - a).norm(), depth + 4 * s.real("diameter"))
                          : FiniteWall::segment(a, b);
    if (e.flag("gate")) {
      gate_walls_.push_back(field_->finite_walls().size());
      has_gate_ = true;
    }
    field_->finite_walls().push_back(wall);
  }
}

void DemSystem::place_particles(const Scene& scene) {
  const auto& s = scene.section("dem");
  const int dim = domain_.dimension;
  const std::string placement = s.text("placement");
  const double diameter = s.real("diameter");
  // Rough-wall particles were added first; the fill goes in front of them so ids stay sorted.
  ParticleStore rough = store_;
  store_.clear();
  auto add = [&](std::int64_t id, const Vec3& x, const Vec3& v, double d) {
    const double r = 0.5 * d, m = particle_mass(dim, r, density_);
    store_.add(id, x, v, Vec3::Zero(), r, m, solid_inertia(dim, m, r));
  };
  if (placement == "collision") {
    placement_ = Placement::kCollision;
    wall_partner_ = s.text("collision_partner") == "wall";
    const double gap = s.real("collision_gap") * diameter, v = s.real("impact_speed");
    Vec3 centre = 0.5 * (domain_.lo + domain_.hi);
    const FaceKind x_lo = domain_.face[0][0];
    if (wall_partner_) {
      if (x_lo != FaceKind::kWall || domain_.face[0][1] != FaceKind::kWall)
        s.fail("collision_partner", "a particle-wall collision needs walls at both x faces",
               "set dem.boundary_x = [\"wall\", \"wall\"]");
      centre.x() = domain_.lo.x() + 0.5 * diameter + gap;
      add(0, centre, Vec3(-v, 0, 0), diameter);
    } else {
      if (x_lo != FaceKind::kPeriodic)
        s.fail("collision_partner", "a particle-particle collision needs a periodic x axis",
               "set dem.boundary_x = [\"periodic\", \"periodic\"]");
      if (domain_.length().x() - 2 * diameter - gap <= 0)
        s.fail("box_hi", "the box is too short in x for the pair and its gap");
      add(0, centre - Vec3(0.5 * (diameter + gap), 0, 0), Vec3(0.5 * v, 0, 0), diameter);
      add(1, centre + Vec3(0.5 * (diameter + gap), 0, 0), Vec3(-0.5 * v, 0, 0), diameter);
    }
    tally_.previous_gap = surface_gap();
  } else {
    placement_ = placement == "random" ? Placement::kRandom : Placement::kLattice;
    const auto count = static_cast<std::size_t>(s.integer("count"));
    std::mt19937_64 rng(static_cast<std::uint64_t>(s.integer("seed")));
    TruncatedGaussianDiameter sizes(diameter, s.real("diameter_std"));
    if (sizes.smallest() <= 0) s.fail("diameter_std", "2 sigma must be smaller than the diameter");
    FillRequest request;
    request.dimension = dim;
    request.lo = vec3(s.reals("fill_lo"));
    request.hi = vec3(s.reals("fill_hi"));
    request.dense = placement == "lattice_dense";
    if (dim == 2) request.lo.z() = request.hi.z() = 0.0;
    for (int k = 0; k < dim; ++k)
      if (request.hi[k] < request.lo[k]) s.fail("fill_hi", "needs fill_hi >= fill_lo");
    for (std::size_t i = 0; i < count; ++i) request.diameters.push_back(sizes(rng));
    // Centres a largest radius inside the box: no particle overlaps a face wall or, through a
    // periodic face, the image of another (the fill itself does not look across faces).
    for (int k = 0; k < dim; ++k)
      if (request.lo[k] < domain_.lo[k] + 0.5 * sizes.largest() ||
          request.hi[k] > domain_.hi[k] - 0.5 * sizes.largest())
        s.fail("fill_lo", "the fill box must keep the largest radius from every box face");
    FillObstacles obstacles;
    obstacles.planes = field_->plane_walls();
    for (const FiniteWall& w : field_->finite_walls()) {
      obstacles.finite.push_back(w);
      obstacles.finite_clearance.push_back(0.0);
    }
    for (const auto& rs : rough_segments_) {
      obstacles.finite.push_back(FiniteWall::segment(rs.a, rs.b));
      obstacles.finite_clearance.push_back(rs.radius);
    }
    if (dim == 3)  // segments of rough walls stand for the whole depth: compare in x-y only
      for (std::size_t k = field_->finite_walls().size(); k < obstacles.finite.size(); ++k)
        obstacles.finite[k] = FiniteWall::rectangle(obstacles.finite[k].centre,
                                                    obstacles.finite[k].axis[0], Vec3::UnitZ(),
                                                    2 * obstacles.finite[k].half_extent[0],
                                                    domain_.length().z() + 4 * diameter);
    const auto centres = placement_ == Placement::kLattice
                             ? lattice_fill(request, obstacles, rng)
                             : random_sequential_addition(request, obstacles, rng);
    if (centres.size() < count)
      s.fail("count", fmt::format("only {} of {} particles fit in the fill box", centres.size(), count),
             "enlarge fill_lo..fill_hi or lower count");
    for (std::size_t i = 0; i < count; ++i)
      add(static_cast<std::int64_t>(i), centres[i], Vec3::Zero(), request.diameters[i]);
  }
  for (std::size_t i = 0; i < rough.size(); ++i) store_.append_from(rough, i);
}

double DemSystem::surface_gap() const {
  if (placement_ != Placement::kCollision || store_.empty()) return 0.0;
  if (wall_partner_) {
    const double x = store_.position[0].x(), r = store_.radius[0];
    return std::min(x - domain_.lo.x() - r, domain_.hi.x() - x - r);
  }
  const Vec3 d = domain_.separation(store_.position[0], store_.position[1]);
  return d.norm() - store_.radius[0] - store_.radius[1];
}

std::string DemSystem::describe() const {
  // The counts of the scene as placed (describe() is not collective).
  return fmt::format(
      "DEM: {} {} ({} fixed), {} + {}, {}, dt = {:.4g} s (tau/{}), {}, {} walls{}{}", initial_mobile_,
      domain_.dimension == 3 ? "spheres" : "disks", initial_fixed_, normal_name_, tangential_name_,
      runge_kutta_ ? "RK2" : "velocity Verlet", dt_, steps_per_collision_,
      skin_ > 0 ? fmt::format("Verlet list (skin {:.3g} m)", skin_) : "cell search every step",
      field_->plane_walls().size() + field_->finite_walls().size(), has_gate_ ? ", gate" : "",
      decomposition_note_);
}

double DemSystem::global_sum(double local) const { return distributed_ ? mpi::sum(local) : local; }
std::int64_t DemSystem::global_sum(std::int64_t local) const {
  return distributed_ ? mpi::sum(local) : local;
}

BinStatistics DemSystem::global_bins() const {
  if (!distributed_) return bins_;
  std::vector<double> raw = bins_.raw();
  mpi::sum_in_place(raw);
  BinStatistics all = bins_;
  all.restore(bins_.samples(), raw);
  return all;
}

void DemSystem::migrate_particles() {
  ScopedTimer timer(timers_, "migration");
  const bool forces = !runge_kutta_ && verlet_.has_forces();
  decomposition_.migrate(store_, forces ? &verlet_.stored_forces() : nullptr,
                         forces ? &verlet_.stored_torques() : nullptr,
                         model_.tangential->needs_history() ? &field_->history() : nullptr);
}

std::vector<double> DemSystem::tally_partials() const {
  return {static_cast<double>(tally_.removed), tally_.removed_mass, tally_.flow_mass,
          tally_.flow_mass_total, tally_.particle_steps, tally_.beta_volume};
}

void DemSystem::set_tally_partials(const std::vector<double>& p) {
  tally_.removed = static_cast<std::int64_t>(p[0]);
  tally_.removed_mass = p[1];
  tally_.flow_mass = p[2];
  tally_.flow_mass_total = p[3];
  tally_.particle_steps = p[4];
  tally_.beta_volume = p[5];
}

std::int64_t DemSystem::mobile_count() const {
  std::int64_t n = 0;
  for (std::size_t i = 0; i < store_.size(); ++i) n += store_.is_fixed(i) ? 0 : 1;
  return n;
}

double DemSystem::mobile_kinetic_energy() const {
  double e = 0;
  for (std::size_t i = 0; i < store_.size(); ++i) {
    if (store_.is_fixed(i)) continue;
    e += 0.5 * store_.mass[i] * store_.velocity[i].squaredNorm() +
         0.5 * store_.inertia[i] * store_.angular_velocity[i].squaredNorm();
  }
  return e;
}

void DemSystem::apply_settling_forces() {
  const double c = tally_.settling ? settle_damping_ : 0.0;
  for (std::size_t i = 0; i < store_.size(); ++i)
    store_.force[i] = -c * store_.mass[i] * store_.velocity[i];
  for (std::size_t w : gate_walls_) field_->finite_walls()[w].enabled = tally_.settling != 0;
}

void DemSystem::finish_settling_if_done() {
  if (!tally_.settling || tally_.time < settle_time_ * (1 - 1e-12)) return;
  double mass = 0, momentum2 = 0;
  for (std::size_t i = 0; i < store_.size(); ++i) {
    if (store_.is_fixed(i)) continue;
    mass += store_.mass[i];
    momentum2 += store_.mass[i] * store_.velocity[i].squaredNorm();
  }
  mass = global_sum(mass);
  momentum2 = global_sum(momentum2);
  const double rms_speed = mass > 0 ? std::sqrt(momentum2 / mass) : 0.0;
  if (rms_speed > settle_speed_ && settle_speed_ > 0) return;
  tally_.settling = 0;
  tally_.opened_at = tally_.time;
  tally_.next_sample = tally_.time + stats_start_;
  apply_settling_forces();
}

void DemSystem::prepare_neighbour_list(double dt, const BeforeEvaluation& refresh) {
  const long outran = prepare_listed_step(store_, *field_, runge_kutta_ ? nullptr : &verlet_, dt,
                                          distributed_, [this] { rebuild_neighbour_list(); },
                                          refresh, ahead_);
  if (outran >= 0)
    skin_failure_ = fmt::format(
        "particle id {} moves {:.3g} m within one step, more than half the neighbour skin "
        "({:.3g} m): raise dem.neighbour_skin or dem.steps_per_collision",
        store_.id[static_cast<std::size_t>(outran)], ahead_[static_cast<std::size_t>(outran)].norm(), skin_);
}

void DemSystem::rebuild_neighbour_list() {
  ScopedTimer timer(timers_, "neighbour_list");
  // After a restart the writer's reference positions stand in for the present ones: they give
  // the ghost set and the list the writer had (the particles already sit in their slabs).
  const bool from_reference = !restart_reference_.empty() && restart_reference_.size() == store_.size();
  if (from_reference) std::swap(store_.position, restart_reference_);
  if (distributed_) {
    if (!from_reference) {
      if (rebalance_every_ > 0 && tally_.steps_since_balance >= rebalance_every_) {
        decomposition_.set_cuts(decomposition_.rebalanced_cuts(store_));
        tally_.steps_since_balance = 0;
      }
      migrate_particles();
    }
    ScopedTimer exchange_timer(timers_, "ghost_exchange");
    decomposition_.exchange_ghosts(store_);
  }
  field_->build_list(store_);
  if (distributed_) SlabDecomposition::strip_ghosts(store_);
  if (from_reference) std::swap(store_.position, restart_reference_);
  restart_reference_.clear();
}

void DemSystem::advance(double /*t*/, double dt) {
  if (tally_.settling && settle_damping_ > 0) apply_settling_forces();
  {
    ScopedTimer timer(timers_, "contacts_and_integration");
    BeforeEvaluation ghosts;
    if (distributed_ && skin_ > 0)
      ghosts = [this](ParticleStore& store) {
        ScopedTimer exchange_timer(timers_, "ghost_exchange");
        decomposition_.refresh_ghosts(store);
      };
    else if (distributed_)
      ghosts = [this](ParticleStore& store) {
        ScopedTimer exchange_timer(timers_, "ghost_exchange");
        decomposition_.exchange_ghosts(store);
      };
    if (skin_ > 0) prepare_neighbour_list(dt, ghosts);  // may migrate particles
    const std::size_t n = store_.size();
    y_before_.resize(n);
    for (std::size_t i = 0; i < n; ++i) y_before_[i] = store_.position[i].y();
    if (runge_kutta_) rk2_.step(store_, *field_, dt, ghosts);
    else verlet_.step(store_, *field_, dt, ghosts);
    if (distributed_) SlabDecomposition::strip_ghosts(store_);
  }
  tally_.particle_steps += static_cast<double>(mobile_count());
  const double t_start = tally_.time;
  tally_.time += dt;
  if (measure_flow_ && tally_.opened_at >= 0) {
    const double since = t_start - tally_.opened_at;
    const double before = tally_.flow_mass;
    measure_flow(dt);
    const bool in_window = since >= flow_start_ * (1 - 1e-12) && (flow_end_ == 0 || since < flow_end_);
    tally_.flow_mass_total += tally_.flow_mass - before;
    if (!in_window) tally_.flow_mass = before;
    else tally_.flow_time += dt;
  }
  if (measure_flow_ && tally_.time >= tally_.next_flow_record * (1 - 1e-12)) record_flow();
  if (placement_ == Placement::kCollision) probe_collision(dt);
  remove_leaving_particles();
  if (distributed_) {
    // Re-cut the slabs now and then, so that a bed that settles or drains stays balanced; the
    // cuts follow from the positions alone, the same on every rank and in every run.
    // With a Verlet list both happen at its rebuilds instead (rebuild_neighbour_list).
    if (rebalance_every_ > 0) ++tally_.steps_since_balance;
    if (skin_ == 0 && rebalance_every_ > 0 && tally_.steps_since_balance >= rebalance_every_) {
      decomposition_.set_cuts(decomposition_.rebalanced_cuts(store_));
      tally_.steps_since_balance = 0;
    }
    if (skin_ == 0) migrate_particles();
    global_mobile_ = mpi::sum(mobile_count());  // for the progress line, which is not collective
  }
  finish_settling_if_done();
  if (statistics_ && tally_.opened_at >= 0 && tally_.time >= tally_.next_sample * (1 - 1e-12)) {
    ScopedTimer timer(timers_, "statistics");
    sample_statistics();
  }
}

void DemSystem::measure_flow(double dt) {
  const bool periodic_y = domain_.periodic(1);
  const double half = 0.5 * domain_.length().y();
  for (std::size_t i = 0; i < store_.size(); ++i) {
    if (store_.is_fixed(i)) continue;
    const double before = y_before_[i], after = store_.position[i].y();
    if (periodic_y && std::abs(after - before) > half) continue;  // wrapped, not a crossing
    if (before >= flow_plane_ && after < flow_plane_) tally_.flow_mass += store_.mass[i];
    else if (before < flow_plane_ && after >= flow_plane_) tally_.flow_mass -= store_.mass[i];
  }
  (void)dt;
}

void DemSystem::record_flow() {
  // The fill top is the 99th percentile of the heights above the plane, so a single bouncing
  // particle does not set it.
  double above = 0;
  scratch_heights_.clear();
  for (std::size_t i = 0; i < store_.size(); ++i) {
    if (store_.is_fixed(i) || store_.position[i].y() < flow_plane_) continue;
    above += store_.mass[i];
    scratch_heights_.push_back(store_.position[i].y());
  }
  if (distributed_) {
    above = mpi::sum(above);
    scratch_heights_ = mpi::all_gather(scratch_heights_);
  }
  double top = flow_plane_;
  if (!scratch_heights_.empty()) {
    const auto k = static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(scratch_heights_.size() - 1));
    std::nth_element(scratch_heights_.begin(), scratch_heights_.begin() + k, scratch_heights_.end());
    top = scratch_heights_[static_cast<std::size_t>(k)];
  }
  flow_csv_ += fmt::format("{:.9g},{:.9g},{:.9g},{:.9g}\n", tally_.time,
                           global_sum(tally_.flow_mass_total), above, top);
  tally_.next_flow_record += flow_record_interval_;
  if (tally_.next_flow_record <= tally_.time) tally_.next_flow_record = tally_.time + flow_record_interval_;
}

std::pair<double, double> DemSystem::gap_rate_and_acceleration() const {
  // Forces at the end of the step: the integrator's (velocity Verlet) or the last evaluation.
  const auto& force = !runge_kutta_ && verlet_.has_forces() ? verlet_.forces() : field_->force();
  if (wall_partner_) {
    const double x = store_.position[0].x();
    const double towards_high = (domain_.hi.x() - x < x - domain_.lo.x()) ? -1.0 : 1.0;
    return {towards_high * store_.velocity[0].x(), towards_high * force[0].x() / store_.mass[0]};
  }
  const Vec3 n = domain_.separation(store_.position[0], store_.position[1]).normalized();
  return {(store_.velocity[1] - store_.velocity[0]).dot(n),
          (force[1] / store_.mass[1] - force[0] / store_.mass[0]).dot(n)};
}

void DemSystem::probe_collision(double dt) {
  // The contact starts and ends where the signed surface gap changes sign; both instants are
  // interpolated linearly within the step, so the duration is not quantised to whole steps.
  // The separation speed is the one at the end instant, extrapolated from the last step in
  // contact with its acceleration and the change of the acceleration over the step before
  // (second order): the step that straddles the end applies part of a force that has
  // physically ceased, which would otherwise bias e by up to ~η Δt/m* (1–3 % at N = 50).
  const double gap = surface_gap();
  const double previous = tally_.previous_gap;
  const auto [rate, acceleration] = gap_rate_and_acceleration();
  if (!tally_.in_contact && gap < 0 && previous >= 0) {
    tally_.in_contact = 1;
    ++tally_.collisions;
    tally_.contact_start = tally_.time - dt + dt * previous / (previous - gap);
  } else if (tally_.in_contact && gap >= 0 && previous < 0) {
    tally_.in_contact = 0;
    const double fraction = previous / (previous - gap);
    const double end = tally_.time - dt + dt * fraction;
    if (tally_.first_duration < 0) {
      tally_.first_duration = end - tally_.contact_start;
      const double s = fraction * dt;
      const double jerk = (tally_.previous_acceleration - tally_.earlier_acceleration) / dt;
      const double separation_speed =
          tally_.previous_rate + tally_.previous_acceleration * s + 0.5 * jerk * s * s;
      tally_.first_restitution = separation_speed / tally_.approach_speed;
    }
  }
  // Before the first contact no force acts: the approach speed is exact.
  if (!tally_.in_contact && gap >= 0 && tally_.collisions == 0) tally_.approach_speed = -rate;
  tally_.previous_gap = gap;
  tally_.previous_rate = rate;
  tally_.earlier_acceleration = tally_.previous_acceleration;
  tally_.previous_acceleration = acceleration;
}

void DemSystem::remove_leaving_particles() {
  // Most steps nobody leaves: a read-only pass finds that out, against bounds held in locals
  // (-inf and +inf where a face is not open), and the keep mask is built only when someone
  // does. (Writing the mask every step, whose byte stores may alias anything, kept the domain
  // reloaded per particle and axis: 6% of a curtain_small run.)
  const std::size_t n = store_.size();
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  std::array<double, 3> low{-kInfinity, -kInfinity, -kInfinity}, high{kInfinity, kInfinity, kInfinity};
  for (int k = 0; k < domain_.dimension; ++k) {
    const auto a = static_cast<std::size_t>(k);
    if (domain_.face[a][0] == FaceKind::kOpen) low[a] = domain_.lo[k];
    if (domain_.face[a][1] == FaceKind::kOpen) high[a] = domain_.hi[k];
  }
  const Vec3* position = store_.position.data();
  auto leaving = [&](std::size_t i) {
    const Vec3& x = position[i];
    return (x[0] < low[0]) | (x[0] > high[0]) | (x[1] < low[1]) | (x[1] > high[1]) | (x[2] < low[2]) |
           (x[2] > high[2]);
  };
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) any |= leaving(i);
  if (!any) return;
  scratch_use_.assign(n, 1);
  for (std::size_t i = 0; i < n; ++i)
    if (leaving(i)) scratch_use_[i] = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!scratch_use_[i]) {
      ++tally_.removed;
      tally_.removed_mass += store_.mass[i];
    }
  // Stable compaction keeps the store in id order, and the integrator's forces with it.
  std::vector<Vec3> f, t;
  if (!runge_kutta_ && verlet_.has_forces() && verlet_.forces().size() == n) {
    f = verlet_.forces();
    t = verlet_.torques();
    keep_slots(f, scratch_use_);
    keep_slots(t, scratch_use_);
  }
  store_.keep_where(scratch_use_);
  if (!f.empty()) verlet_.restore_forces(std::move(f), std::move(t));
  else verlet_.reset();
}

void DemSystem::sample_statistics() {
  const std::size_t n = store_.size();
  std::int64_t max_id = 0;
  for (auto id : store_.id)
    if (id < (std::int64_t{1} << 40)) max_id = std::max(max_id, id);
  const auto ids = static_cast<std::size_t>(max_id + 1);
  if (sample_position_.size() < ids) {
    sample_position_.resize(ids, Vec3::Zero());
    sample_seen_.resize(ids, 0);
  }
  scratch_velocity_.resize(n);
  scratch_use_.assign(n, 0);
  const bool have_previous = tally_.last_sample >= 0;
  const double elapsed = tally_.time - tally_.last_sample;
  for (std::size_t i = 0; i < n; ++i) {
    if (store_.is_fixed(i)) continue;
    const auto id = static_cast<std::size_t>(store_.id[i]);
    if (displacement_velocity_) {
      if (have_previous && sample_seen_[id]) {
        scratch_velocity_[i] = domain_.separation(sample_position_[id], store_.position[i]) / elapsed;
        scratch_use_[i] = 1;
      }
    } else {
      scratch_velocity_[i] = store_.velocity[i];
      scratch_use_[i] = 1;
    }
  }
  // Displacement velocities need two samples: the first one only records positions.
  if (!displacement_velocity_ || have_previous) {
    bins_.add_sample(store_, domain_.dimension, scratch_velocity_, scratch_use_);
    for (std::size_t i = 0; i < n; ++i) {
      if (store_.is_fixed(i)) continue;
      const Vec3& x = store_.position[i];
      if (x.x() >= beta_window_[0] && x.x() < beta_window_[1] && x.y() >= beta_window_[2] &&
          x.y() < beta_window_[3])
        tally_.beta_volume += particle_volume(domain_.dimension, store_.radius[i]);
    }
    ++tally_.beta_samples;
  }
  std::fill(sample_seen_.begin(), sample_seen_.end(), 0);
  if (distributed_) {
    // Every rank keeps every particle's sample position: by the next sample a particle may
    // belong to another rank.
    std::vector<double> mine;
    for (std::size_t i = 0; i < n; ++i)
      if (!store_.is_fixed(i)) {
        const Vec3& x = store_.position[i];
        mine.insert(mine.end(), {static_cast<double>(store_.id[i]), x.x(), x.y(), x.z()});
      }
    const std::vector<double> all = mpi::all_gather(mine);
    for (std::size_t k = 0; k + 3 < all.size(); k += 4) {
      const auto id = static_cast<std::size_t>(all[k]);
      if (sample_position_.size() <= id) {
        sample_position_.resize(id + 1, Vec3::Zero());
        sample_seen_.resize(id + 1, 0);
      }
      sample_position_[id] = Vec3(all[k + 1], all[k + 2], all[k + 3]);
      sample_seen_[id] = 1;
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      if (store_.is_fixed(i)) continue;
      const auto id = static_cast<std::size_t>(store_.id[i]);
      sample_position_[id] = store_.position[i];
      sample_seen_[id] = 1;
    }
  }
  tally_.last_sample = tally_.time;
  tally_.next_sample += stats_interval_;
  if (tally_.next_sample <= tally_.time) tally_.next_sample = tally_.time + stats_interval_;
}

std::optional<std::string> DemSystem::check_state() const {
  if (!skin_failure_.empty()) return skin_failure_;
  if (const std::size_t i = store_.first_non_finite(); i < store_.size()) {
    const Vec3& x = store_.position[i];
    return fmt::format("non-finite state of particle id {} at ({}, {}, {})", store_.id[i], x.x(),
                       x.y(), x.z());
  }
  const DeepestContact& c = field_->deepest_contact();
  if (c.overlap_over_radius > max_overlap_ratio_)
    return fmt::format("particle id {} overlaps its {} by {:.3g} of a radius (limit {:.3g}): "
                       "raise the stiffness or dem.steps_per_collision",
                       c.id, c.is_wall ? "wall" : "neighbour", c.overlap_over_radius,
                       max_overlap_ratio_);
  return std::nullopt;
}

void DemSystem::save_good_state() {
  good_store_ = store_;
  good_tally_ = tally_;
  good_bins_ = bins_;
  good_flow_csv_ = flow_csv_;
  copy_vec3(good_sample_position_, sample_position_);
  good_sample_seen_ = sample_seen_;
  if (verlet_.has_forces()) {
    copy_vec3(good_force_, verlet_.forces());
    copy_vec3(good_torque_, verlet_.torques());
  } else {
    good_force_.clear();
  }
  field_->history().live_entries(good_history_);
  good_history_step_ = field_->history().step();
}

void DemSystem::restore_good_state() {
  store_ = good_store_;
  tally_ = good_tally_;
  bins_ = good_bins_;
  flow_csv_ = good_flow_csv_;
  copy_vec3(sample_position_, good_sample_position_);
  sample_seen_ = good_sample_seen_;
  if (!good_force_.empty()) verlet_.restore_forces(good_force_, good_torque_);
  else verlet_.reset();
  field_->invalidate_list();
  skin_failure_.clear();
  field_->history().restore(good_history_step_, good_history_);
  apply_settling_forces();
}

namespace {
/// The tally's fields by name, for checkpoints.
template <class Tally, class F>
void visit_tally(Tally& t, F&& f) {
  f("time", t.time);
  f("settling", t.settling);
  f("opened_at", t.opened_at);
  f("removed", t.removed);
  f("removed_mass", t.removed_mass);
  f("flow_mass", t.flow_mass);
  f("flow_time", t.flow_time);
  f("flow_mass_total", t.flow_mass_total);
  f("next_flow_record", t.next_flow_record);
  f("in_contact", t.in_contact);
  f("collisions", t.collisions);
  f("contact_start", t.contact_start);
  f("approach_speed", t.approach_speed);
  f("first_duration", t.first_duration);
  f("first_restitution", t.first_restitution);
  f("previous_gap", t.previous_gap);
  f("previous_rate", t.previous_rate);
  f("previous_acceleration", t.previous_acceleration);
  f("earlier_acceleration", t.earlier_acceleration);
  f("particle_steps", t.particle_steps);
  f("next_sample", t.next_sample);
  f("last_sample", t.last_sample);
  f("beta_volume", t.beta_volume);
  f("beta_samples", t.beta_samples);
  f("steps_since_balance", t.steps_since_balance);
}

void write_particles(io::Hdf5Group& g, const ParticleStore& s, bool full, bool distributed,
                     const std::vector<std::size_t>* subset = nullptr) {
  std::vector<std::size_t> all;
  if (!subset) {
    all.resize(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) all[i] = i;
    subset = &all;
  }
  auto pick3 = [&](const std::vector<Vec3>& v) {
    std::vector<double> out;
    for (auto i : *subset) out.insert(out.end(), {v[i].x(), v[i].y(), v[i].z()});
    return out;
  };
  auto pick1 = [&](const std::vector<double>& v) {
    std::vector<double> out;
    for (auto i : *subset) out.push_back(v[i]);
    return out;
  };
  write_array(g, "position", pick3(s.position), 3, distributed);
  write_array(g, "velocity", pick3(s.velocity), 3, distributed);
  write_array(g, "angular_velocity", pick3(s.angular_velocity), 3, distributed);
  write_array(g, "radius", pick1(s.radius), 1, distributed);
  std::vector<std::int64_t> ids, flags;
  for (auto i : *subset) {
    ids.push_back(s.id[i]);
    flags.push_back(s.flags[i]);
  }
  write_array(g, "id", ids, 1, distributed);
  write_array(g, "flags", flags, 1, distributed);
  if (full) {
    write_array(g, "force", pick3(s.force), 3, distributed);
    write_array(g, "torque", pick3(s.torque), 3, distributed);
    write_array(g, "mass", pick1(s.mass), 1, distributed);
    write_array(g, "inertia", pick1(s.inertia), 1, distributed);
  }
}

void write_bins(io::Hdf5Group& g, const BinStatistics& bins) {
  const auto& layout = bins.layout();
  std::vector<double> x, y;
  for (long i = 0; i < layout.count[0]; ++i) x.push_back(bins.bin_centre(0, i));
  for (long j = 0; j < layout.count[1]; ++j) y.push_back(bins.bin_centre(1, j));
  write_replicated(g, "x", x, 1);
  write_replicated(g, "y", y, 1);
  const auto nx = static_cast<std::size_t>(layout.count[0]);
  auto field = [&](const char* name, auto&& value) {
    std::vector<double> v(bins.bins());
    for (std::size_t b = 0; b < v.size(); ++b) v[b] = value(b);
    write_replicated(g, name, v, nx);  // rows = y, columns = x
  };
  field("beta", [&](std::size_t b) { return bins.beta(b); });
  field("u_mean", [&](std::size_t b) { return bins.mean_u(b); });
  field("v_mean", [&](std::size_t b) { return bins.mean_v(b); });
  field("u_rms", [&](std::size_t b) { return bins.rms_u(b); });
  field("v_rms", [&](std::size_t b) { return bins.rms_v(b); });
  field("count", [&](std::size_t b) { return bins.particle_count(b); });
  g.set_attribute("samples", static_cast<std::int64_t>(bins.samples()));
  g.set_attribute("units", std::string("x, y [m]; beta [-]; u, v, u_rms, v_rms [m/s]; count: particle samples"));
}
}  // namespace

std::vector<io::OutputGrid> DemSystem::write_output(io::Hdf5File& file,
                                                    const std::string& file_name) {
  ScopedTimer timer(timers_, "output");
  const std::int64_t total = global_sum(static_cast<std::int64_t>(store_.size()));
  {
    auto g = file.root().create_group("particles");
    write_particles(g, store_, false, distributed_);
    g.set_attribute("count", total);
    g.set_attribute("dimension", static_cast<std::int64_t>(domain_.dimension));
    g.set_attribute("units", std::string("SI: m, m/s, rad/s"));
  }
  if (statistics_) {
    auto g = file.root().create_group("dem_statistics");
    const BinStatistics bins = global_bins();
    write_bins(g, bins);
    if (mpi::is_root())
      io::write_text_atomically(file.path().parent_path() / "statistics.csv", bins.csv());
  }
  if (curtain_ && tally_.opened_at >= 0) write_curtain_state(file.path().parent_path());
  if (measure_flow_ && mpi::is_root())
    io::write_text_atomically(file.path().parent_path() / "flow.csv", flow_csv_);
  const std::string base = file_name + ":/particles/";
  std::vector<io::XdmfArray> arrays = {{"radius", base + "radius", 1},
                                       {"velocity", base + "velocity", 3},
                                       {"angular_velocity", base + "angular_velocity", 3},
                                       {"id", base + "id", 1, "Int", 8},
                                       {"flags", base + "flags", 1, "Int", 8}};
  return {{"particles", io::polyvertex_grid("particles", static_cast<long>(total),
                                            base + "position", arrays)}};
}

void DemSystem::write_curtain_state(const std::filesystem::path& folder) const {
  auto file = io::Hdf5File::create(folder / "curtain_state.h5");
  auto& root = file.root();
  root.set_attribute("grainwave_kind", std::string("curtain_state"));
  root.set_attribute("version", std::string(GRAINWAVE_VERSION));
  root.set_attribute("scene", scene_.name());
  root.set_attribute("time", tally_.time);
  root.set_attribute("time_since_opening", tally_.time - tally_.opened_at);
  root.set_attribute("window_y_low", curtain_window_[0]);
  root.set_attribute("window_y_high", curtain_window_[1]);
  root.set_attribute("dimension", static_cast<std::int64_t>(domain_.dimension));
  root.set_attribute("units", std::string("SI: m, m/s, rad/s, s"));
  root.set_attribute("contents", std::string("particles below the slit; binned profiles"));
  root.write_text("scene_text", scene_.text());
  std::vector<std::size_t> inside;
  for (std::size_t i = 0; i < store_.size(); ++i) {
    const double y = store_.position[i].y();
    if (!store_.is_fixed(i) && y >= curtain_window_[0] && y < curtain_window_[1]) inside.push_back(i);
  }
  {
    auto g = root.create_group("particles");
    write_particles(g, store_, false, distributed_, &inside);
    g.set_attribute("count", global_sum(static_cast<std::int64_t>(inside.size())));
  }
  {
    auto g = root.create_group("profiles");
    write_bins(g, global_bins());
  }
  file.commit();
}

void DemSystem::write_checkpoint(io::Hdf5Group& group) {
  auto g = group.create_group("dem");
  write_particles(g, store_, true, distributed_);
  // The tally as attributes, with the per-rank sums added up (readable; a restart on another
  // number of ranks uses them), and the per-rank parts as rows, one per rank.
  Tally all = tally_;
  if (distributed_) {
    all.removed = mpi::sum(tally_.removed);
    all.removed_mass = mpi::sum(tally_.removed_mass);
    all.flow_mass = mpi::sum(tally_.flow_mass);
    all.flow_mass_total = mpi::sum(tally_.flow_mass_total);
    all.particle_steps = mpi::sum(tally_.particle_steps);
    all.beta_volume = mpi::sum(tally_.beta_volume);
  }
  visit_tally(all, [&](const char* name, auto& value) { g.set_attribute(name, value); });
  write_array(g, "tally_partials", tally_partials(), tally_partials().size(), distributed_);
  g.set_attribute("initial_energy", initial_energy_);
  g.set_attribute("initial_mobile", initial_mobile_);
  g.write_text("flow_csv", flow_csv_);
  const bool forces = !runge_kutta_ && verlet_.has_forces();
  write_array(g, "integrator_force", forces ? flatten(verlet_.forces()) : std::vector<double>{}, 3,
              distributed_);
  write_array(g, "integrator_torque", forces ? flatten(verlet_.torques()) : std::vector<double>{}, 3,
              distributed_);
  // The Verlet list's reference positions (row by row with the particles): a restart builds
  // its first list from them, which is the list this run holds, so the rebuilds, and with them
  // the order in which forces are added, stay those of the uninterrupted run. None when the
  // list no longer holds these particles (some left): it is rebuilt before the next step anyway.
  bool list_holds = skin_ > 0 && field_->verlet_list().holds(store_, store_.size());
  if (distributed_) list_holds = !mpi::any(!list_holds);
  std::vector<double> reference;
  if (list_holds) {
    const auto& r = field_->verlet_list().reference();
    reference = flatten(std::vector<Vec3>(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(store_.size())));
  }
  write_array(g, "neighbour_reference", reference, 3, distributed_);
  // Contacts between particles of two ranks are kept by both: such entries appear twice.
  std::vector<ContactHistoryEntry> entries;
  field_->history().live_entries(entries);
  std::vector<std::int64_t> keys;
  std::vector<double> values;
  for (const auto& e : entries) {
    keys.insert(keys.end(), {e.first, e.second, e.last_step, e.is_new ? 1 : 0});
    values.insert(values.end(), {e.displacement.x(), e.displacement.y(), e.displacement.z(),
                                 e.stage_velocity.x(), e.stage_velocity.y(), e.stage_velocity.z()});
  }
  write_array(g, "history_keys", keys, 4, distributed_);
  write_array(g, "history_values", values, 6, distributed_);
  g.set_attribute("history_step", field_->history().step());
  // Bin sums per rank: one block of rows per rank.
  write_array(g, "bins_raw", bins_.raw(), 6, distributed_);
  g.set_attribute("bins_samples", static_cast<std::int64_t>(bins_.samples()));
  g.set_attribute("ranks", static_cast<std::int64_t>(distributed_ ? mpi::size() : 1));
  if (distributed_) write_replicated(g, "slab_cuts", decomposition_.cuts(), 1);
  write_replicated(g, "sample_position", flatten(sample_position_), 3);
  std::vector<std::int64_t> seen(sample_seen_.begin(), sample_seen_.end());
  write_replicated(g, "sample_seen", seen, 1);
}

void DemSystem::read_checkpoint(const io::Hdf5Group& group) {
  const auto g = group.open_group("dem");
  const auto x = unflatten(read_all_real(g, "position"));
  const auto v = unflatten(read_all_real(g, "velocity"));
  const auto w = unflatten(read_all_real(g, "angular_velocity"));
  const auto f = unflatten(read_all_real(g, "force"));
  const auto t = unflatten(read_all_real(g, "torque"));
  const auto r = read_all_real(g, "radius");
  const auto m = read_all_real(g, "mass");
  const auto inertia = read_all_real(g, "inertia");
  const auto ids = read_all_integer(g, "id");
  const auto flags = read_all_integer(g, "flags");
  auto force = unflatten(read_all_real(g, "integrator_force"));
  auto torque = unflatten(read_all_real(g, "integrator_torque"));
  // The slabs as they were, when as many ranks wrote the file (else the cuts of the start).
  if (const auto cuts = read_all_real(g, "slab_cuts");
      distributed_ && cuts.size() == decomposition_.cuts().size())
    decomposition_.set_cuts(cuts);
  // Every rank reads all particles and keeps those in its slab, in id order. With the Verlet
  // list's reference positions, the slab is the one a particle was in at the list's build:
  // between builds particles do not migrate.
  const auto reference = unflatten(read_all_real(g, "neighbour_reference"));
  const bool from_reference = skin_ > 0 && reference.size() == ids.size();
  std::vector<std::size_t> mine;
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (decomposition_.owner(from_reference ? reference[i] : x[i]) == (distributed_ ? mpi::rank() : 0))
      mine.push_back(i);
  std::sort(mine.begin(), mine.end(), [&](std::size_t a, std::size_t b) { return ids[a] < ids[b]; });
  store_.clear();
  field_->invalidate_list();
  restart_reference_.clear();
  std::vector<Vec3> my_force, my_torque;
  for (const std::size_t i : mine) {
    if (from_reference) restart_reference_.push_back(reference[i]);
    store_.add(ids[i], x[i], v[i], w[i], r[i], m[i], inertia[i], static_cast<std::uint32_t>(flags[i]));
    store_.force.back() = f[i];
    store_.torque.back() = t[i];
    if (!force.empty()) {
      my_force.push_back(force[i]);
      my_torque.push_back(torque[i]);
    }
  }
  visit_tally(tally_, [&](const char* name, auto& value) {
    if (!g.has_attribute(name)) return;  // written before the field existed: its start value
    if constexpr (std::is_same_v<std::decay_t<decltype(value)>, double>) value = g.real_attribute(name);
    else value = g.integer_attribute(name);
  });
  // The per-rank sums: this rank's part when as many ranks wrote the file, else the totals go
  // to rank 0.
  const std::int64_t writers = g.has_attribute("ranks") ? g.integer_attribute("ranks") : 1;
  const std::int64_t ranks = distributed_ ? mpi::size() : 1;
  const std::vector<double> partials = read_all_real(g, "tally_partials");
  const std::size_t width = tally_partials().size();
  if (writers == ranks && partials.size() == width * static_cast<std::size_t>(ranks)) {
    const auto me = static_cast<std::size_t>(distributed_ ? mpi::rank() : 0);
    set_tally_partials(std::vector<double>(partials.begin() + static_cast<std::ptrdiff_t>(me * width),
                                           partials.begin() + static_cast<std::ptrdiff_t>((me + 1) * width)));
  } else if (distributed_ && !mpi::is_root()) {
    set_tally_partials(std::vector<double>(width, 0.0));
  }
  initial_energy_ = g.real_attribute("initial_energy");
  initial_mobile_ = g.integer_attribute("initial_mobile");
  flow_csv_ = g.read_text("flow_csv");
  if (!force.empty()) verlet_.restore_forces(std::move(my_force), std::move(my_torque));
  else verlet_.reset();
  // The history entries of the contacts this rank computes: those of an owned particle (once,
  // though a contact between two ranks was written by both, the later copy).
  std::vector<std::int64_t> owned_ids(store_.id.begin(), store_.id.end());
  const auto keys = read_all_integer(g, "history_keys");
  const auto values = read_all_real(g, "history_values");
  std::vector<ContactHistoryEntry> entries;
  for (std::size_t k = 0; k < keys.size() / 4; ++k) {
    ContactHistoryEntry e;
    e.first = keys[4 * k];
    e.second = keys[4 * k + 1];
    e.last_step = keys[4 * k + 2];
    e.is_new = keys[4 * k + 3] != 0;
    e.displacement = Vec3(values[6 * k], values[6 * k + 1], values[6 * k + 2]);
    e.stage_velocity = Vec3(values[6 * k + 3], values[6 * k + 4], values[6 * k + 5]);
    const bool ours = std::binary_search(owned_ids.begin(), owned_ids.end(), e.first) ||
                      std::binary_search(owned_ids.begin(), owned_ids.end(), e.second);
    if (ours) entries.push_back(e);
  }
  // Of two copies of a pair (written by two ranks) the one touched last is the current one.
  auto pair_less = [](const ContactHistoryEntry& a, const ContactHistoryEntry& b) {
    if (a.first != b.first) return a.first < b.first;
    return a.second != b.second ? a.second < b.second : a.last_step > b.last_step;
  };
  std::sort(entries.begin(), entries.end(), pair_less);  // copies equal in all three are identical
  entries.erase(std::unique(entries.begin(), entries.end(),
                            [](const ContactHistoryEntry& a, const ContactHistoryEntry& b) {
                              return a.first == b.first && a.second == b.second;
                            }),
                entries.end());
  field_->history().restore(g.integer_attribute("history_step"), entries);
  // Bin sums: this rank's block when as many ranks wrote them, else the totals on rank 0.
  std::vector<double> raw = read_all_real(g, "bins_raw");
  const std::size_t block = bins_.raw().size();
  if (block > 0 && raw.size() == block * static_cast<std::size_t>(writers)) {
    std::vector<double> mine_raw(block, 0.0);
    if (writers == ranks) {
      const auto me = static_cast<std::size_t>(distributed_ ? mpi::rank() : 0);
      std::copy(raw.begin() + static_cast<std::ptrdiff_t>(me * block),
                raw.begin() + static_cast<std::ptrdiff_t>((me + 1) * block), mine_raw.begin());
    } else if (!distributed_ || mpi::is_root()) {
      for (std::size_t k = 0; k < raw.size(); ++k) mine_raw[k % block] += raw[k];
    }
    raw = std::move(mine_raw);
  }
  bins_.restore(static_cast<long>(g.integer_attribute("bins_samples")), raw);
  sample_position_ = unflatten(read_all_real(g, "sample_position"));
  const auto seen = read_all_integer(g, "sample_seen");
  sample_seen_.assign(seen.begin(), seen.end());
  for (std::size_t w2 : gate_walls_) field_->finite_walls()[w2].enabled = tally_.settling != 0;
  global_mobile_ = global_sum(mobile_count());
}

void DemSystem::report(io::Json& counts, io::Json& metrics, double step_wall_s, long steps) const {
  const std::int64_t mobile = global_sum(mobile_count());
  const std::int64_t held = global_sum(static_cast<std::int64_t>(store_.size()));
  const double kinetic_energy = global_sum(mobile_kinetic_energy());
  counts.set("particles", mobile);
  counts.set("fixed_particles", held - mobile);
  counts.set("particles_removed", global_sum(tally_.removed));
  counts.set("contacts", global_sum(static_cast<std::int64_t>(field_->contact_count())));
  if (skin_ > 0) counts.set("neighbour_list_builds", static_cast<std::int64_t>(field_->verlet_list().builds()));
  if (distributed_) {
    counts.set("ranks_in_slabs", static_cast<std::int64_t>(mpi::size()));
    // Moving particles per rank, the work each carries: how well the cuts balance it.
    counts.set("slab_particles_min", -mpi::max(-mobile_count()));
    counts.set("slab_particles_max", mpi::max(mobile_count()));
  }
  metrics.set("time_step", dt_);
  metrics.set("kinetic_energy", kinetic_energy);
  if (tally_.opened_at >= 0) metrics.set("gate_opened_at", tally_.opened_at);
  const double particle_steps = global_sum(tally_.particle_steps);
  (void)steps;
  metrics.set("particle_steps_per_s", step_wall_s > 0 ? particle_steps / step_wall_s : 0.0);
  // Memory of all ranks over the particles: ghosts and per-rank buffers included.
  metrics.set("bytes_per_particle",
              static_cast<double>(global_sum(static_cast<std::int64_t>(memory_bytes()))) /
                  static_cast<double>(std::max<std::int64_t>(held, 1)));
  const bool closed = gravity_.isZero() && tally_.removed == 0 && settle_damping_ == 0 &&
                      field_->settings().drag_zones.empty();
  if (closed && initial_energy_ > 0)
    metrics.set("energy_rel_drift", (kinetic_energy - initial_energy_) / initial_energy_);
  if (placement_ == Placement::kCollision) {
    counts.set("collisions", tally_.collisions);
    metrics.set("restitution_target", restitution_target_);
    const double m = store_.mass[0], r = store_.radius[0];
    metrics.set("contact_duration_theory", wall_partner_
                                               ? model_.normal->contact_duration(m, r)
                                               : model_.normal->contact_duration(0.5 * m, 0.5 * r));
    if (tally_.first_duration > 0) {
      metrics.set("restitution_measured", tally_.first_restitution);
      metrics.set("contact_duration", tally_.first_duration);
    }
  }
  if (measure_flow_ && tally_.flow_time > 0)
    metrics.set("mass_flow_rate", global_sum(tally_.flow_mass) / tally_.flow_time);
  if (packing_window_) {
    const auto [a, b] = *packing_window_;
    double solid = 0;
    for (std::size_t i = 0; i < store_.size(); ++i)
      if (!store_.is_fixed(i))
        solid += volume_in_slab(domain_.dimension, store_.position[i].y(), store_.radius[i], a, b);
    solid = global_sum(solid);
    const Vec3 L = domain_.length();
    metrics.set("packing_fraction", solid / (L.x() * (domain_.dimension == 3 ? L.z() : 1.0) * (b - a)));
  }
  if (statistics_ && tally_.beta_samples > 0) {
    const double area = (beta_window_[1] - beta_window_[0]) * (beta_window_[3] - beta_window_[2]);
    const double depth = domain_.dimension == 3 ? domain_.length().z() : 1.0;
    if (area > 0)
      metrics.set("beta_below_slit",
                  global_sum(tally_.beta_volume) / (static_cast<double>(tally_.beta_samples) * area * depth));
    metrics.set("statistics_samples", static_cast<double>(tally_.beta_samples));
  }
}

std::size_t DemSystem::memory_bytes() const {
  // State + last good copy, the integrator's and the force field's per-particle arrays, the
  // contact list and the history (its table, the table's spare for purges, the pinned data).
  const std::size_t n = store_.size();
  // The Verlet list: its pairs, and a reference position and id per slot.
  const std::size_t list = field_->verlet_list().pair_count() * 2 * sizeof(std::uint32_t) +
                           field_->verlet_list().reference().size() * (sizeof(Vec3) + sizeof(std::int64_t));
  return 2 * n * ParticleStore::bytes_per_particle() + 4 * n * sizeof(Vec3) * 2 + list +
         n * (2 * sizeof(Vec3) + sizeof(double)) + field_->contacts().capacity() * sizeof(Contact) +
         field_->history().bytes();
}

std::string DemSystem::progress_note() const {
  // Not collective: the contacts are this rank's when distributed.
  return fmt::format("N {}  contacts {}{}{}", distributed_ ? global_mobile_ : mobile_count(),
                     field_->contact_count(),
                     distributed_ ? " (rank 0)" : "", tally_.settling ? "  settling" : "");
}

}  // namespace grainwave::particles::dem

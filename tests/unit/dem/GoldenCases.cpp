// One driver for the data-driven DEM contact-law cases in tests/golden/dem/*.toml. Each file
// names a `case` (the experiment), the normal and tangential laws with their parameters, the
// setup, and tolerances; the expected values are derived here from closed-form results
// (002 Eqs 3.10/3.17, Hertz impact theory, rigid-body rolling), never stored outputs.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/HertzNormal.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>
#include <toml.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

namespace {

const std::filesystem::path kGoldenDir = std::filesystem::path(GRAINWAVE_TEST_DATA) / "golden" / "dem";

dem::LawParameters law_parameters(const toml::value& table) {
  dem::LawParameters parameters;
  for (const auto& [key, value] : table.as_table()) {
    if (key == "law") continue;
    parameters.set(key, value.is_integer() ? static_cast<double>(value.as_integer())
                                           : value.as_floating());
  }
  return parameters;
}

dem::ContactModel model_from(const toml::value& file) {
  const auto& normal = toml::find(file, "normal");
  const auto& tangential = toml::find(file, "tangential");
  return dem::make_contact_model(toml::find<std::string>(normal, "law"), law_parameters(normal),
                                 toml::find<std::string>(tangential, "law"),
                                 law_parameters(tangential));
}

gw::Domain open_box(int dimension, double half_width) {
  gw::Domain domain;
  domain.dimension = dimension;
  domain.lo = Vec3::Constant(-half_width);
  domain.hi = Vec3::Constant(half_width);
  if (dimension == 2) domain.lo.z() = domain.hi.z() = 0.0;
  for (auto& axis : domain.face) axis = {gw::FaceKind::kOpen, gw::FaceKind::kOpen};
  return domain;
}

/// Steps with the named integrator until `done` returns true (or max_steps).
template <class Done, class Observe>
long run(const std::string& integrator, gw::ParticleStore& store, dem::ContactForceField& field,
         double dt, long max_steps, Done&& done, Observe&& observe) {
  dem::VelocityVerlet verlet;
  dem::RungeKutta2 rk2;
  for (long step = 1; step <= max_steps; ++step) {
    if (integrator == "velocity_verlet") verlet.step(store, field, dt);
    else if (integrator == "runge_kutta2") rk2.step(store, field, dt);
    else throw std::runtime_error("unknown integrator " + integrator);
    observe(step);
    if (done()) return step;
  }
  return max_steps;
}

double sphere_mass(int dimension, double density, double radius) {
  return dimension == 2 ? density * std::numbers::pi * radius * radius
                        : density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
}

/// 2∫₀¹ dx / sqrt(1 − x^{5/2}) (Hertz collision time in units of δ_max/v), by the substitution
/// x = 1 − u² that removes the endpoint singularity, and the midpoint rule.
double hertz_duration_integral() {
  const int n = 200000;
  double sum = 0.0;
  for (int k = 0; k < n; ++k) {
    const double u = (k + 0.5) / n;
    sum += 2.0 * u / std::sqrt(1.0 - std::pow(1.0 - u * u, 2.5));
  }
  return 2.0 * sum / n;
}

// ---- case: single_collision -----------------------------------------------------------------
// Two equal particles (or one and a wall) meet head-on; the measured restitution is the ratio of
// separation to approach speed, the duration the time between the interpolated zero crossings
// of the overlap.
void single_collision(const toml::value& file) {
  const auto& setup = toml::find(file, "setup");
  const auto& expect = toml::find(file, "expect");
  const int dimension = toml::find_or<int>(setup, "dimension", 3);
  const double radius = toml::find<double>(setup, "radius");
  const double density = toml::find<double>(setup, "density");
  const int steps_per_collision = toml::find_or<int>(setup, "steps_per_collision", 50);
  const std::string integrator = toml::find<std::string>(setup, "integrator");
  const auto speeds = toml::find<std::vector<double>>(setup, "impact_speeds");
  const double mass = sphere_mass(dimension, density, radius);
  const double inertia = gw::solid_inertia(dimension, mass, radius);
  const double m_eff = 0.5 * mass;

  for (double speed : speeds) {
    SCOPED_TRACE("impact speed " + std::to_string(speed));
    dem::ContactModel model = model_from(file);
    dem::ContactForceField field(model, open_box(dimension, 100.0 * radius));
    gw::ParticleStore store;
    // Gap of 3.37 steps of approach so the contact starts between steps, as it would in a run.
    const double dt_guess = model.normal->contact_duration(m_eff, 0.5 * radius) / steps_per_collision;
    const double gap = 3.37 * speed * dt_guess;
    store.add(0, Vec3(-radius - 0.5 * gap, 0, 0), Vec3(0.5 * speed, 0, 0), Vec3::Zero(), radius,
              mass, inertia);
    store.add(1, Vec3(radius + 0.5 * gap, 0, 0), Vec3(-0.5 * speed, 0, 0), Vec3::Zero(), radius,
              mass, inertia);
    const double dt = dem::stable_time_step(store, *model.normal, steps_per_collision);

    double previous_overlap = -gap;
    double t_start = -1.0, t_end = -1.0;
    auto overlap = [&] { return 2.0 * radius - (store.position[1] - store.position[0]).norm(); };
    run(integrator, store, field, dt, 100L * steps_per_collision,
        [&] { return t_end >= 0.0; },
        [&](long step) {
          const double o = overlap();
          const double t = step * dt;
          if (previous_overlap <= 0.0 && o > 0.0 && t_start < 0.0)
            t_start = t - dt * o / (o - previous_overlap);
          if (previous_overlap > 0.0 && o <= 0.0 && t_start >= 0.0)
            t_end = t - dt * o / (o - previous_overlap);
          previous_overlap = o;
        });
    ASSERT_GE(t_end, 0.0) << "the particles never separated";
    const double separation_speed = store.velocity[1].x() - store.velocity[0].x();
    const double measured_e = separation_speed / speed;
    const double e = toml::find<double>(toml::find(file, "normal"), "restitution");
    EXPECT_NEAR(measured_e, e, toml::find<double>(expect, "restitution_rel_tol") * e)
        << "measured e = " << measured_e;

    double tau = 0.0;
    const std::string law = toml::find<std::string>(toml::find(file, "normal"), "law");
    if (law == "linear_spring_dashpot") {  // 002 Eq. 3.17
      const double k = toml::find<double>(toml::find(file, "normal"), "stiffness");
      const double log_e = std::log(e);
      tau = std::sqrt((std::numbers::pi * std::numbers::pi + log_e * log_e) * m_eff / k);
    } else if (law == "hertz" && e == 1.0) {  // τ = 2∫… δ_max/v, δ_max = (5 m* v²/(4K))^{2/5}
      const auto& normal = toml::find(file, "normal");
      const double nu = toml::find<double>(normal, "poisson_ratio");
      const double e_star = toml::find<double>(normal, "youngs_modulus") / (2.0 * (1.0 - nu * nu));
      const double k = 4.0 / 3.0 * e_star * std::sqrt(0.5 * radius);
      const double delta_max = std::pow(5.0 * m_eff * speed * speed / (4.0 * k), 0.4);
      tau = hertz_duration_integral() * delta_max / speed;
    }
    if (tau > 0.0) {
      EXPECT_NEAR(t_end - t_start, tau, toml::find<double>(expect, "duration_rel_tol") * tau)
          << "measured duration " << t_end - t_start;
    }
    std::printf("[golden] e=%.3f v=%.3g: measured e=%.6f (err %.2e), duration %.6e vs %.6e\n", e,
                speed, measured_e, measured_e / e - 1.0, t_end - t_start, tau);
  }
}

// ---- case: bouncing_between_walls ----------------------------------------------------------
// One particle between two parallel walls with e = 1, μ = 0, no gravity: the kinetic energy out
// of contact must stay at its initial value over many collisions.
void bouncing_between_walls(const toml::value& file) {
  const auto& setup = toml::find(file, "setup");
  const auto& expect = toml::find(file, "expect");
  const double radius = toml::find<double>(setup, "radius");
  const double density = toml::find<double>(setup, "density");
  const double speed = toml::find<double>(setup, "speed");
  const long collisions = toml::find<long>(setup, "collisions");
  const double gap = toml::find<double>(setup, "gap_in_radii") * radius;
  const int steps_per_collision = toml::find_or<int>(setup, "steps_per_collision", 50);
  const std::string integrator = toml::find<std::string>(setup, "integrator");
  const double mass = sphere_mass(3, density, radius);

  gw::Domain domain = open_box(3, radius + 0.5 * gap);
  domain.face[0] = {gw::FaceKind::kWall, gw::FaceKind::kWall};
  dem::ContactModel model = model_from(file);
  dem::ContactForceField field(model, domain);
  ASSERT_EQ(field.plane_walls().size(), 2u);
  gw::ParticleStore store;
  // An oblique direction so the wall contacts do not recur at the same phase of the step grid.
  store.add(0, Vec3(0.1234 * gap, 0, 0), speed * Vec3(1.0, 0.0, 0.0), Vec3::Zero(), radius, mass,
            gw::solid_inertia(3, mass, radius));
  const double dt = dem::stable_time_step(store, *model.normal, steps_per_collision);
  const double energy0 = 0.5 * mass * speed * speed;
  // Verlet's energy error on leaving a contact depends on where the contact fell on the step
  // grid (the force has a kink at δ = 0), so single collisions scatter by O((ω Δt)²)·small; the
  // drift is the change of the mean over the first and last 10% of collisions.
  const long window = std::max(1L, collisions / 10);
  long bounces = 0;
  double previous_vx = speed;
  double worst = 0.0, first_sum = 0.0, last_sum = 0.0;
  run(integrator, store, field, dt, 1000000000L, [&] { return bounces >= collisions; },
      [&](long) {
        const double vx = store.velocity[0].x();
        const bool in_contact = field.contact_count() > 0;
        if (!in_contact && (vx > 0) != (previous_vx > 0)) {
          ++bounces;
          const double error = 0.5 * mass * store.velocity[0].squaredNorm() / energy0 - 1.0;
          worst = std::max(worst, std::abs(error));
          if (bounces <= window) first_sum += error;
          if (bounces > collisions - window) last_sum += error;
          previous_vx = vx;
        }
      });
  const double drift = (last_sum - first_sum) / static_cast<double>(window);
  std::printf("[golden] %ld collisions (%s): energy drift %.3e, largest single error %.3e\n",
              bounces, integrator.c_str(), drift, worst);
  EXPECT_EQ(bounces, collisions);
  EXPECT_LT(std::abs(drift), toml::find<double>(expect, "max_energy_drift"));
  EXPECT_LT(worst, toml::find<double>(expect, "max_collision_energy_error"));
}

// ---- case: sliding_to_rolling ---------------------------------------------------------------
// A sphere (or disk) launched without spin on a floor slides under Coulomb friction until its
// contact point sticks; angular momentum about the contact point is conserved, so it then rolls
// at v0/(1 + I/(m R²)) (5/7 v0 for a sphere, 2/3 v0 for a disk), reached after
// t = v0 / (μ g (1 + m R²/I)).
void sliding_to_rolling(const toml::value& file) {
  const auto& setup = toml::find(file, "setup");
  const auto& expect = toml::find(file, "expect");
  const int dimension = toml::find_or<int>(setup, "dimension", 3);
  const double radius = toml::find<double>(setup, "radius");
  const double density = toml::find<double>(setup, "density");
  const double v0 = toml::find<double>(setup, "speed");
  const double g = toml::find<double>(setup, "gravity");
  const double friction = toml::find<double>(toml::find(file, "tangential"), "friction");
  const int steps_per_collision = toml::find_or<int>(setup, "steps_per_collision", 50);
  const std::string integrator = toml::find<std::string>(setup, "integrator");
  const double mass = sphere_mass(dimension, density, radius);
  const double inertia = gw::solid_inertia(dimension, mass, radius);

  gw::Domain domain = open_box(dimension, 1000.0 * radius);
  domain.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kOpen};
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0, -g, 0);
  dem::ContactModel model = model_from(file);
  dem::ContactForceField field(model, domain, settings);
  gw::ParticleStore store;
  store.add(0, Vec3(0, domain.lo.y() + radius, 0), Vec3(v0, 0, 0), Vec3::Zero(), radius, mass, inertia);
  const double dt = dem::stable_time_step(store, *model.normal, steps_per_collision);
  // Settle onto the floor first (no sliding yet), so the normal force equals m g.
  store.velocity[0].setZero();
  run(integrator, store, field, dt, 40L * steps_per_collision, [] { return false; }, [](long) {});
  store.velocity[0] = Vec3(v0, 0, 0);
  store.angular_velocity[0].setZero();

  const double ratio = inertia / (mass * radius * radius);
  const double v_roll = v0 / (1.0 + ratio);
  const double t_roll = v0 / (friction * g * (1.0 + 1.0 / ratio));
  const long steps = static_cast<long>(std::ceil(3.0 * t_roll / dt));
  const long mid_step = static_cast<long>(std::lround(0.5 * t_roll / dt));
  double v_mid = 0.0;
  run(integrator, store, field, dt, steps, [] { return false; }, [&](long step) {
    if (step == mid_step) v_mid = store.velocity[0].x();
  });
  // While sliding, Coulomb friction μ m g decelerates the centre uniformly.
  const double v_mid_expected = v0 - friction * g * mid_step * dt;
  const double v_final = store.velocity[0].x();
  const double slip = v_final + radius * store.angular_velocity[0].z();
  std::printf("[golden] rolling (dim %d): v = %.6f v0 (expect %.6f), sliding v(t/2) = %.6f v0 "
              "(expect %.6f), slip %.2e v0\n",
              dimension, v_final / v0, v_roll / v0, v_mid / v0, v_mid_expected / v0, slip / v0);
  EXPECT_NEAR(v_final, v_roll, toml::find<double>(expect, "velocity_rel_tol") * v_roll);
  EXPECT_NEAR(v_mid, v_mid_expected, toml::find<double>(expect, "velocity_rel_tol") * v_mid_expected);
  EXPECT_LT(std::abs(slip), 1e-3 * v0) << "not rolling";
}

// ---- case: segment_end_collision ------------------------------------------------------------
// A disk aimed obliquely at the end point of a finite segment: the contact normal is the line
// from the end point to the centre, so an elastic frictionless impact sends it straight back
// (an infinite line would only flip the normal component).
void segment_end_collision(const toml::value& file) {
  const auto& setup = toml::find(file, "setup");
  const auto& expect = toml::find(file, "expect");
  const double radius = toml::find<double>(setup, "radius");
  const double density = toml::find<double>(setup, "density");
  const double speed = toml::find<double>(setup, "speed");
  const double angle = toml::find<double>(setup, "approach_angle_degrees") * std::numbers::pi / 180.0;
  const std::string integrator = toml::find<std::string>(setup, "integrator");
  const double mass = sphere_mass(2, density, radius);
  dem::ContactModel model = model_from(file);
  dem::ContactForceField field(model, open_box(2, 100.0 * radius));
  field.finite_walls().push_back(dem::FiniteWall::segment(Vec3(-10 * radius, 0, 0), Vec3::Zero()));
  const Vec3 direction(std::cos(angle), std::sin(angle), 0.0);  // from end point to the centre
  gw::ParticleStore store;
  store.add(0, 1.5 * radius * direction, -speed * direction, Vec3::Zero(), radius, mass,
            gw::solid_inertia(2, mass, radius));
  const double dt = dem::stable_time_step(store, *model.normal, 50);
  run(integrator, store, field, dt, 100000, [&] { return store.position[0].norm() > 1.5 * radius; },
      [](long) {});
  const Vec3 v = store.velocity[0];
  std::printf("[golden] segment end: v = (%.6f, %.6f) vs (%.6f, %.6f)\n", v.x(), v.y(),
              speed * direction.x(), speed * direction.y());
  const double tol = toml::find<double>(expect, "velocity_rel_tol") * speed;
  EXPECT_NEAR(v.x(), speed * direction.x(), tol);
  EXPECT_NEAR(v.y(), speed * direction.y(), tol);
}

std::vector<std::string> golden_files() {
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(kGoldenDir))
    if (entry.path().extension() == ".toml") files.push_back(entry.path().stem().string());
  std::sort(files.begin(), files.end());
  return files;
}

class GoldenDem : public ::testing::TestWithParam<std::string> {};

TEST_P(GoldenDem, MatchesClosedForm) {
  const toml::value file = toml::parse((kGoldenDir / (GetParam() + ".toml")).string());
  const std::string name = toml::find<std::string>(file, "case");
  if (name == "single_collision") single_collision(file);
  else if (name == "bouncing_between_walls") bouncing_between_walls(file);
  else if (name == "sliding_to_rolling") sliding_to_rolling(file);
  else if (name == "segment_end_collision") segment_end_collision(file);
  else FAIL() << "unknown golden case '" << name << "'";
}

INSTANTIATE_TEST_SUITE_P(Files, GoldenDem, ::testing::ValuesIn(golden_files()),
                         [](const auto& test_info) { return test_info.param; });

TEST(GoldenDem, FilesPresent) { EXPECT_GE(golden_files().size(), 8u); }

}  // namespace

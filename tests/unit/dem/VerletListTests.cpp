// The Verlet list must find exactly the contacts the cell search finds, at every step, while
// being rebuilt only now and then.
#include "particles/dem/ContactForceField.hpp"
#include "particles/dem/Integrators.hpp"

#include <gtest/gtest.h>

#include <random>

namespace gw = grainwave::particles;
namespace dem = grainwave::particles::dem;
using gw::Vec3;

TEST(VerletList, SameForcesAsCellSearchThroughoutAGranularGas) {
  gw::Domain domain;
  domain.hi = Vec3(5.0, 5.0, 5.0);
  domain.face[1] = {gw::FaceKind::kWall, gw::FaceKind::kWall};
  auto model = dem::make_contact_model("linear_spring_dashpot",
                                       {{"stiffness", 1e4}, {"restitution", 0.8}},
                                       "static_friction", {{"friction", 0.3}});
  dem::ContactForceSettings settings;
  settings.gravity = Vec3(0.0, -1.0, 0.0);
  dem::ContactForceField driver(model, domain, settings);
  dem::ContactForceField cells(model, domain, settings);
  settings.verlet_skin = 0.2;
  dem::ContactForceField listed(model, domain, settings);

  gw::ParticleStore s;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 300; ++k) {
    const double r = 0.15 + 0.1 * u(rng);
    s.add(k, Vec3(5 * u(rng), 0.3 + 4.4 * u(rng), 5 * u(rng)),
          Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5), Vec3::Zero(), r, r * r * r,
          0.4 * r * r * r * r * r);
  }
  dem::VelocityVerlet verlet;
  const double dt = dem::stable_time_step(s, *model.normal, 50);
  const int steps = 2000;
  double worst = 0.0;
  long contacts_seen = 0;
  for (int step = 0; step < steps; ++step) {
    verlet.step(s, driver, dt);
    cells.evaluate(s, dem::HistoryStage::kSingle, dt);
    listed.evaluate(s, dem::HistoryStage::kSingle, dt);
    ASSERT_EQ(cells.contacts().size(), listed.contacts().size()) << "step " << step;
    contacts_seen += static_cast<long>(cells.contacts().size());
    // Contact forces summed in another order round differently: compare against the largest
    // single contact force, which sets the size of that rounding.
    double largest = 1.0;
    for (const dem::Contact& c : cells.contacts()) largest = std::max(largest, std::abs(c.normal_force));
    for (std::size_t i = 0; i < s.size(); ++i)
      worst = std::max(worst, (cells.force()[i] - listed.force()[i]).norm() / largest);
  }
  std::printf("Verlet list: %ld builds in %d steps, %zu pairs listed, %ld contacts seen\n",
              listed.verlet_list().builds(), steps, listed.verlet_list().pair_count(),
              contacts_seen);
  EXPECT_LT(worst, 1e-12);  // only the summation order differs
  EXPECT_GT(contacts_seen, 1000);
  EXPECT_GT(listed.verlet_list().builds(), 1);
  EXPECT_LT(listed.verlet_list().builds(), steps / 5);
}

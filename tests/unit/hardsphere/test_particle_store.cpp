// ParticleStore::first_non_finite, which every particle run's state check calls after each step:
// its vector pass must see a NaN or an infinity in any component of the three arrays it reads,
// and name the first slot holding one.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "particles/ParticleStore.hpp"

namespace gp = grainwave::particles;
using gp::Vec3;

TEST(ParticleStore, FirstNonFiniteFindsEveryKindInEveryArray) {
  gp::ParticleStore s;
  for (int i = 0; i < 37; ++i)  // an odd count: the vector pass has a remainder
    s.add(i, Vec3(i, -i, 1e300), Vec3(1e-310, 0.0, -0.0), Vec3::Zero(), 0.5, 1.0, 0.1);
  EXPECT_EQ(s.first_non_finite(), s.size()) << "huge, subnormal and signed-zero values are finite";
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const double bad : {nan, inf, -inf})
    for (int array = 0; array < 3; ++array)
      for (const std::size_t slot : {std::size_t{0}, std::size_t{17}, std::size_t{36}})
        for (int k = 0; k < 3; ++k) {
          gp::ParticleStore t = s;
          (array == 0 ? t.position : array == 1 ? t.velocity : t.angular_velocity)[slot][k] = bad;
          EXPECT_EQ(t.first_non_finite(), slot) << "array " << array << ", component " << k << ", value " << bad;
          if (slot == 36) continue;
          t.velocity[36].z() = nan;  // a later one too: the first is named
          EXPECT_EQ(t.first_non_finite(), slot) << "array " << array << ", component " << k << ", value " << bad;
        }
  gp::ParticleStore empty;
  EXPECT_EQ(empty.first_non_finite(), 0u);
}

#include <gtest/gtest.h>

#include <cstring>
#include <numeric>
#include <vector>

#include "core/StreamingCopy.hpp"

// The streamed copy writes exactly what std::copy would, whatever the length (short arrays take
// std::copy, long odd ones end with one ordinary store) and the alignment (a misaligned pair
// takes std::copy), and nothing past the end.
TEST(StreamingCopy, CopiesEveryValueBitwise) {
  constexpr std::size_t kLong = grainwave::kStreamedCopyFrom;
  for (const std::size_t count : {std::size_t{0}, std::size_t{1}, std::size_t{17}, kLong, kLong + 1, kLong + 2}) {
    for (const std::size_t shift : {0u, 1u}) {
      std::vector<double> from(count + 2), to(count + 2, -1.0);
      std::iota(from.begin(), from.end(), 0.5);
      from[shift] = -0.0;  // a sign that a sum would lose
      grainwave::copy_streaming(from.data() + shift, count, to.data() + shift);
      for (std::size_t k = 0; k < to.size(); ++k) {
        const double expected = k >= shift && k < shift + count ? from[k] : -1.0;
        EXPECT_EQ(std::memcmp(&to[k], &expected, sizeof(double)), 0) << "count " << count << " shift " << shift << " at " << k;
      }
    }
  }
}

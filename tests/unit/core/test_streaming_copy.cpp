#include <gtest/gtest.h>

#include <cstring>
#include <numeric>
#include <vector>

#include "core/StreamingCopy.hpp"

// The streamed copy writes exactly what std::copy would, whatever the length (odd ones end with
// one ordinary store) and the alignment (a misaligned pair takes std::copy), and nothing past the
// end.
TEST(StreamingCopy, CopiesEveryValueBitwise) {
  for (const std::size_t count : {0u, 1u, 2u, 3u, 17u, 1000u}) {
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

#pragma once
// Function multiversioning for the numerical kernels (GCC target_clones): a kernel marked with
// one of these is compiled once per listed instruction set, and the loader picks the widest the
// CPU runs. `flatten` inlines the templates each kernel calls into each clone, so every clone is
// compiled for its instruction set as a whole. The kernels' files are built without FMA
// contraction (-ffp-contract=off in their CMakeLists), so all clones round alike and results are
// bitwise the same on any x86-64 CPU. Under the sanitizers (and off x86-64) nothing is cloned.
//   GRAINWAVE_CLONES_AVX2     AVX2 and the baseline
//   GRAINWAVE_CLONES_AVX512   AVX-512F, AVX2 and the baseline: for kernels whose rows are long
//                             enough to gain from 512-bit vectors (measure: short rows lose)
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_ADDRESS__)
#define GRAINWAVE_CLONES_AVX2 __attribute__((target_clones("avx2", "default"), flatten))
#define GRAINWAVE_CLONES_AVX512 __attribute__((target_clones("avx512f", "avx2", "default"), flatten))
#else
#define GRAINWAVE_CLONES_AVX2
#define GRAINWAVE_CLONES_AVX512
#endif

namespace grainwave {

/// Whether the CPU running this process has AVX-512F (the widest clone's instruction set), for
/// kernels that pick a lane width at run time: a wider vector type is one register only there.
inline bool cpu_has_avx512f() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has = __builtin_cpu_supports("avx512f");
  return has;
#else
  return false;
#endif
}

}  // namespace grainwave

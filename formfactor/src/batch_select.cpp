#include <cstdlib>
#include <cstring>

#include "batch.hpp"

namespace lambert::formfactor::detail {

// The best variant the CPU supports; the environment variable LAMBERT_ISA=avx2|generic picks a lesser one (to
// measure the AVX2 or baseline code on an AVX-512 machine). A variant the CPU lacks is never picked.
const BatchKernels& batch_kernels() {
  static const BatchKernels& k = [] () -> const BatchKernels& {
    __builtin_cpu_init();
    const char* want = std::getenv("LAMBERT_ISA");
    const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq");
    const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    if (want && std::strcmp(want, "generic") == 0) return batch_kernels_generic();
    if (want && std::strcmp(want, "avx2") == 0 && avx2) return batch_kernels_avx2();
    if (avx512) return batch_kernels_avx512();
    if (avx2) return batch_kernels_avx2();
    return batch_kernels_generic();
  }();
  return k;
}

}  // namespace lambert::formfactor::detail

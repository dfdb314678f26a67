#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "batch.hpp"

namespace lambert::formfactor::detail {

// The best variant the CPU supports; the environment variable LAMBERT_ISA=avx2|generic picks a lesser one (to
// measure the AVX2 or baseline code on an AVX-512 machine). A variant the CPU lacks is never picked: a request the
// CPU cannot meet, or a value that names no variant, is said once on stderr and the best variant used.
const BatchKernels& batch_kernels() {
  static const BatchKernels& k = [] () -> const BatchKernels& {
    __builtin_cpu_init();
    const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq");
    const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    const BatchKernels& best =
        avx512 ? batch_kernels_avx512() : avx2 ? batch_kernels_avx2() : batch_kernels_generic();
    const char* want = std::getenv("LAMBERT_ISA");
    if (!want || !*want) return best;
    if (std::strcmp(want, "generic") == 0) return batch_kernels_generic();
    if (std::strcmp(want, "avx2") == 0 && avx2) return batch_kernels_avx2();
    if (std::strcmp(want, "avx512") == 0 && avx512) return batch_kernels_avx512();
    std::fprintf(stderr, "lambert: warning: LAMBERT_ISA=%s %s; using %s\n", want,
                 std::strcmp(want, "avx2") == 0 || std::strcmp(want, "avx512") == 0
                     ? "is not supported by this CPU"
                     : "names no kernel set (avx512, avx2 or generic)",
                 best.name);
    return best;
  }();
  return k;
}

}  // namespace lambert::formfactor::detail

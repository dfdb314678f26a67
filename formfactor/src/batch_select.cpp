#include "batch.hpp"

namespace lambert::formfactor::detail {

const BatchKernels& batch_kernels() {
  static const BatchKernels& k = [] () -> const BatchKernels& {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")) return batch_kernels_avx512();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return batch_kernels_avx2();
    return batch_kernels_generic();
  }();
  return k;
}

}  // namespace lambert::formfactor::detail

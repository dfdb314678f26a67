#pragma once
// The SIMD kernel sets this CPU can run (formfactor/src/batch.hpp): the baseline always, AVX2 and AVX-512 where
// supported; the kernel tests compare every one of them.
#include <vector>

#include "../formfactor/src/batch.hpp"

namespace lambert::batchtest {

inline std::vector<const formfactor::detail::BatchKernels*> supported_kernels() {
  namespace fd = formfactor::detail;
  std::vector<const fd::BatchKernels*> v{&fd::batch_kernels_generic()};
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) v.push_back(&fd::batch_kernels_avx2());
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq")) v.push_back(&fd::batch_kernels_avx512());
  return v;
}

}  // namespace lambert::batchtest

#pragma once
// The rational part of the kernels' atan2 (internal.hpp for scalars, isa/batch.cpp for SIMD lanes): Cephes atan on
// [0, 0.66] (|t| <= 0.66 after the reduction atan(a) = pi/4 + atan((a - 1)/(a + 1)) for a > 0.66); ~1 ulp. T is
// double or a GCC vector of doubles (the same expression, so both give the same bits).
namespace lambert::formfactor::detail {

constexpr double kAtanSplit = 0.66;                       // above it, the pi/4 reduction
constexpr double kPio4Tail = 3.061616997868382943065e-17;  // pi/4 - double(pi/4)

template <class T>
inline T atan_reduced(T t) {
  const T t2 = t * t;
  const T p = (((-8.750608600031904122785e-1 * t2 - 1.615753718733365076637e1) * t2 - 7.500855792314704667340e1) * t2 -
               1.228866684490136173410e2) * t2 - 6.485021904942025371773e1;
  const T q = ((((t2 + 2.485846490142306297962e1) * t2 + 1.650270098316988542046e2) * t2 + 4.328810604912902668951e2) *
                   t2 + 4.853903996359136964868e2) * t2 + 1.945506571482613964425e2;
  return t + t * (t2 * p / q);
}

}  // namespace lambert::formfactor::detail

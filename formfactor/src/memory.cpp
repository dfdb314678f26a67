// The dense matrix: size check before allocating, allocation, huge pages.
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <new>
#include <string>

#include "assembler.hpp"

namespace lambert::formfactor::detail {

std::size_t default_max_bytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return std::size_t(8) << 30;
  return std::size_t(0.8 * double(pages) * double(page));
}

void check_matrix_size(int n, std::size_t max_bytes) {
  const std::size_t bytes = DenseMatrixOperator::bytes_for(std::size_t(n));
  const std::size_t limit = max_bytes ? max_bytes : default_max_bytes();
  if (bytes > limit)
    throw InputError("form factors: the dense matrix for " + std::to_string(n) + " patches needs " +
                     std::to_string(bytes) + " bytes (" + std::to_string(n) + "^2 doubles), more than the " +
                     std::to_string(limit) + " bytes allowed" +
                     (max_bytes ? std::string(" (max_bytes)") : std::string(" (80% of physical memory)")) +
                     "; use fewer patches");
}

void allocate_matrix(DenseMatrixOperator::Matrix& F, int n) {
  const std::size_t bytes = DenseMatrixOperator::bytes_for(std::size_t(n));
  try {
    F.resize(n, n);
  } catch (const std::bad_alloc&) {
    throw InputError("form factors: cannot allocate the dense matrix for " + std::to_string(n) + " patches (" +
                     std::to_string(bytes) + " bytes)");
  }
  // Transparent huge pages for the big matrix: 512x fewer page faults and TLB misses when writing it.
  if (bytes >= (std::size_t(64) << 20)) {
    const std::uintptr_t b0 = (reinterpret_cast<std::uintptr_t>(F.data()) + (std::uintptr_t(2) << 20) - 1) &
                              ~((std::uintptr_t(2) << 20) - 1);
    const std::uintptr_t b1 = (reinterpret_cast<std::uintptr_t>(F.data()) + bytes) & ~((std::uintptr_t(2) << 20) - 1);
    if (b1 > b0) madvise(reinterpret_cast<void*>(b0), b1 - b0, MADV_HUGEPAGE);  // advisory: failure is harmless
  }
}

}  // namespace lambert::formfactor::detail

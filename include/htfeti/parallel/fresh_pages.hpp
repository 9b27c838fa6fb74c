// Fresh pages in one call: a large block just allocated is made resident with
// madvise(MADV_POPULATE_WRITE) (Linux 5.14 and later) before it is written, instead of one page
// fault per 4 KiB page as it is first touched. The pages and their contents are the same;
// only the way the kernel supplies them differs. On the virtual machines measured
// (docs/performance.md, "Fresh pages in one call") a page fault costs about 11 us and a page
// made resident this way about half; the subdomain factors and their single-precision copies
// are most of the pages a METIS-split run touches.
#pragma once

#include <Eigen/SparseCore>
#include <cstddef>
#include <vector>

namespace htfeti {

/// Blocks of at least this many bytes are made resident in one call.
inline constexpr std::size_t kPopulateBytes = std::size_t(1) << 20;

/// Makes the whole 4 KiB pages inside [p, p + bytes) resident and writable, when bytes >=
/// kPopulateBytes (smaller blocks mostly reuse pages the allocator already has). Does nothing
/// where the kernel does not support it (the first refusal turns it off). Thread-safe.
void populate(void* p, std::size_t bytes);

/// M becomes a compressed rows x cols matrix with room for nnz entries (the column starts to be
/// written by the caller), its value and row arrays resident (populate()).
inline void resize_resident(Eigen::SparseMatrix<double>& M, Eigen::Index rows, Eigen::Index cols,
                            Eigen::Index nnz) {
  M.resize(rows, cols);
  M.makeCompressed();
  M.resizeNonZeros(nnz);
  populate(M.valuePtr(), sizeof(double) * static_cast<std::size_t>(nnz));
  populate(M.innerIndexPtr(), sizeof(int) * static_cast<std::size_t>(nnz));
}

/// v becomes n value-initialized elements (zeros for numbers) in new storage made resident
/// before it is written (populate()): the old contents are dropped. For arrays of known final
/// size that would otherwise be grown, or zeroed page by page.
template <class T>
void resize_resident(std::vector<T>& v, std::size_t n) {
  std::vector<T>().swap(v);
  v.reserve(n);
  populate(v.data(), sizeof(T) * n);
  v.resize(n);
}

/// Routes CHOLMOD's allocations (SuiteSparse_config's malloc, calloc, realloc and free)
/// through populate() and, for blocks of kPopulateBytes and more, a pool that keeps freed
/// blocks (up to 256 MiB) for the next ones, so that the blocks one factorization frees serve
/// the next with pages already resident (off under AddressSanitizer). Called once before the
/// first factorization; idempotent and thread-safe.
void populate_cholmod_allocations();

/// While an object of this class lives, CHOLMOD's blocks allocated on its thread are taken
/// from the pool at their own size: an idle block larger by kPopulateBytes or more gives up its
/// tail, which stays idle. For factors kept for the whole run beside the subdomains' (the
/// implicit Dirichlet preconditioner's): served whole, they took the larger blocks that a
/// subdomain's factorization frees for the next and kept all of them (on the 80^3 METIS cube
/// with one layer: 2.9 GB more peak memory, and fresh pages for the subdomains' factors that
/// made the factorization phase 6-9 s longer; docs/performance.md, "The layered Dirichlet
/// preconditioner"). Nests.
class KeptAllocations {
 public:
  KeptAllocations();
  ~KeptAllocations();
  KeptAllocations(const KeptAllocations&) = delete;
  KeptAllocations& operator=(const KeptAllocations&) = delete;

 private:
  bool previous_;
};

/// Returns the pool's idle blocks to the system (after the factorizations of a setup).
/// Thread-safe.
void release_idle_blocks();

}  // namespace htfeti

#include "htfeti/feti/sparse_cholesky.hpp"

#include <cholmod.h>
#include <stdlib.h>  // random_r, initstate_r (glibc)

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "htfeti/parallel/blas_buffers.hpp"
#include "htfeti/parallel/fresh_pages.hpp"

extern "C" void dpotri_(const char* uplo, const int* n, double* a, const int* lda, int* info);

namespace htfeti {

namespace {
// A CHOLMOD call failed: out of memory (CHOLMOD_OUT_OF_MEMORY, or CHOLMOD_TOO_LARGE for a size
// beyond its integers) is std::bad_alloc, so the run ends with "out of memory" (exit 2) as any
// other allocation failure; anything else is a numerical failure with the status in the message.
[[noreturn]] void cholmod_failed(const cholmod_common& c, const char* what) {
  if (c.status == CHOLMOD_OUT_OF_MEMORY || c.status == CHOLMOD_TOO_LARGE) throw std::bad_alloc();
  throw std::runtime_error(std::string(what) + " (CHOLMOD status " + std::to_string(c.status) +
                           ")");
}
}  // namespace

Ordering parse_ordering(const std::string& name) {
  return parse_name(kOrderingNames, name, "ordering");
}

std::string to_string(Ordering value) { return name_of(kOrderingNames, value); }

namespace {
// A is its own upper triangle: compressed, with no entry below the diagonal (Subdomain's K_rr).
bool is_upper_triangle(const Eigen::SparseMatrix<double>& A) {
  if (!A.isCompressed()) return false;
  const int* p = A.outerIndexPtr();
  const int* i = A.innerIndexPtr();
  for (Eigen::Index c = 0; c < A.cols(); ++c)
    for (int k = p[c]; k < p[c + 1]; ++k)
      if (i[k] > c) return false;
  return true;
}

// The upper triangle of A (rows <= column), column by column, into arrays made resident in one
// call each (parallel/fresh_pages.hpp): the matrix of A.triangularView<Eigen::Upper>().
Eigen::SparseMatrix<double> upper_triangle(const Eigen::SparseMatrix<double>& A) {
  using It = Eigen::SparseMatrix<double>::InnerIterator;
  const Eigen::Index n = A.cols();
  Eigen::Index nnz = 0;
  for (Eigen::Index c = 0; c < n; ++c)
    for (It it(A, c); it; ++it) nnz += it.row() <= c;
  Eigen::SparseMatrix<double> U;
  resize_resident(U, A.rows(), n, nnz);
  int* outer = U.outerIndexPtr();
  int* inner = U.innerIndexPtr();
  double* value = U.valuePtr();
  Eigen::Index k = 0;
  outer[0] = 0;
  for (Eigen::Index c = 0; c < n; ++c) {
    for (It it(A, c); it; ++it)
      if (it.row() <= c) inner[k] = static_cast<int>(it.row()), value[k++] = it.value();
    outer[c + 1] = static_cast<int>(k);
  }
  return U;
}

// A CHOLMOD view (no copy) of the upper triangle `upper` (compressed), stype = 1. CHOLMOD's
// analysis and factorization read the matrix only.
cholmod_sparse upper_view(const Eigen::SparseMatrix<double>& upper) {
  if (!upper.isCompressed()) throw std::logic_error("upper_view: the matrix is not compressed");
  cholmod_sparse view{};
  view.nrow = view.ncol = static_cast<size_t>(upper.rows());
  view.nzmax = static_cast<size_t>(upper.nonZeros());
  view.p = const_cast<int*>(upper.outerIndexPtr());
  view.i = const_cast<int*>(upper.innerIndexPtr());
  view.x = const_cast<double*>(upper.valuePtr());
  view.stype = 1;  // upper triangle stored
  view.itype = CHOLMOD_INT;
  view.xtype = CHOLMOD_REAL;
  view.dtype = CHOLMOD_DOUBLE;
  view.sorted = 1;
  view.packed = 1;
  return view;
}

// The numeric factorization of `view` into the analysed L (its values made or overwritten), with
// BLAS on one thread (the same bits on any number of threads, blas_buffers.hpp); CHOLMOD's
// workspace freed after (O(n) per factor: not kept). Throws if A is not positive definite.
void factor_numeric(cholmod_sparse& view, cholmod_factor* L, cholmod_common& c) {
  {
    const BlasOnOneThread one;
    cholmod_factorize(&view, L, &c);
  }
  if (c.status == CHOLMOD_NOT_POSDEF || L->minor < L->n)
    throw std::runtime_error("CHOLMOD: matrix is not positive definite");
  if (c.status < 0) cholmod_failed(c, "CHOLMOD factorization failed");
  cholmod_free_work(&c);
}

// The key of a right-hand side for the memos below: its nonzeros (position, value) and their
// FNV-1a hash. Keys are compared in full (positions and values), not only by the hash.
std::uint64_t nonzero_key(const double* x, long n, std::vector<long>& at,
                          std::vector<double>& value) {
  std::uint64_t hash = 1469598103934665603ULL;
  for (long k = 0; k < n; ++k)
    if (x[k] != 0.0) {
      std::uint64_t w;
      std::memcpy(&w, x + k, sizeof w);
      hash = ((hash ^ static_cast<std::uint64_t>(k)) * 1099511628211ULL ^ w) * 1099511628211ULL;
      at.push_back(k);
      value.push_back(x[k]);
    }
  return hash;
}
}  // namespace

// What the holders of one cached numeric factor (the entry and the factorizations of equal
// matrices) share besides the factor: S^{-1}, computed by the first that asks
// (SparseCholesky::schur_inverse), and the solves done so far.
struct SharedFactor {
  std::mutex mutex;
  // make_single()'s copy of the factor's values, made once for all holders.
  std::shared_ptr<const std::vector<float>> single;
  std::shared_ptr<const SparseCholesky::SchurInverse> value;
  // solve_many's results for the right-hand sides solved so far with this factor (the same bit
  // for bit in every holder of the slot): the input's nonzeros (position, value) and the
  // solution, at most kMaxSolves of them.
  struct Solve {
    int ncols = 0;
    std::uint64_t hash = 0;
    std::vector<long> at;
    std::vector<double> value, out;
  };
  static constexpr int kMaxSolves = 16;
  std::vector<std::shared_ptr<const Solve>> solves;
  long solve_reuses = 0;
  // shared_result's results, held once for all holders: the key (its nonzeros and tag) and the
  // result, null while the first holder that asked computes it (the others wait on `ready`).
  struct Result {
    std::uint64_t hash = 0;
    Eigen::Index rows = 0, cols = 0;
    std::vector<long> at;
    std::vector<double> value;
    std::vector<int> tag;
    std::shared_ptr<const Eigen::MatrixXd> out;
    bool failed = false;  // its compute() threw: those who waited compute their own
  };
  static constexpr int kMaxResults = 64;
  std::vector<std::shared_ptr<Result>> results;
  std::condition_variable ready;
  long result_reuses = 0;
};

// One cached symbolic analysis: the pattern it belongs to (compared in full) and the symbolic
// factor, allocated through the cache's own CHOLMOD common.
struct SubdomainCache::Entry {
  std::uint64_t hash = 0;
  int method = 0;  // Impl::method, plus 3 with `last` ordered last
  std::vector<int> p, i, last;
  std::uint64_t value_hash = 0;  // numeric entries: the values and their hash
  std::vector<double> x;
  double bytes = 0;
  long factor_bytes = 0;               // numeric entries: the factor's part of `bytes`
  std::shared_ptr<SharedFactor> slot;  // numeric entries: what their holders share
  cholmod_common common;
  cholmod_factor* L = nullptr;              // symbolic entries: the analysis (copied by its users)
  std::shared_ptr<cholmod_factor> numeric;  // numeric entries: the factor, shared by its users
  Entry() { cholmod_start(&common), common.print = 0, common.error_handler = nullptr; }
  ~Entry() {
    cholmod_free_factor(&L, &common);
    cholmod_finish(&common);
  }
};

SubdomainCache::SubdomainCache(int capacity, double numeric_bytes)
    : capacity_(capacity), numeric_bytes_(numeric_bytes) {}
long SubdomainCache::numeric_reuses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return numeric_reuses_;
}
long SubdomainCache::solve_reuses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  long n = 0;
  for (const auto& e : numeric_)
    if (e->slot) {
      std::lock_guard<std::mutex> slot_lock(e->slot->mutex);
      n += e->slot->solve_reuses + e->slot->result_reuses;
    }
  return n;
}
int SubdomainCache::matrices() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(numeric_.size());
}
double SubdomainCache::kept_factor_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  double bytes = 0;
  for (const auto& e : numeric_) bytes += static_cast<double>(e->factor_bytes);
  return bytes;
}
SubdomainCache::~SubdomainCache() = default;

std::shared_ptr<const SubdomainCache::Matrix> SubdomainCache::intern_matrix(Matrix& K) {
  K.makeCompressed();
  const long nnz = K.nonZeros();
  std::uint64_t h = 1469598103934665603ULL;  // FNV-1a over the sizes and the values' bits
  auto mix = [&](std::uint64_t v) { h = (h ^ v) * 1099511628211ULL; };
  mix(static_cast<std::uint64_t>(K.rows())), mix(static_cast<std::uint64_t>(nnz));
  for (long k = 0; k < nnz; ++k) {
    std::uint64_t bits;
    std::memcpy(&bits, K.valuePtr() + k, sizeof bits);
    mix(bits);
  }
  auto equal = [&](const Matrix& A) {
    return A.rows() == K.rows() && A.cols() == K.cols() && A.nonZeros() == nnz &&
           std::equal(A.outerIndexPtr(), A.outerIndexPtr() + A.outerSize() + 1,
                      K.outerIndexPtr()) &&
           std::equal(A.innerIndexPtr(), A.innerIndexPtr() + nnz, K.innerIndexPtr()) &&
           std::memcmp(A.valuePtr(), K.valuePtr(), sizeof(double) * nnz) == 0;
  };
  std::vector<std::shared_ptr<const Matrix>> candidates;  // compared outside the lock
  {
    std::lock_guard<std::mutex> lock(matrix_mutex_);
    const auto [first, last] = held_matrices_.equal_range(h);
    for (auto it = first; it != last; ++it)
      if (auto A = it->second.lock()) candidates.push_back(std::move(A));
  }
  for (auto& A : candidates)
    if (equal(*A)) {
      Matrix().swap(K);
      std::lock_guard<std::mutex> lock(matrix_mutex_);
      ++matrix_reuses_;
      return std::move(A);
    }
  // (An equal matrix interned meanwhile by another thread is simply held twice.)
  auto A = std::make_shared<Matrix>();
  A->swap(K);
  std::lock_guard<std::mutex> lock(matrix_mutex_);
  held_matrices_.emplace(h, A);
  return A;
}

long SubdomainCache::matrix_reuses() const {
  std::lock_guard<std::mutex> lock(matrix_mutex_);
  return matrix_reuses_;
}

long SubdomainCache::analyses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return analyses_;
}
long SubdomainCache::reuses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return reuses_;
}
int SubdomainCache::patterns() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int>(entries_.size());
}

namespace {
// A numeric factor held by several owners (a numeric cache entry and the factorizations of equal
// matrices), freed with the last of them. It is only read once factored (solves, the Schur
// block), and every holder solves with its own CHOLMOD common and work arrays, so holders in
// different threads solve with it at the same time.
std::shared_ptr<cholmod_factor> share_factor(cholmod_factor* L) {
  return std::shared_ptr<cholmod_factor>(L, [](cholmod_factor* f) {
    cholmod_common c;
    cholmod_start(&c);
    cholmod_free_factor(&f, &c);
    cholmod_finish(&c);
  });
}
}  // namespace

// METIS draws its random numbers from the C library's rand(), reseeded (srand) at the start of
// every call: with the C library's one state for the process, two threads ordering at once would
// interleave their draws and get orderings that depend on the timing. The program defines rand()
// and srand() itself, with the C library's generator (random_r over a 128-byte state: the
// TYPE_3 generator of glibc's rand(), which starts as if seeded with 1) and one state per
// thread, so that every METIS call draws the sequence its own seed gives whatever runs beside
// it: the same orderings and partitions as from glibc's rand(), bit for bit, and the orderings
// of several threads at once.
namespace {
struct ThreadRandom {
  random_data data{};
  char state[128] = {};
  bool seeded = false;
  void seed(unsigned s) {
    data = random_data{};
    initstate_r(s, state, sizeof state, &data);
    seeded = true;
  }
};
thread_local ThreadRandom thread_random;
}  // namespace
}  // namespace htfeti

extern "C" int rand() noexcept {
  htfeti::ThreadRandom& r = htfeti::thread_random;
  if (!r.seeded) r.seed(1);
  std::int32_t value = 0;
  random_r(&r.data, &value);
  return value;
}
extern "C" void srand(unsigned seed) noexcept { htfeti::thread_random.seed(seed); }

namespace htfeti {

struct SparseCholesky::Impl {
  cholmod_common common;
  cholmod_factor* factor = nullptr;
  cholmod_dense* x = nullptr;  // solve work arrays, reused (cholmod_solve2)
  cholmod_dense* y = nullptr;
  cholmod_dense* e = nullptr;
  int n = 0;
  int nlast = 0;   // rows ordered last by factorize(A, last)
  int method = 0;  // 0 AMD, 1 METIS, 2 nesdis (the constructor's ordering)
  double symbolic_seconds = 0, numeric_seconds = 0;
  std::shared_ptr<SharedFactor> slot;  // shared with a numeric cache entry, if any
  bool memo_solves = false;            // solve() through solve_many's memo (interface-last factors)
  std::shared_ptr<cholmod_factor> shared;        // set when `factor` is a numeric cache entry's
  std::shared_ptr<const std::vector<float>> xs;  // make_single(): L's values, single precision
  std::vector<double> sy, st;  // solve_single(): permuted vector, rows below a supernode
  // keep_single_only(): the factor's values dropped (L symbolic again; a shared factor keeps
  // them), A's upper triangle kept for the refinement of double solves, its infinity norm, and
  // the refinement's work arrays.
  bool refine = false;
  Eigen::SparseMatrix<double> a;
  double anorm = 0;
  std::vector<double> rb, rr;
  long refined_solves = 0, refinement_steps = 0;
  bool refactored = false;

  explicit Impl(Ordering ordering)
      : method(ordering == Ordering::amd      ? 0
               : ordering == Ordering::nesdis ? 2
                                              : 1) {
    populate_cholmod_allocations();  // the factors' pages in one call each (fresh_pages.hpp)
    cholmod_start(&common);
    common.print = 0;
    common.error_handler = nullptr;
    common.supernodal = CHOLMOD_SUPERNODAL;
    common.nmethods = 1;
    common.method[0].ordering = method == 0   ? CHOLMOD_AMD
                                : method == 2 ? CHOLMOD_NESDIS
                                              : CHOLMOD_METIS;
    common.postorder = 1;
  }
  ~Impl() {
    cholmod_free_dense(&x, &common);
    cholmod_free_dense(&y, &common);
    cholmod_free_dense(&e, &common);
    drop_factor();
    cholmod_finish(&common);
  }
  void drop_factor() {
    xs.reset();
    Eigen::SparseMatrix<double>().swap(a);
    std::vector<double>().swap(rb), std::vector<double>().swap(rr);
    refine = refactored = false;
    if (shared)
      factor = nullptr, shared.reset();
    else
      cholmod_free_factor(&factor, &common);
  }
};

SparseCholesky::SparseCholesky(Ordering ordering) : impl_(std::make_unique<Impl>(ordering)) {}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

void SparseCholesky::factorize(const Eigen::SparseMatrix<double>& A, SubdomainCache* cache) {
  factorize_impl(A, nullptr, cache);
}

void SparseCholesky::factorize(const Eigen::SparseMatrix<double>& A, const std::vector<int>& last,
                               SubdomainCache* cache) {
  factorize_impl(A, &last, cache);
}

double SparseCholesky::symbolic_seconds() const { return impl_->symbolic_seconds; }
double SparseCholesky::numeric_seconds() const { return impl_->numeric_seconds; }

// The symbolic analysis of A (upper triangle `upper`, CHOLMOD view `view`) with the rows in `last`
// ordered after all others: constrained AMD (method 0), or nested dissection of the other rows
// (METIS_NodeND: method 1, CHOLMOD's: method 2), then the rows of `last`; postordered when that
// keeps them last. Throws if CHOLMOD fails.
static cholmod_factor* analyze_with_last(cholmod_sparse& view,
                                         const Eigen::SparseMatrix<double>& upper,
                                         const std::vector<int>& last, int method,
                                         cholmod_common& c) {
  const int n = static_cast<int>(upper.rows());
  cholmod_factor* factor = nullptr;
  std::vector<int> cmember(n, 0), perm(n);
  for (int r : last) cmember[r] = 1;
  if (method == 0) {
    // Constrained AMD: set 0 first, then set 1 (`last`).
    if (!cholmod_camd(&view, nullptr, 0, cmember.data(), perm.data(), &c))
      cholmod_failed(c, "CHOLMOD: constrained ordering failed");
  } else {
    // Nested dissection of the rows not in `last`, then `last`.
    std::vector<int> inner, index(n, -1);
    for (int r = 0; r < n; ++r)
      if (!cmember[r]) index[r] = static_cast<int>(inner.size()), inner.push_back(r);
    const int ni = static_cast<int>(inner.size());
    std::vector<Eigen::Triplet<double>> t;
    for (int col = 0; col < n; ++col)
      for (Eigen::SparseMatrix<double>::InnerIterator it(upper, col); it; ++it)
        if (index[it.row()] >= 0 && index[col] >= 0)
          t.emplace_back(index[it.row()], index[col], it.value());
    Eigen::SparseMatrix<double> Aii(ni, ni);
    Aii.setFromTriplets(t.begin(), t.end());
    cholmod_sparse vi = upper_view(Aii);
    std::vector<int> pi(ni);
    if (ni > 0) {
      // The matrix is a valid symmetric pattern built here, so METIS fails only when its own
      // allocations do (it reports METIS_ERROR, which CHOLMOD passes on as CHOLMOD_INVALID):
      // out of memory, as measured under an address-space limit.
      if (method == 2) {  // CHOLMOD's nested dissection: its tree of parts is not needed
        std::vector<int> cparent(ni), cmember_i(ni);
        if (cholmod_nested_dissection(&vi, nullptr, 0, pi.data(), cparent.data(), cmember_i.data(),
                                      &c) < 0)
          throw std::bad_alloc();
      } else if (!cholmod_metis(&vi, nullptr, 0, 1, pi.data(), &c)) {
        throw std::bad_alloc();
      }
    }
    int k = 0;
    for (int q = 0; q < ni; ++q) perm[k++] = inner[pi[q]];
    for (int r = 0; r < n; ++r)
      if (cmember[r]) perm[k++] = r;
  }
  const int saved_nmethods = c.nmethods, saved_ordering = c.method[0].ordering;
  const int saved_postorder = c.postorder;
  c.nmethods = 1;
  c.method[0].ordering = CHOLMOD_GIVEN;
  // Postordering gives larger supernodes (less padding, faster solves) and usually keeps the
  // trailing set last; if it does not, analyze again without it.
  for (int post = 1; post >= 0; --post) {
    c.postorder = post;
    factor = cholmod_analyze_p(&view, perm.data(), nullptr, 0, &c);
    if (!factor) break;
    const int* fp = static_cast<const int*>(factor->Perm);
    bool tail_ok = true;
    for (int p = n - static_cast<int>(last.size()); p < n && tail_ok; ++p)
      tail_ok = cmember[fp[p]] == 1;
    if (tail_ok) break;
    cholmod_free_factor(&factor, &c);
  }
  c.nmethods = saved_nmethods;
  c.method[0].ordering = saved_ordering;
  c.postorder = saved_postorder;
  if (!factor) cholmod_failed(c, "CHOLMOD analysis failed");
  return factor;
}

void SparseCholesky::factorize_impl(const Eigen::SparseMatrix<double>& A,
                                    const std::vector<int>* last, SubdomainCache* cache) {
  if (A.rows() != A.cols()) throw std::invalid_argument("SparseCholesky: matrix is not square");
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto& c = impl_->common;
  // K_rr comes as its upper triangle already (Subdomain::reduced_matrix): read in place.
  const bool in_place = is_upper_triangle(A);
  const Eigen::SparseMatrix<double> copy =
      in_place ? Eigen::SparseMatrix<double>() : upper_triangle(A);
  const Eigen::SparseMatrix<double>& upper = in_place ? A : copy;
  cholmod_sparse view = upper_view(upper);
  impl_->drop_factor();
  impl_->slot.reset();
  impl_->memo_solves = last != nullptr;
  impl_->nlast = last ? static_cast<int>(last->size()) : 0;

  // The pattern's key for the cache: method, the sorted set ordered last, the upper triangle.
  const int n = static_cast<int>(A.rows()), nnz = static_cast<int>(upper.nonZeros());
  const int method = last ? 3 + impl_->method : impl_->method;
  std::vector<int> last_sorted;
  std::uint64_t hash = 1469598103934665603ULL;  // FNV-1a
  const auto mix = [&hash](const int* v, long len) {
    for (long k = 0; k < len; ++k)
      hash = (hash ^ static_cast<std::uint32_t>(v[k])) * 1099511628211ULL;
  };
  const auto same = [&](const SubdomainCache::Entry& e) {
    return e.hash == hash && e.method == method && static_cast<int>(e.p.size()) == n + 1 &&
           static_cast<int>(e.i.size()) == nnz && e.last == last_sorted &&
           std::equal(e.p.begin(), e.p.end(), upper.outerIndexPtr()) &&
           std::equal(e.i.begin(), e.i.end(), upper.innerIndexPtr());
  };
  // A cache entry for this pattern: a copy of the current (symbolic) factor, or with `numeric`
  // the current numeric factor itself, from then on shared by this factorization and the entry.
  const auto new_entry = [&](bool numeric) {
    auto e = std::make_unique<SubdomainCache::Entry>();
    e->hash = hash;
    e->method = method;
    e->p.assign(upper.outerIndexPtr(), upper.outerIndexPtr() + n + 1);
    e->i.assign(upper.innerIndexPtr(), upper.innerIndexPtr() + nnz);
    e->last = last_sorted;
    if (numeric) {
      if (!impl_->shared) {  // (should share_factor throw, its deleter has freed the factor)
        cholmod_factor* own = impl_->factor;
        impl_->factor = nullptr;
        impl_->shared = share_factor(own);
        impl_->factor = impl_->shared.get();
      }
      e->numeric = impl_->shared;
    } else {
      e->L = cholmod_copy_factor(impl_->factor, &e->common);
      if (!e->L) throw std::bad_alloc();
    }
    return e;
  };
  bool reused = false;
  std::uint64_t value_hash = 1469598103934665603ULL;
  const auto same_values = [&](const SubdomainCache::Entry& e) {
    return e.value_hash == value_hash && same(e) &&
           std::equal(e.x.begin(), e.x.end(), upper.valuePtr());
  };
  if (cache) {
    if (last) {
      last_sorted = *last;
      std::sort(last_sorted.begin(), last_sorted.end());
    }
    mix(&method, 1);
    mix(&n, 1);
    mix(last_sorted.data(), static_cast<long>(last_sorted.size()));
    mix(upper.outerIndexPtr(), n + 1);
    mix(upper.innerIndexPtr(), nnz);
    if (cache->numeric_bytes_ > 0) {
      for (long k = 0; k < nnz; ++k) {  // FNV-1a over the values' 64-bit words
        std::uint64_t w;
        std::memcpy(&w, upper.valuePtr() + k, sizeof w);
        value_hash = (value_hash ^ w) * 1099511628211ULL;
      }
    }
    // Entries are never removed while the cache lives, so a found one is used outside the lock
    // (the analysis copies of two threads do not wait for each other).
    const SubdomainCache::Entry* numeric = nullptr;
    const SubdomainCache::Entry* symbolic = nullptr;
    {
      std::lock_guard<std::mutex> lock(cache->mutex_);
      for (const auto& e : cache->numeric_)
        if (same_values(*e)) {
          numeric = e.get();
          ++cache->numeric_reuses_;
          break;
        }
      if (!numeric)
        for (const auto& e : cache->entries_)
          if (same(*e)) {
            symbolic = e.get();
            ++cache->reuses_;
            break;
          }
    }
    if (numeric) {  // an equal matrix was factored: its factor, shared (read only)
      impl_->shared = numeric->numeric;
      impl_->factor = impl_->shared.get();
      impl_->slot = numeric->slot;
      impl_->n = n;
      impl_->symbolic_seconds = std::chrono::duration<double>(clock::now() - t0).count();
      impl_->numeric_seconds = 0;
      return;
    }
    if (symbolic) {
      impl_->factor = cholmod_copy_factor(symbolic->L, &c);
      if (!impl_->factor) throw std::bad_alloc();
      reused = true;
    }
  }
  if (reused) {
    // the cached analysis is the one this pattern would get
  } else if (last) {
    impl_->factor = analyze_with_last(view, upper, *last, impl_->method, c);
  } else {
    impl_->factor = cholmod_analyze(&view, &c);
  }
  if (!impl_->factor) cholmod_failed(c, "CHOLMOD analysis failed");
  if (cache && !reused) {
    std::lock_guard<std::mutex> lock(cache->mutex_);
    bool known = false;  // another thread may have added the same pattern meanwhile
    for (const auto& e : cache->entries_) known = known || same(*e);
    ++cache->analyses_;
    if (!known && static_cast<int>(cache->entries_.size()) < cache->capacity_) {
      auto e = new_entry(false);
      if (e->L) cache->entries_.push_back(std::move(e));
    }
  }
  const auto t1 = clock::now();
  factor_numeric(view, impl_->factor, c);
  impl_->n = static_cast<int>(A.rows());
  const auto t2 = clock::now();
  // A repeated pattern (its analysis was reused): keep this numeric factor for equal matrices.
  if (cache && reused && cache->numeric_bytes_ > 0) {
    const double bytes =
        static_cast<double>(factor_bytes()) + 8.0 * nnz + 8.0 * impl_->nlast * impl_->nlast;
    std::lock_guard<std::mutex> lock(cache->mutex_);
    bool known = false;
    for (const auto& e : cache->numeric_) known = known || same_values(*e);
    if (!known && cache->numeric_held_ + bytes <= cache->numeric_bytes_) {
      auto e = new_entry(true);
      e->value_hash = value_hash;
      e->x.assign(upper.valuePtr(), upper.valuePtr() + nnz);
      e->bytes = bytes;
      e->factor_bytes = factor_bytes();
      e->slot = impl_->slot = std::make_shared<SharedFactor>();
      cache->numeric_held_ += bytes;
      cache->numeric_.push_back(std::move(e));
    }
  }
  impl_->symbolic_seconds = std::chrono::duration<double>(t1 - t0).count();
  impl_->numeric_seconds = std::chrono::duration<double>(t2 - t1).count();
}

void SparseCholesky::solve(const double* b, double* out) {
  if (impl_->refine) return solve_refined(b, out);
  if (impl_->slot && impl_->memo_solves) {  // a shared interface-last factor: the memo
    if (out != b) std::memmove(out, b, sizeof(double) * impl_->n);
    solve_many(out, 1);
    return;
  }
  auto& c = impl_->common;
  cholmod_dense rhs{};
  rhs.nrow = rhs.d = rhs.nzmax = static_cast<size_t>(impl_->n);
  rhs.ncol = 1;
  rhs.x = const_cast<double*>(b);
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  const BlasOnOneThread one;
  if (!cholmod_solve2(CHOLMOD_A, impl_->factor, &rhs, nullptr, &impl_->x, nullptr, &impl_->y,
                      &impl_->e, &c))
    cholmod_failed(c, "CHOLMOD solve failed");
  std::memcpy(out, impl_->x->x, sizeof(double) * impl_->n);
}

void SparseCholesky::solve_many(double* X, int ncols) {
  if (ncols <= 0) return;
  if (impl_->refine) {  // (setup work only: column by column)
    for (int j = 0; j < ncols; ++j) {
      double* x = X + static_cast<long>(impl_->n) * j;
      solve_refined(x, x);
    }
    return;
  }
  // A factor shared through the numeric cache looks the right-hand side up among those already
  // solved with it (equal subdomains with equal constraints: the columns of K_i^+ C_i^T repeat).
  const long total = static_cast<long>(impl_->n) * ncols;
  SharedFactor* slot = impl_->slot.get();
  std::shared_ptr<SharedFactor::Solve> mine;
  if (slot) {
    mine = std::make_shared<SharedFactor::Solve>();
    mine->ncols = ncols;
    mine->hash = nonzero_key(X, total, mine->at, mine->value);
    std::shared_ptr<const SharedFactor::Solve> found;
    {
      std::lock_guard<std::mutex> lock(slot->mutex);
      for (const auto& e : slot->solves)
        if (e->hash == mine->hash && e->ncols == ncols && e->at == mine->at &&
            e->value == mine->value) {
          found = e;
          ++slot->solve_reuses;
          break;
        }
    }
    if (found) {
      std::memcpy(X, found->out.data(), sizeof(double) * total);
      return;
    }
  }
  auto& c = impl_->common;
  cholmod_dense rhs{};
  rhs.nrow = rhs.d = static_cast<size_t>(impl_->n);
  rhs.ncol = static_cast<size_t>(ncols);
  rhs.nzmax = rhs.nrow * rhs.ncol;
  rhs.x = X;
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  // Work arrays of this call: solve()'s are sized for one column and stay so.
  cholmod_dense *x = nullptr, *y = nullptr, *e = nullptr;
  bool ok = false;
  {
    const BlasOnOneThread one;
    ok = cholmod_solve2(CHOLMOD_A, impl_->factor, &rhs, nullptr, &x, nullptr, &y, &e, &c);
  }
  if (ok) std::memcpy(X, x->x, sizeof(double) * rhs.nzmax);
  cholmod_free_dense(&x, &c);
  cholmod_free_dense(&y, &c);
  cholmod_free_dense(&e, &c);
  if (!ok) cholmod_failed(c, "CHOLMOD solve failed");
  if (slot) {
    std::lock_guard<std::mutex> lock(slot->mutex);
    if (static_cast<int>(slot->solves.size()) < SharedFactor::kMaxSolves) {
      mine->out.assign(X, X + total);
      slot->solves.push_back(std::move(mine));
    }
  }
}

std::shared_ptr<const Eigen::MatrixXd> SparseCholesky::shared_result(
    const Eigen::MatrixXd& key, const std::vector<int>& tag,
    const std::function<Eigen::MatrixXd()>& compute) {
  SharedFactor* slot = impl_->slot.get();
  if (!slot) return std::make_shared<const Eigen::MatrixXd>(compute());
  auto mine = std::make_shared<SharedFactor::Result>();
  mine->rows = key.rows(), mine->cols = key.cols(), mine->tag = tag;
  std::uint64_t hash = nonzero_key(key.data(), key.size(), mine->at, mine->value);
  for (int t : tag) hash = (hash ^ static_cast<std::uint64_t>(t)) * 1099511628211ULL;
  mine->hash = hash;
  {
    std::unique_lock<std::mutex> lock(slot->mutex);
    std::shared_ptr<SharedFactor::Result> e;
    for (const auto& held : slot->results)
      if (held->hash == hash && held->rows == mine->rows && held->cols == mine->cols &&
          held->at == mine->at && held->value == mine->value && held->tag == mine->tag) {
        e = held;  // held by pointer: the vector may grow meanwhile
        break;
      }
    if (e) {
      slot->ready.wait(lock, [&] { return e->out != nullptr || e->failed; });
      if (!e->failed) {
        ++slot->result_reuses;
        return e->out;
      }
    }
    if (e || static_cast<int>(slot->results.size()) >= SharedFactor::kMaxResults) {
      // Its first holder's compute() threw, or no room for another key: computed unshared.
      lock.unlock();
      return std::make_shared<const Eigen::MatrixXd>(compute());
    }
    slot->results.push_back(mine);  // out still null: equal keys wait for it
  }
  std::shared_ptr<const Eigen::MatrixXd> out;
  try {
    out = std::make_shared<const Eigen::MatrixXd>(compute());
  } catch (...) {  // withdraw the key; those waiting for it compute their own
    {
      std::lock_guard<std::mutex> lock(slot->mutex);
      mine->failed = true;
      slot->results.erase(std::find(slot->results.begin(), slot->results.end(), mine));
    }
    slot->ready.notify_all();
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(slot->mutex);
    mine->out = out;
  }
  slot->ready.notify_all();
  return out;
}

int SparseCholesky::rows() const { return impl_->n; }

void SparseCholesky::make_single() {
  const cholmod_factor* L = impl_->factor;
  if (!L || !L->is_super) throw std::logic_error("make_single: no supernodal factor");
  const auto copy = [L]() {
    const double* Lx = static_cast<const double*>(L->x);
    auto xs = std::make_shared<std::vector<float>>();
    xs->reserve(L->xsize);
    populate(xs->data(), L->xsize * sizeof(float));  // (parallel/fresh_pages.hpp)
    xs->assign(Lx, Lx + L->xsize);
    return std::shared_ptr<const std::vector<float>>(std::move(xs));
  };
  if (impl_->slot) {  // a factor shared through the numeric cache: one copy for all holders
    std::lock_guard<std::mutex> lock(impl_->slot->mutex);
    if (!impl_->slot->single) impl_->slot->single = copy();
    impl_->xs = impl_->slot->single;
  } else {
    impl_->xs = copy();
  }
  const int* pi = static_cast<const int*>(L->pi);
  int widest = 0;
  for (size_t s = 0; s < L->nsuper; ++s) widest = std::max(widest, pi[s + 1] - pi[s]);
  impl_->sy.assign(impl_->n, 0.0);
  impl_->st.assign(widest, 0.0);
}

bool SparseCholesky::has_single() const { return impl_->xs != nullptr; }

bool SparseCholesky::has_double() const {
  return impl_->factor != nullptr && impl_->factor->xtype != CHOLMOD_PATTERN;
}

bool SparseCholesky::keep_single_only(Eigen::SparseMatrix<double>&& A) {
  Impl& m = *impl_;
  if (!m.factor || !m.xs || m.memo_solves || m.refine || !has_double()) return false;
  if (!A.isCompressed() || !is_upper_triangle(A) || A.rows() != m.n)
    throw std::logic_error("keep_single_only: not the factored upper triangle");
  m.a.swap(A);
  std::vector<double> row_sum(m.n, 0.0);  // ||A||_inf of the symmetric A from its upper half
  for (int col = 0; col < m.n; ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(m.a, col); it; ++it) {
      row_sum[it.row()] += std::abs(it.value());
      if (it.row() != col) row_sum[col] += std::abs(it.value());
    }
  m.anorm = m.n > 0 ? *std::max_element(row_sum.begin(), row_sum.end()) : 0.0;
  m.rb.assign(m.n, 0.0), m.rr.assign(m.n, 0.0);
  m.refine = true;
  if (m.shared) return true;  // the holders of a shared factor keep its values
  // Supernodal numeric -> supernodal symbolic: frees L's values (to the block pool), keeps the
  // supernodes, permutation and row indices that solve_single() reads.
  if (!cholmod_change_factor(CHOLMOD_PATTERN, 1, 1, 1, 1, m.factor, &m.common))
    cholmod_failed(m.common, "CHOLMOD: cannot drop the factor's values");
  return true;
}

void SparseCholesky::drop_double() {
  Impl& m = *impl_;
  if (!m.factor || !m.xs) throw std::logic_error("drop_double: no single-precision copy");
  if (m.shared || !has_double()) return;  // the holders of a shared factor keep its values
  if (!cholmod_change_factor(CHOLMOD_PATTERN, 1, 1, 1, 1, m.factor, &m.common))
    cholmod_failed(m.common, "CHOLMOD: cannot drop the factor's values");
}

long SparseCholesky::held_bytes() const {
  const cholmod_factor* L = impl_->factor;
  if (!L) return 0;
  long bytes = factor_bytes();  // counts the values as built
  if (L->is_super && !has_double()) bytes -= static_cast<long>(L->xsize) * 8;
  return bytes + single_bytes();
}

bool SparseCholesky::refines() const { return impl_->refine; }

long SparseCholesky::refinement_bytes() const {
  const Impl& m = *impl_;
  if (!m.refine) return 0;
  return static_cast<long>(m.a.nonZeros()) * static_cast<long>(sizeof(double) + sizeof(int)) +
         static_cast<long>(m.n + 1) * static_cast<long>(sizeof(int)) +
         static_cast<long>(m.rb.size() + m.rr.size()) * static_cast<long>(sizeof(double));
}

SparseCholesky::RefinementStats SparseCholesky::refinement_stats() const {
  return {impl_->refined_solves, impl_->refinement_steps, impl_->refactored};
}

// Mixed-precision iterative refinement (as LAPACK's dsposv): z = (L_s L_s^T)^{-1} b, then
// z += (L_s L_s^T)^{-1} (b - A z) while the updates shrink (each at most half the last) and
// the residual is above ||z||_inf ||A||_inf eps, i.e. to the accuracy of the double solve
// itself; a residual that stops shrinking is accepted at dsposv's level of a backward-stable
// solve, ||b - A z||_inf <= ||z||_inf ||A||_inf eps sqrt(n). Each step: one product with A's
// upper triangle (both halves from it) and one single-precision solve; steps contract the
// error by about cond(A) times single precision. Where they do not reach dsposv's level (a
// matrix too ill-conditioned for the rounded factor, or 30 steps), A is factored again in
// double and solved with that from then on.
void SparseCholesky::solve_refined(const double* b, double* out) {
  Impl& m = *impl_;
  if (m.a.rows() != m.n) throw std::logic_error("SparseCholesky: solve without a factor");
  const int n = m.n;
  double* rb = m.rb.data();
  double* r = m.rr.data();
  std::memcpy(rb, b, sizeof(double) * n);  // (b and out may alias)
  solve_single(rb, out);
  const double tight = m.anorm * std::numeric_limits<double>::epsilon();
  const double loose = tight * std::sqrt(static_cast<double>(n));
  const int* outer = m.a.outerIndexPtr();
  const int* inner = m.a.innerIndexPtr();
  const double* value = m.a.valuePtr();
  constexpr int kMaxSteps = 30;
  double last_update = std::numeric_limits<double>::infinity();
  bool stalled = false;
  ++m.refined_solves;
  for (int step = 0;; ++step) {
    std::memcpy(r, rb, sizeof(double) * n);  // r = b - A z
    for (int col = 0; col < n; ++col) {
      const double zc = out[col];
      double acc = 0.0;
      for (int p = outer[col]; p < outer[col + 1]; ++p) {
        const int row = inner[p];
        r[row] -= value[p] * zc;
        if (row != col) acc += value[p] * out[row];
      }
      r[col] -= acc;
    }
    double rnorm = 0.0, znorm = 0.0;
    for (int k = 0; k < n; ++k)
      rnorm = std::max(rnorm, std::abs(r[k])), znorm = std::max(znorm, std::abs(out[k]));
    if (rnorm <= znorm * tight) return;
    if (stalled || step == kMaxSteps || !std::isfinite(rnorm)) {
      if (rnorm <= znorm * loose) return;  // (false for NaN)
      break;
    }
    solve_single(r, r);
    double update = 0.0;
    for (int k = 0; k < n; ++k) out[k] += r[k], update = std::max(update, std::abs(r[k]));
    ++m.refinement_steps;
    stalled = step > 0 && !(update < 0.5 * last_update);
    last_update = update;
  }
  // The single-precision copy is too coarse for this matrix: its double factor again (a shared
  // one is still there; either is the factor its analysis and values give, bit for bit). The
  // kept triangle is not needed after that.
  if (!has_double()) {
    cholmod_sparse view = upper_view(m.a);
    factor_numeric(view, m.factor, m.common);
  }
  m.refactored = true;
  m.refine = false;
  Eigen::SparseMatrix<double>().swap(m.a);
  std::vector<double>().swap(m.rr);
  solve(rb, out);
  std::vector<double>().swap(m.rb);
}

const void* SparseCholesky::single_data() const { return impl_->xs.get(); }

long SparseCholesky::single_bytes() const {
  return impl_->xs ? static_cast<long>(impl_->xs->size() * sizeof(float)) : 0;
}

// Kernels of solve_single(): single-precision values, double sums. On x86-64 cloned for AVX2
// (chosen at run time), since the build targets the baseline instruction set.
#if defined(__x86_64__) && defined(__GNUC__)
#define HTFETI_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define HTFETI_CLONES
#endif
namespace {
HTFETI_CLONES void axpy_single(int m, const float* c, double v, double* t) {
#pragma omp simd
  for (int i = 0; i < m; ++i) t[i] += static_cast<double>(c[i]) * v;
}
HTFETI_CLONES double dot_single(int m, const float* c, const double* t) {
  double acc = 0.0;
#pragma omp simd reduction(+ : acc)
  for (int i = 0; i < m; ++i) acc += static_cast<double>(c[i]) * t[i];
  return acc;
}
}  // namespace

void SparseCholesky::solve_single(const double* b, double* x) {
  const cholmod_factor* L = impl_->factor;
  const int n = impl_->n, ns = static_cast<int>(L->nsuper);
  const int* perm = static_cast<const int*>(L->Perm);
  const int* super = static_cast<const int*>(L->super);
  const int* pi = static_cast<const int*>(L->pi);
  const int* px = static_cast<const int*>(L->px);
  const int* Ls = static_cast<const int*>(L->s);
  const float* Lx = impl_->xs->data();
  double* y = impl_->sy.data();
  double* t = impl_->st.data();
  for (int k = 0; k < n; ++k) y[k] = b[perm[k]];
  for (int s = 0; s < ns; ++s) {  // L y = P b
    const int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
    const int below = nsrow - nscol;
    const float* A = Lx + px[s];
    double* yc = y + k1;
    for (int i = 0; i < below; ++i) t[i] = 0.0;
    for (int j = 0; j < nscol; ++j) {
      const float* col = A + static_cast<long>(j) * nsrow;
      const double v = yc[j] / static_cast<double>(col[j]);
      yc[j] = v;
      axpy_single(nscol - j - 1, col + j + 1, -v, yc + j + 1);
      axpy_single(below, col + nscol, v, t);
    }
    const int* r = Ls + pi[s] + nscol;
    for (int i = 0; i < below; ++i) y[r[i]] -= t[i];
  }
  for (int s = ns - 1; s >= 0; --s) {  // L^T x = y
    const int k1 = super[s], nscol = super[s + 1] - k1, nsrow = pi[s + 1] - pi[s];
    const int below = nsrow - nscol;
    const float* A = Lx + px[s];
    double* yc = y + k1;
    const int* r = Ls + pi[s] + nscol;
    for (int i = 0; i < below; ++i) t[i] = y[r[i]];
    for (int j = nscol - 1; j >= 0; --j) {
      const float* col = A + static_cast<long>(j) * nsrow;
      const double acc = yc[j] - dot_single(below, col + nscol, t) -
                         dot_single(nscol - j - 1, col + j + 1, yc + j + 1);
      yc[j] = acc / static_cast<double>(col[j]);
    }
  }
  for (int k = 0; k < n; ++k) x[perm[k]] = y[k];
}

void SparseCholesky::schur_factor(Eigen::MatrixXd& Ls, std::vector<int>& order) const {
  const cholmod_factor* L = impl_->factor;
  const int n = impl_->n, nb = impl_->nlast, p0 = n - nb;
  if (!L || nb == 0 || !has_double())
    throw std::logic_error("schur_factor: factorize(A, last) was not called");
  const int* perm = static_cast<const int*>(L->Perm);
  order.resize(nb);
  for (int i = 0; i < nb; ++i) order[i] = perm[p0 + i];
  Ls = Eigen::MatrixXd::Zero(nb, nb);
  if (!L->is_super) {  // simplicial LL^T: columns p0..n-1 hold only rows >= p0
    const int* Lp = static_cast<const int*>(L->p);
    const int* Li = static_cast<const int*>(L->i);
    const int* Lnz = static_cast<const int*>(L->nz);
    const double* Lx = static_cast<const double*>(L->x);
    for (int j = p0; j < n; ++j)
      for (int q = Lp[j]; q < Lp[j] + Lnz[j]; ++q) Ls(Li[q] - p0, j - p0) = Lx[q];
    return;
  }
  const int* super = static_cast<const int*>(L->super);
  const int* pi = static_cast<const int*>(L->pi);
  const int* px = static_cast<const int*>(L->px);
  const int* Ls_rows = static_cast<const int*>(L->s);
  const double* Lx = static_cast<const double*>(L->x);
  for (size_t s = 0; s < L->nsuper; ++s) {
    const int k1 = super[s], k2 = super[s + 1];
    if (k2 <= p0) continue;
    const int nsrow = pi[s + 1] - pi[s];
    for (int j = std::max(k1, p0); j < k2; ++j)
      for (int i = j - k1; i < nsrow; ++i) {
        const int row = Ls_rows[pi[s] + i];
        Ls(row - p0, j - p0) = Lx[px[s] + static_cast<long>(j - k1) * nsrow + i];
      }
  }
}

std::shared_ptr<const SparseCholesky::SchurInverse> SparseCholesky::schur_inverse() const {
  auto compute = [this]() {
    const BlasOnOneThread one;
    auto r = std::make_shared<SchurInverse>();
    schur_factor(r->S, r->order);  // L_s, then S^{-1} in place
    const int nb = static_cast<int>(r->S.rows());
    if (nb > 0) {
      int info = 0;
      dpotri_("L", &nb, r->S.data(), &nb, &info);
      if (info != 0) throw std::runtime_error("the Schur complement is singular");
      r->S.triangularView<Eigen::StrictlyUpper>() = r->S.transpose();
    }
    return std::shared_ptr<const SchurInverse>(std::move(r));
  };
  if (!impl_->slot) return compute();
  std::lock_guard<std::mutex> lock(impl_->slot->mutex);
  if (!impl_->slot->value) impl_->slot->value = compute();
  return impl_->slot->value;
}

double SparseCholesky::rcond() const {
  if (!impl_->factor || !has_double()) return 0;
  return cholmod_rcond(impl_->factor, &impl_->common);
}

long SparseCholesky::factor_nonzeros() const {
  const cholmod_factor* L = impl_->factor;
  if (!L) return 0;
  if (L->is_super) return static_cast<long>(L->xsize);
  return static_cast<long>(L->nzmax);
}

}  // namespace htfeti

namespace htfeti {

long SparseCholesky::symbolic_factor_bytes(const Eigen::SparseMatrix<double>& A,
                                           Ordering ordering) {
  return static_cast<long>(symbolic_stats(A, ordering).bytes);
}

SparseCholesky::SymbolicStats SparseCholesky::symbolic_stats(const Eigen::SparseMatrix<double>& A,
                                                             Ordering ordering) {
  SparseCholesky chol(ordering);
  auto& c = chol.impl_->common;
  const Eigen::SparseMatrix<double> upper = upper_triangle(A);
  cholmod_sparse view = upper_view(upper);
  chol.impl_->factor = cholmod_analyze(&view, &c);
  if (!chol.impl_->factor) cholmod_failed(c, "CHOLMOD analysis failed");
  const cholmod_factor* L = chol.impl_->factor;
  SymbolicStats st;
  st.values = static_cast<double>(L->is_super ? L->xsize : L->nzmax);
  st.supernodes = static_cast<double>(L->is_super ? L->nsuper : L->n);
  st.flops = c.fl;
  st.bytes = static_cast<double>(chol.factor_bytes());
  return st;
}

bool SparseCholesky::factor_shared() const { return impl_->shared != nullptr; }

long SparseCholesky::factor_bytes() const {
  const cholmod_factor* L = impl_->factor;
  if (!L) return 0;
  const long n = static_cast<long>(L->n), idx = sizeof(int);
  long bytes = 3 * n * idx;  // Perm, ColCount, IPerm
  if (L->is_super)
    bytes += static_cast<long>(L->xsize) * 8 + static_cast<long>(L->ssize) * idx +
             3 * static_cast<long>(L->nsuper + 1) * idx;
  else
    bytes += static_cast<long>(L->nzmax) * (8 + idx) + 4 * (n + 2) * idx;
  return bytes;
}

}  // namespace htfeti

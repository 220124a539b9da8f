// Allocation counting for the zero-allocation tests (issue 9 item 3, issue 10). Include in
// exactly ONE translation unit of a test executable: it replaces the global operator
// new/delete AND interposes the C allocator (malloc, calloc, realloc, posix_memalign,
// aligned_alloc, memalign) with counting versions that forward to glibc, so allocations made
// inside C and C++ libraries (LCM, glib, OpenCV's fastMalloc, Eigen, Ceres) are counted too,
// on every thread of the process.
//
// Diagnostics: while `g_alloc_trace` is true, every counted allocation prints its call stack
// to stderr (backtrace_symbols_fd, which does not allocate), to find what allocates.
#pragma once

#include <execinfo.h>
#include <malloc.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RDSLAM_ALLOC_COUNTING 0  // sanitizers own the allocator; counting is meaningless there
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define RDSLAM_ALLOC_COUNTING 0
#else
#define RDSLAM_ALLOC_COUNTING 1
#endif
#else
#define RDSLAM_ALLOC_COUNTING 1
#endif

namespace {
std::atomic<uint64_t> g_new_calls{0};     // operator new / new[]
std::atomic<uint64_t> g_malloc_calls{0};  // every C-level allocation (includes new's malloc)
std::atomic<bool> g_alloc_trace{false};
thread_local bool t_in_trace = false;

inline void count_malloc() {
  g_malloc_calls.fetch_add(1, std::memory_order_relaxed);
  if (g_alloc_trace.load(std::memory_order_relaxed) && !t_in_trace) {
    t_in_trace = true;
    void* frames[24];
    const int n = backtrace(frames, 24);
    static const char kSep[] = "---- allocation:\n";
    if (write(2, kSep, sizeof(kSep) - 1) < 0) {
    }
    backtrace_symbols_fd(frames, n, 2);
    t_in_trace = false;
  }
}
}  // namespace

#if RDSLAM_ALLOC_COUNTING
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);

void* malloc(size_t n) {
  count_malloc();
  return __libc_malloc(n);
}
void* calloc(size_t a, size_t b) {
  count_malloc();
  return __libc_calloc(a, b);
}
void* realloc(void* p, size_t n) {
  count_malloc();
  return __libc_realloc(p, n);
}
void free(void* p) {
  __libc_free(p);
}
void* memalign(size_t align, size_t n) {
  count_malloc();
  return __libc_memalign(align, n);
}
void* aligned_alloc(size_t align, size_t n) {
  count_malloc();
  return __libc_memalign(align, n);
}
int posix_memalign(void** out, size_t align, size_t n) {
  count_malloc();
  void* p = __libc_memalign(align, n);
  if (!p) return ENOMEM;
  *out = p;
  return 0;
}
}  // extern "C"

void* operator new(size_t n) {
  g_new_calls.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n) {
  g_new_calls.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(size_t n, std::align_val_t a) {
  g_new_calls.fetch_add(1, std::memory_order_relaxed);
  void* p = nullptr;
  if (posix_memalign(&p, static_cast<size_t>(a), n ? n : 1) == 0) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n, std::align_val_t a) {
  return operator new(n, a);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, size_t, std::align_val_t) noexcept {
  std::free(p);
}
#endif

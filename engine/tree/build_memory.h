// Memory of the MKtree build (BuildMKTree, mktree_builder.h): the allocator of its large arrays, the
// per-node scratch arrays, and giving freed heap memory back between phases. Internal to engine/tree.
//
// The build's peak RSS is reported per object (bench/tree_build_bench) and is part of its contract (about
// 60 bytes per object, BuildTuning::ram_node_objects), so the arrays are sized and freed on purpose: nothing
// is zero-filled that is written before it is read, large arrays are mapped on their own so that freeing one
// returns it to the system at once, and scratch arrays keep their pages mapped as they shrink (see
// bench/README.md, tree_build_bench, for what these choices measured).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace mktree::build {

// How far ahead record reads in key order are prefetched, in objects, in nodes of at least
// kPrefetchObjects objects (the records of smaller nodes are in cache).
inline constexpr uint32_t kPrefetch = 48;
inline constexpr uint32_t kPrefetchObjects = 8192;

// The allocator of the build's large arrays.
// - No zero-fill: resize() constructs nothing (every element is written before it is read), so the page
//   faults happen in the loops that fill the arrays (on two threads for the layout), not in a serial
//   memset. Not even Box3f's member initializers run.
// - Arrays of kMapBytes or more are mapped on their own, so freeing one gives its memory back at once (not
//   to a heap whose holes the next allocations may not fit).
template <typename T>
struct BuildAllocator {
  using value_type = T;
  static constexpr size_t kMapBytes = size_t{1} << 20;  // smaller arrays come from malloc
  BuildAllocator() = default;
  template <typename U>
  BuildAllocator(const BuildAllocator<U>&) noexcept {}
  T* allocate(size_t n) {
#ifdef __linux__
    if (n * sizeof(T) >= kMapBytes) {
      void* p = mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      return static_cast<T*>(p);
    }
#endif
    void* p = std::malloc(std::max<size_t>(n * sizeof(T), 1));
    if (p == nullptr) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
#ifdef __linux__
    if (n * sizeof(T) >= kMapBytes) {
      munmap(p, n * sizeof(T));
      return;
    }
#endif
    std::free(p);
  }
  template <typename U>
  void construct(U*) noexcept {
    // Implicit-lifetime element types only (as for Scratch): the storage's objects exist once written.
    static_assert(std::is_trivially_copyable_v<U> && std::is_trivially_destructible_v<U>);
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <typename U>
  bool operator==(const BuildAllocator<U>&) const noexcept {
    return true;
  }
};
template <typename T>
using BuildVector = std::vector<T, BuildAllocator<T>>;

// A per-node scratch array: it grows without zero-filling (every node writes what it reads), keeps its
// size from node to node, and is shrunk explicitly. From kMapBytes on it is mapped on its own and resized
// in place (mremap): the pages it keeps stay mapped, so shrinking it as the nodes get smaller faults
// nothing in again (with free-and-allocate, the next larger node would fault them in again).
template <typename T>
class Scratch {
  // Implicit-lifetime element types only: the storage's objects exist once written.
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  Scratch() = default;
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  ~Scratch() { Free(); }

  void Fit(size_t n) {
    if (n > capacity_) Reset(n);
  }
  // Capacity n (at least), contents not kept.
  void Reset(size_t n) {
    const size_t bytes = std::max<size_t>(n * sizeof(T), 1);
#ifdef __linux__
    if (mapped_ > 0 || bytes >= BuildAllocator<T>::kMapBytes) {  // once mapped, resized in place
      const size_t want = (bytes + kPage - 1) / kPage * kPage;
      void* p = mapped_ > 0 ? mremap(data_, mapped_, want, MREMAP_MAYMOVE)
                            : mmap(nullptr, want, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      if (mapped_ == 0) Free();
      data_ = static_cast<T*>(p);
      mapped_ = want;
      capacity_ = want / sizeof(T);
      return;
    }
#endif
    Free();
    data_ = static_cast<T*>(std::malloc(bytes));
    if (data_ == nullptr) throw std::bad_alloc();
    capacity_ = n;
  }
  size_t capacity() const { return capacity_; }
  // Room for n values of U (as large as T) in this array's storage, for a phase in which its own values
  // are dead: two scratch arrays live at different times share their pages.
  template <typename U>
  U* StorageAs(size_t n) {
    static_assert(sizeof(U) == sizeof(T) && alignof(U) <= alignof(T));
    static_assert(std::is_trivially_copyable_v<U> && std::is_trivially_destructible_v<U>);
    Fit(n);
    return reinterpret_cast<U*>(data_);
  }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T& operator[](size_t i) { return data_[i]; }
  const T& operator[](size_t i) const { return data_[i]; }

 private:
  static constexpr size_t kPage =
      4096;  // mremap sizes are whole pages (rounding up only wastes address space)

  void Free() {
#ifdef __linux__
    if (mapped_ > 0) {
      munmap(data_, mapped_);
      data_ = nullptr;
      mapped_ = 0;
      capacity_ = 0;
      return;
    }
#endif
    std::free(data_);
    data_ = nullptr;
    capacity_ = 0;
  }

  T* data_ = nullptr;
  size_t capacity_ = 0;
  size_t mapped_ = 0;  // bytes mapped, 0 when data_ is from malloc
};

// Frees of at least this many bytes are followed by TrimHeap (trimming is a walk of the heap).
inline constexpr size_t kTrimBytes = size_t{8} << 20;

// Gives the heap's free pages back to the system: the builder frees large temporaries between phases,
// and glibc keeps freed heap memory (not only its top) resident otherwise.
void TrimHeap();

}  // namespace mktree::build

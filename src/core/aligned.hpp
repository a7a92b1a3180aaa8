#pragma once
// An allocator for std::vector whose storage starts on an A-byte boundary (A a power of two, at
// least alignof(T)): arrays of 64-byte records then put each record in one cache line.
#include <cstddef>
#include <new>
#include <vector>

namespace ks {

template <class T, std::size_t A>
struct AlignedAllocator {
  static_assert(A >= alignof(T) && (A & (A - 1)) == 0, "a power of two, at least alignof(T)");
  using value_type = T;
  template <class U>
  struct rebind {
    using other = AlignedAllocator<U, A>;
  };
  AlignedAllocator() noexcept = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U, A>&) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(A)));
  }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t(A)); }
  template <class U>
  bool operator==(const AlignedAllocator<U, A>&) const noexcept {
    return true;
  }
};

// A vector whose data() is a multiple of 64 bytes (one cache line).
template <class T>
using LineAlignedVector = std::vector<T, AlignedAllocator<T, 64>>;

}  // namespace ks

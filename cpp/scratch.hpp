// Scratch arrays that renders reuse (projected vertices, world normals; setup records), sized or
// grown without being initialised or copied.
//
// A renderer's first frame allocates these and later frames reuse them. std::vector::resize
// value-initialises: it zeroes every element on the calling thread, page faults included, only
// for the parallel passes to overwrite it. Here the pass that writes an element is the first to
// touch it.
//
// Plain operator new, not a fresh mapping with huge pages: that was tried and made the first
// frame slower, since the heap holds memory freed by earlier work that malloc reuses without any
// page fault at all (both: benchmarks/RESULTS.md, "Measurements behind the code").
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>
#include <type_traits>
#include <utility>

namespace sr {

// A run of T's whose contents are undefined after resize() (every element must be written
// before it is read). Keeps its capacity, as a std::vector does, so that renders of the same
// scene reuse it.
template <typename T>
class ScratchArray {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>,
                "scratch elements are raw memory");

 public:
  ScratchArray() = default;
  ScratchArray(ScratchArray&& other) noexcept { swap(other); }
  ScratchArray& operator=(ScratchArray&& other) noexcept {
    swap(other);
    return *this;
  }
  ScratchArray(const ScratchArray&) = delete;
  ScratchArray& operator=(const ScratchArray&) = delete;
  ~ScratchArray() { release(); }

  void resize(std::size_t n) {
    if (n > capacity_) {
      release();  // the old contents need not survive
      data_ = static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(alignof(T))));
      capacity_ = n;
    }
    size_ = n;
  }
  std::size_t size() const { return size_; }
  T* data() { return data_; }
  const T* data() const { return data_; }

 private:
  void release() {
    if (data_) ::operator delete(data_, std::align_val_t(alignof(T)));
    data_ = nullptr;
    size_ = capacity_ = 0;
  }
  void swap(ScratchArray& other) noexcept {
    std::swap(data_, other.data_);
    std::swap(size_, other.size_);
    std::swap(capacity_, other.capacity_);
  }

  T* data_ = nullptr;
  std::size_t size_ = 0, capacity_ = 0;
};

// An append-only run of T's grown by realloc(), which extends a block in place when it can and
// moves a large one by remapping its pages (glibc): std::vector's growth copied every setup
// record once more in a first frame (benchmarks/RESULTS.md, "Measurements behind the code").
// Keeps its capacity across clear(), as a std::vector does. Elements start on a cache line (a
// 64-byte setup record then spans one line, not two).
template <typename T>
class GrowingArray {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T> &&
                    alignof(T) <= alignof(std::max_align_t),
                "grown with realloc");

 public:
  GrowingArray() = default;
  GrowingArray(GrowingArray&& other) noexcept { swap(other); }
  GrowingArray& operator=(GrowingArray&& other) noexcept {
    swap(other);
    return *this;
  }
  GrowingArray(const GrowingArray&) = delete;
  GrowingArray& operator=(const GrowingArray&) = delete;
  ~GrowingArray() { std::free(raw_); }

  void push_back(const T& value) {  // `value` must not be an element of this array
    if (size_ == capacity_) reserve(capacity_ ? 2 * capacity_ : 64);
    data_[size_++] = value;
  }
  // Appends an element left uninitialised, to be written in place (a record built elsewhere
  // with narrow stores and copied in with wide loads stalls store-to-load forwarding).
  T& emplace_back() {
    if (size_ == capacity_) reserve(capacity_ ? 2 * capacity_ : 64);
    return data_[size_++];
  }
  void reserve(std::size_t n) {
    if (n <= capacity_) return;
    // realloc keeps 16-byte alignment only: the elements start at the first cache-line boundary
    // of the block, moved in it if the block's own offset from one changed.
    const std::size_t old_offset = std::size_t(reinterpret_cast<char*>(data_) - raw_);
    char* p = static_cast<char*>(std::realloc(raw_, n * sizeof(T) + kAlign));
    if (!p) throw std::bad_alloc();
    const std::size_t offset = (kAlign - (reinterpret_cast<uintptr_t>(p) & (kAlign - 1))) & (kAlign - 1);
    if (offset != old_offset && size_ != 0) std::memmove(p + offset, p + old_offset, size_ * sizeof(T));
    raw_ = p;
    data_ = reinterpret_cast<T*>(p + offset);
    capacity_ = n;
  }
  void clear() { size_ = 0; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  T* data() { return data_; }
  const T* data() const { return data_; }
  const T& operator[](std::size_t i) const { return data_[i]; }

 private:
  void swap(GrowingArray& other) noexcept {
    std::swap(data_, other.data_);
    std::swap(raw_, other.raw_);
    std::swap(size_, other.size_);
    std::swap(capacity_, other.capacity_);
  }

  static constexpr std::size_t kAlign = 64;
  T* data_ = nullptr;  // the first element, cache-line aligned
  char* raw_ = nullptr;  // the block
  std::size_t size_ = 0, capacity_ = 0;
};

}  // namespace sr

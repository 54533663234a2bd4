// The body of a binary_compressed PCD file, PCL's layout, compressed with PCL's lzfCompress on a
// few threads (see pcd_compressed.cpp). Plain C++: no Python object is touched here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace example_pcl {

// Bytes whose resize() leaves them uninitialised (every byte is written before it is read): a
// Kinect frame's buffers would otherwise be zeroed, 10 MB a frame, only to be overwritten.
template <typename T>
struct UninitializedAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
using Bytes = std::vector<std::uint8_t, UninitializedAllocator<std::uint8_t>>;

// One field as the compressed body stores it: its bytes within a point, and how many.
struct FieldBytes {
  size_t offset, size;
};

// The most threads compress_body runs at once, whatever the chunk count or the core count.
constexpr size_t kMaxCompressThreads = 8;

// The points (point_step bytes each, fields at their offsets) rearranged field-major, as PCL's
// compressed body stores them: every point's first field, then every point's second field, ...
Bytes to_field_major(const std::uint8_t* data, size_t points, size_t point_step, const std::vector<FieldBytes>& fields);

// The compressed body (uint32 compressed size, uint32 uncompressed size, then the LZF stream) of
// `body`, cut into `chunks` pieces (0: one per core, none under 256 KiB) compressed on
// min(cores, chunks, kMaxCompressThreads) threads, the calling thread being one of them; when no
// thread can be started the calling thread compresses every chunk. Returns the pieces to write in
// order; on failure returns nothing and sets `error` to why.
std::vector<Bytes> compress_body(const Bytes& body, size_t chunks, std::string& error);

}  // namespace example_pcl

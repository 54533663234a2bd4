// binary_compressed PCD bodies. PCL's layout (PCDWriter::writeBinaryCompressed and
// PCDReader::readBodyBinary, PCL 1.13): the header of generateHeaderBinaryCompressed,
// "DATA binary_compressed\n", uint32 compressed size, uint32 uncompressed size, then the
// LZF-compressed points stored field-major: every point's first field, then every point's second
// field, ... (fields named "_" are padding and left out). PCL's own writer spends most of its
// ~100 ms per Kinect frame putting the compressed bytes into its ostream one put() at a time and
// copying each field with a library memcpy; here the fields are gathered in cache-sized blocks of
// points and the bytes written straight to the file (io.cpp writes them).
//
// The compression is split into chunks: LZF's tokens are literal runs and back-references into
// output already produced, and a compressor given one chunk refers only to that chunk, so chunks
// compressed independently and concatenated form one valid LZF stream of the whole (PCL's
// lzfDecompress keeps no state between tokens; it only checks a reference does not reach before
// the start of its output). Only the compression ratio can change, and only at chunk seams.
#include "pcd_compressed.hpp"

#include <pcl/io/lzf.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <limits>
#include <system_error>
#include <thread>

namespace example_pcl {
namespace {

// Copies `size` bytes known at compile time, so the compiler emits plain moves.
template <size_t Size>
void gather_field(const std::uint8_t* src, size_t step, size_t begin, size_t end, std::uint8_t* dst) {
  for (size_t i = begin; i < end; ++i) std::memcpy(dst + i * Size, src + i * step, Size);
}

void gather_field(const std::uint8_t* src, size_t step, size_t size, size_t begin, size_t end, std::uint8_t* dst) {
  switch (size) {
    case 1: return gather_field<1>(src, step, begin, end, dst);
    case 2: return gather_field<2>(src, step, begin, end, dst);
    case 4: return gather_field<4>(src, step, begin, end, dst);
    case 8: return gather_field<8>(src, step, begin, end, dst);
    case 12: return gather_field<12>(src, step, begin, end, dst);
    case 16: return gather_field<16>(src, step, begin, end, dst);
    default:
      for (size_t i = begin; i < end; ++i) std::memcpy(dst + i * size, src + i * step, size);
  }
}

// The most lzfCompress can produce from n bytes: one control byte per 32 literals when nothing
// repeats (liblzf's LZF_MAX_COMPRESSED_SIZE is n * 33 / 32 + 1), plus slack for tiny inputs.
size_t lzf_bound(size_t n) { return n + n / 32 + 16; }

}  // namespace

Bytes to_field_major(const std::uint8_t* data, size_t points, size_t point_step, const std::vector<FieldBytes>& fields) {
  size_t point_bytes = 0;
  for (const auto& f : fields) point_bytes += f.size;
  Bytes out(points * point_bytes);
  std::vector<std::uint8_t*> planes;
  size_t plane_offset = 0;
  for (const auto& f : fields) {
    planes.push_back(out.data() + plane_offset);
    plane_offset += f.size * points;
  }
  // Blocks of points small enough to stay in cache are read once for all their fields.
  constexpr size_t kBlock = 2048;  // points: 64 KB of 32-byte points
  for (size_t begin = 0; begin < points; begin += kBlock) {
    const size_t end = std::min(points, begin + kBlock);
    for (size_t j = 0; j < fields.size(); ++j)
      gather_field(data + fields[j].offset, point_step, fields[j].size, begin, end, planes[j]);
  }
  return out;
}

std::vector<Bytes> compress_body(const Bytes& body, size_t chunks, std::string& error) {
  const size_t n = body.size();
  const size_t cores = std::max<size_t>(1, std::thread::hardware_concurrency());
  if (chunks == 0) {
    constexpr size_t kMinChunk = 256 * 1024;
    chunks = std::max<size_t>(1, std::min(cores, n / kMinChunk));
  }
  chunks = std::max<size_t>(1, std::min(chunks, std::max<size_t>(n, 1)));
  std::vector<Bytes> out(chunks + 1);
  std::vector<size_t> begin(chunks + 1);
  for (size_t k = 0; k <= chunks; ++k) begin[k] = n * k / chunks;  // sizes differ by at most one byte
  for (size_t k = 0; k < chunks; ++k) out[k + 1].resize(lzf_bound(begin[k + 1] - begin[k]));
  std::vector<unsigned int> produced(chunks, 0);
  // Every worker (the calling thread included) takes the next chunk nobody has taken yet.
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t k = next++; k < chunks; k = next++) {
      const size_t size = begin[k + 1] - begin[k];
      if (size > 0)
        produced[k] = pcl::lzfCompress(body.data() + begin[k], static_cast<unsigned int>(size), out[k + 1].data(),
                                       static_cast<unsigned int>(out[k + 1].size()));
    }
  };
  {
    const size_t helpers = std::min({cores, chunks, kMaxCompressThreads}) - 1;
    std::vector<std::thread> threads;
    threads.reserve(helpers);
    try {
      for (size_t t = 0; t < helpers; ++t) threads.emplace_back(work);
    } catch (const std::system_error&) {
      // No more threads to be had: the ones started and this one share the chunks.
    }
    work();
    for (auto& t : threads) t.join();
  }
  std::uint64_t total = 0;
  for (size_t k = 0; k < chunks; ++k) {
    if (produced[k] == 0 && begin[k + 1] > begin[k]) {
      error = "LZF compression failed";
      return {};
    }
    out[k + 1].resize(produced[k]);
    total += produced[k];
  }
  if (total > std::numeric_limits<std::uint32_t>::max()) {
    error = "the compressed data (" + std::to_string(total) + " bytes) does not fit binary_compressed's 32-bit size";
    return {};
  }
  const std::uint32_t sizes[2] = {static_cast<std::uint32_t>(total), static_cast<std::uint32_t>(n)};
  out[0].resize(sizeof(sizes));
  std::memcpy(out[0].data(), sizes, sizeof(sizes));
  return out;
}

}  // namespace example_pcl

// Data-parallel loops of cpp/esdf on the shared cufund::ThreadPool.
#pragma once

#include <algorithm>
#include <cstddef>

#include "thread_pool.h"

namespace cufund::esdf {

// Calls body(begin, end, chunk_index) for consecutive chunks of at most `chunk` items covering
// [0, n), on up to `threads` threads (the caller included; chunks are claimed one at a time, so a
// busy machine only slows the loop down). Results must not depend on which thread ran a chunk.
template <typename Body>
void parallel_chunks(std::ptrdiff_t n, std::ptrdiff_t chunk, int threads, Body&& body) {
  if (n <= 0) return;
  chunk = std::max<std::ptrdiff_t>(1, chunk);
  const std::ptrdiff_t chunks = (n + chunk - 1) / chunk;
  ThreadPool::instance().parallel_for(static_cast<std::size_t>(chunks), threads, [&](std::size_t c) {
    const auto begin = static_cast<std::ptrdiff_t>(c) * chunk;
    body(begin, std::min(n, begin + chunk), static_cast<std::ptrdiff_t>(c));
  });
}

// Threads an `nthreads` request resolves to (<= 0 means all hardware threads).
inline int resolve_threads(int nthreads) { return nthreads > 0 ? nthreads : ThreadPool::instance().size(); }

// A chunk size giving each of `threads` threads about 8 chunks, and at least `min_chunk` items.
inline std::ptrdiff_t chunk_size(std::ptrdiff_t n, int threads, std::ptrdiff_t min_chunk) {
  return std::max(min_chunk, n / (8 * std::max(1, threads)) + 1);
}

}  // namespace cufund::esdf

// Data-parallel loops of cpp/esdf on the shared cufund::ThreadPool.
#pragma once

#include <algorithm>
#include <cstddef>

#include "thread_pool.h"

namespace cufund::esdf {

// The shared pool's chunked loop (thread_pool.h).
using cufund::parallel_chunks;

// Threads an `nthreads` request resolves to (<= 0 means all hardware threads).
inline int resolve_threads(int nthreads) { return nthreads > 0 ? nthreads : ThreadPool::instance().size(); }

// A chunk size giving each of `threads` threads about 8 chunks, and at least `min_chunk` items.
inline std::ptrdiff_t chunk_size(std::ptrdiff_t n, int threads, std::ptrdiff_t min_chunk) {
  return std::max(min_chunk, n / (8 * std::max(1, threads)) + 1);
}

}  // namespace cufund::esdf

// A process-wide pool for data-parallel loops that degrades gracefully on a busy machine.
//
// The calling thread works too, and chunks are claimed one at a time from a shared counter, so a
// worker that the OS has not scheduled yet simply claims nothing: the caller never waits for a thread
// that has not started (an OpenMP fork-join barrier does, which costs a whole scheduler time slice
// per call when the cores are shared). Idle workers spin for a few tens of microseconds before they
// sleep, so back-to-back loops (a simulation stepping at 1 kHz) find them awake.
// Results must not depend on which thread ran which chunk.
//
// A parallel_for called from inside a running loop (by the caller or a worker, on any pool) runs its
// body inline on that thread, so nesting never deadlocks. The shared pool's size comes from the
// CUFUND_NUM_THREADS environment variable, else the CPUs this process may run on (sched_getaffinity).
// Fork safety: fork() waits until no parallel loop and no ForkSafeSection is running (pthread_atfork),
// and the child builds a fresh shared pool on first use (the parent's workers do not exist there).
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace cufund {

class ThreadPool {
 public:
  // The shared pool, with default_size() - 1 workers, created on first use (throws
  // std::invalid_argument when CUFUND_NUM_THREADS is set but not an integer in [1, kMaxThreads]).
  static ThreadPool& instance();

  // Threads the shared pool uses, the caller included: CUFUND_NUM_THREADS if set, else the number of
  // CPUs in this process's affinity mask. Reads the environment on every call.
  static int default_size();
  static constexpr int kMaxThreads = 1024;

  // True while the calling thread runs a chunk of a parallel_for (any pool).
  static bool in_parallel_region();

  explicit ThreadPool(int workers);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  // Calls fn(i) once for every i in [0, n) on at most `threads` threads, the caller included
  // (threads <= 0: all). Returns when every call has returned. If a call throws, no new calls start,
  // and the first exception is rethrown here once every running call has returned.
  void parallel_for(std::size_t n, int threads, const std::function<void(std::size_t)>& fn);

  int size() const { return static_cast<int>(workers_.size()) + 1; }

 private:
  void work();
  bool job_waiting(std::uint64_t seen) const;
  // Runs fn(i) for claimed indices until none are left; an exception stops the claiming and is kept.
  void run_claims(const std::function<void(std::size_t)>& fn, std::size_t n);

  std::vector<std::thread> workers_;
  std::mutex submit_;  // one job at a time
  std::mutex m_;       // guards the job description below and the sleeping
  std::condition_variable wake_, done_;
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<bool> open_{false};
  std::atomic<bool> stop_{false};
  std::atomic<int> active_{0};
  const std::function<void(std::size_t)>* fn_ = nullptr;
  std::size_t n_ = 0;
  int max_workers_ = 0, entered_ = 0;
  std::atomic<std::size_t> next_{0};
  std::exception_ptr error_;  // the first exception of the current job (guarded by m_)
};

// Holds off fork() (in any thread) while alive: a fork waits until every section has ended, so a
// child never inherits an object half-way through an update or a lock held by a vanished thread.
// Re-entrant on one thread; a no-op inside a parallel_for chunk (the loop's caller holds one).
// Never wait for the GIL or for another thread's section while holding one.
class ForkSafeSection {
 public:
  ForkSafeSection();
  ~ForkSafeSection();
  ForkSafeSection(const ForkSafeSection&) = delete;
  ForkSafeSection& operator=(const ForkSafeSection&) = delete;

 private:
  bool held_ = false;
};

// Calls body(begin, end, chunk_index) for consecutive chunks of at most `chunk` items covering
// [0, n), on up to `threads` threads of the shared pool (the caller included; chunks are claimed one
// at a time, so a busy machine only slows the loop down). Results must not depend on which thread
// ran a chunk.
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

}  // namespace cufund

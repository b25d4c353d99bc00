#include "thread_pool.h"

#include <algorithm>
#include <chrono>

namespace cufund {
namespace {

// How long an idle thread polls before it blocks: long enough to bridge the gap between the
// parallel loops of consecutive simulation steps, short enough not to matter when idle.
constexpr auto kSpin = std::chrono::microseconds(50);

template <typename Ready>
bool spin_until(Ready&& ready) {
  const auto deadline = std::chrono::steady_clock::now() + kSpin;
  for (int k = 0;; ++k) {
    if (ready()) return true;
    if ((k & 63) == 63 && std::chrono::steady_clock::now() > deadline) return false;
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
}

}  // namespace

ThreadPool& ThreadPool::instance() {
  static ThreadPool pool(std::max(1, static_cast<int>(std::thread::hardware_concurrency())) - 1);
  return pool;
}

ThreadPool::ThreadPool(int workers) {
  for (int i = 0; i < workers; ++i) workers_.emplace_back([this] { work(); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lk(m_);
    stop_.store(true);
  }
  wake_.notify_all();
  for (auto& t : workers_) t.join();
}

void ThreadPool::run_claims(const std::function<void(std::size_t)>& fn, std::size_t n) {
  try {
    for (std::size_t i; (i = next_.fetch_add(1, std::memory_order_relaxed)) < n;) fn(i);
  } catch (...) {
    next_.store(n, std::memory_order_relaxed);  // nobody starts another call
    std::lock_guard<std::mutex> lk(m_);
    if (!error_) error_ = std::current_exception();
  }
}

bool ThreadPool::job_waiting(std::uint64_t seen) const {
  return open_.load(std::memory_order_acquire) && generation_.load(std::memory_order_acquire) != seen;
}

void ThreadPool::parallel_for(std::size_t n, int threads, const std::function<void(std::size_t)>& fn) {
  if (threads <= 0) threads = size();
  if (threads <= 1 || n <= 1 || workers_.empty()) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::lock_guard<std::mutex> one_job(submit_);
  {
    std::lock_guard<std::mutex> lk(m_);
    fn_ = &fn;
    n_ = n;
    max_workers_ = threads - 1;
    entered_ = 0;
    error_ = nullptr;
    next_.store(0, std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
    open_.store(true, std::memory_order_release);
  }
  wake_.notify_all();
  run_claims(fn, n);
  {
    std::lock_guard<std::mutex> lk(m_);
    open_.store(false, std::memory_order_release);  // workers that look from now on do not join this job
  }
  std::unique_lock<std::mutex> lk(m_, std::defer_lock);
  if (!spin_until([this] { return active_.load(std::memory_order_acquire) == 0; })) {
    lk.lock();
    done_.wait(lk, [this] { return active_.load(std::memory_order_acquire) == 0; });
  } else {
    lk.lock();
  }
  if (error_) {
    std::exception_ptr e = error_;
    error_ = nullptr;
    lk.unlock();
    std::rethrow_exception(e);
  }
}

void ThreadPool::work() {
  std::uint64_t seen = 0;
  for (;;) {
    if (!spin_until([&] { return stop_.load(std::memory_order_relaxed) || job_waiting(seen); })) {
      std::unique_lock<std::mutex> lk(m_);
      wake_.wait(lk, [&] { return stop_.load(std::memory_order_relaxed) || job_waiting(seen); });
    }
    std::unique_lock<std::mutex> lk(m_);
    if (stop_.load()) return;
    if (!open_.load(std::memory_order_relaxed)) continue;  // the job closed while we were getting here
    seen = generation_.load(std::memory_order_relaxed);
    if (entered_ >= max_workers_) continue;
    ++entered_;
    active_.fetch_add(1, std::memory_order_relaxed);
    const auto* fn = fn_;
    const std::size_t n = n_;
    lk.unlock();
    run_claims(*fn, n);
    lk.lock();
    if (active_.fetch_sub(1, std::memory_order_acq_rel) == 1) done_.notify_all();
  }
}

}  // namespace cufund

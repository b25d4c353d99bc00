#include "thread_pool.h"

#include <algorithm>

namespace cufund {

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
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : workers_) t.join();
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
    next_.store(0, std::memory_order_relaxed);
    ++generation_;
    open_ = true;
  }
  wake_.notify_all();
  for (std::size_t i; (i = next_.fetch_add(1, std::memory_order_relaxed)) < n;) fn(i);
  std::unique_lock<std::mutex> lk(m_);
  open_ = false;  // workers that wake from now on do not join this job
  done_.wait(lk, [this] { return active_ == 0; });
}

void ThreadPool::work() {
  std::uint64_t seen = 0;
  std::unique_lock<std::mutex> lk(m_);
  for (;;) {
    wake_.wait(lk, [&] { return stop_ || (open_ && generation_ != seen); });
    if (stop_) return;
    seen = generation_;
    if (entered_ >= max_workers_) continue;
    ++entered_;
    ++active_;
    const auto* fn = fn_;
    const std::size_t n = n_;
    lk.unlock();
    for (std::size_t i; (i = next_.fetch_add(1, std::memory_order_relaxed)) < n;) (*fn)(i);
    lk.lock();
    if (--active_ == 0) done_.notify_all();
  }
}

}  // namespace cufund

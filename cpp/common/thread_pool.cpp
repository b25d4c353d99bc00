#include "thread_pool.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace cufund {
namespace {

thread_local int tls_region_depth = 0;      // > 0 while this thread runs a chunk of a parallel_for
thread_local int tls_section_depth = 0;     // ForkSafeSections alive on this thread
thread_local bool tls_fork_locked = false;  // this thread's fork holds the gate (between prepare and parent/child)

// The shared pool (created on first use) and the pools a forked child abandoned: their workers do not
// exist in the child. Kept reachable, never destroyed (a worker may have held their mutexes at fork).
std::atomic<ThreadPool*> g_pool{nullptr};
std::mutex g_create;
ThreadPool* g_abandoned[64] = {};
int g_num_abandoned = 0;

void fork_prepare();
void fork_parent();
void fork_child();

// Readers: ForkSafeSections; the writer: fork()'s prepare handler. Writer-preferring, so a fork is not
// starved by back-to-back loops.
pthread_rwlock_t g_gate;

void init_gate() {
  pthread_rwlockattr_t attr;
  pthread_rwlockattr_init(&attr);
#if defined(__GLIBC__)
  pthread_rwlockattr_setkind_np(&attr, PTHREAD_RWLOCK_PREFER_WRITER_NONRECURSIVE_NP);
#endif
  pthread_rwlock_init(&g_gate, &attr);
  pthread_rwlockattr_destroy(&attr);
}

pthread_rwlock_t& fork_gate() {
  static const bool ready = [] {
    init_gate();
    pthread_atfork(fork_prepare, fork_parent, fork_child);
    return true;
  }();
  (void)ready;
  return g_gate;
}

void fork_prepare() {
  // A fork from inside a section or loop cannot wait for itself; it forks as it is.
  if (tls_section_depth > 0 || tls_region_depth > 0) return;
  pthread_rwlock_wrlock(&fork_gate());
  g_create.lock();
  tls_fork_locked = true;
}

void fork_parent() {
  if (!tls_fork_locked) return;
  tls_fork_locked = false;
  g_create.unlock();
  pthread_rwlock_unlock(&fork_gate());
}

void fork_child() {
  if (tls_fork_locked) {
    tls_fork_locked = false;
    g_create.unlock();
  }
  // Readers that waited in the parent do not exist here: a fresh lock, not an unlock that would hand
  // the lock to them. No thread of this process holds it now (the forking thread held it to write, or
  // forked from inside a section of its own, whose end must then find an unlocked gate: counted below).
  init_gate();
  if (tls_section_depth > 0) pthread_rwlock_rdlock(&g_gate);
  if (ThreadPool* old = g_pool.load()) {
    if (g_num_abandoned < 64) g_abandoned[g_num_abandoned++] = old;
    g_pool.store(nullptr);  // the next instance() starts fresh workers in this process
  }
}

struct RegionScope {
  RegionScope() { ++tls_region_depth; }
  ~RegionScope() { --tls_region_depth; }
};

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

ForkSafeSection::ForkSafeSection() {
  if (tls_region_depth > 0) return;  // the loop's caller holds one for the whole loop
  if (tls_section_depth++ == 0) pthread_rwlock_rdlock(&fork_gate());
  held_ = true;
}

ForkSafeSection::~ForkSafeSection() {
  if (held_ && --tls_section_depth == 0) pthread_rwlock_unlock(&fork_gate());
}

bool ThreadPool::in_parallel_region() { return tls_region_depth > 0; }

int ThreadPool::default_size() {
  if (const char* env = std::getenv("CUFUND_NUM_THREADS"); env != nullptr && *env != '\0') {
    char* end = nullptr;
    errno = 0;
    const long v = std::strtol(env, &end, 10);
    while (end != nullptr && std::isspace(static_cast<unsigned char>(*end))) ++end;
    if (errno != 0 || end == env || *end != '\0' || v < 1 || v > kMaxThreads) {
      throw std::invalid_argument("CUFUND_NUM_THREADS must be an integer in [1, " + std::to_string(kMaxThreads) +
                                  "], got '" + std::string(env) + "'");
    }
    return static_cast<int>(v);
  }
  int n = 0;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) n = CPU_COUNT(&set);
  if (n <= 0) n = static_cast<int>(std::thread::hardware_concurrency());
  return std::clamp(n, 1, kMaxThreads);
}

ThreadPool& ThreadPool::instance() {
  ThreadPool* pool = g_pool.load(std::memory_order_acquire);
  if (pool != nullptr) return *pool;
  fork_gate();  // registers the fork handlers before the first worker exists
  std::lock_guard<std::mutex> lk(g_create);
  pool = g_pool.load(std::memory_order_relaxed);
  if (pool == nullptr) {
    pool = new ThreadPool(default_size() - 1);  // never destroyed: workers may outlive static destructors
    g_pool.store(pool, std::memory_order_release);
  }
  return *pool;
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
  RegionScope region;
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
  if (tls_region_depth > 0) {  // nested inside a loop: this thread's share of the outer loop runs it
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  ForkSafeSection no_fork;
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

#include <gtest/gtest.h>
#include <sched.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <numeric>
#include <string>

#include <atomic>
#include <chrono>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "thread_pool.h"

namespace cufund {
namespace {

TEST(ThreadPool, EveryIndexRunsExactlyOnce) {
  ThreadPool pool(3);
  for (std::size_t n : {0u, 1u, 2u, 7u, 1000u}) {
    for (int threads : {0, 1, 2, 4, 9}) {
      std::vector<std::atomic<int>> hits(n);
      pool.parallel_for(n, threads, [&](std::size_t i) { hits[i].fetch_add(1); });
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << "n " << n << " threads " << threads;
    }
  }
}

TEST(ThreadPool, UsesWorkersWhenAllowedAndOnlyTheCallerWhenNot) {
  ThreadPool pool(2);
  std::mutex m;
  std::set<std::thread::id> ids;
  auto record = [&](std::size_t) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    std::lock_guard<std::mutex> lk(m);
    ids.insert(std::this_thread::get_id());
  };
  pool.parallel_for(64, 1, record);
  EXPECT_EQ(ids.size(), 1u);
  EXPECT_EQ(*ids.begin(), std::this_thread::get_id());
  ids.clear();
  pool.parallel_for(64, 3, record);  // 128 ms of sleeping chunks: the workers join in
  EXPECT_GT(ids.size(), 1u);
  EXPECT_LE(ids.size(), 3u);
}

TEST(ThreadPool, ConcurrentCallersAreSerialisedSafely) {
  ThreadPool pool(2);
  std::atomic<long> total{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < 4; ++c) {
    callers.emplace_back([&] {
      for (int rep = 0; rep < 50; ++rep)
        pool.parallel_for(100, 0, [&](std::size_t i) { total += static_cast<long>(i); });
    });
  }
  for (auto& t : callers) t.join();
  EXPECT_EQ(total.load(), 4L * 50 * (99 * 100 / 2));
}

TEST(ThreadPool, AnExceptionStopsTheLoopAndReachesTheCaller) {
  ThreadPool pool(2);
  for (int rep = 0; rep < 50; ++rep) {
    std::atomic<int> calls{0};
    const std::size_t bad = static_cast<std::size_t>(rep % 7);  // thrown by the caller or by a worker
    EXPECT_THROW(pool.parallel_for(1000, 3,
                                   [&](std::size_t i) {
                                     calls.fetch_add(1);
                                     std::this_thread::sleep_for(std::chrono::microseconds(20));
                                     if (i == bad) throw std::runtime_error("chunk failed");
                                   }),
                 std::runtime_error);
    EXPECT_LT(calls.load(), 1000);  // the loop stopped early
  }
  // The pool is still usable afterwards.
  std::atomic<int> calls{0};
  pool.parallel_for(100, 3, [&](std::size_t) { calls.fetch_add(1); });
  EXPECT_EQ(calls.load(), 100);
}

TEST(ThreadPool, NestedParallelForRunsInlineAndComputesTheRightResult) {
  ThreadPool pool(3);
  constexpr std::size_t kOuter = 16, kInner = 200;
  std::vector<long> sums(kOuter, 0);
  std::atomic<int> nested_inside{0};
  pool.parallel_for(kOuter, 0, [&](std::size_t i) {
    EXPECT_TRUE(ThreadPool::in_parallel_region());
    const auto me = std::this_thread::get_id();
    std::vector<long> part(kInner, 0);
    // The same pool and the shared pool: both would wait on a job that cannot finish if not inline.
    pool.parallel_for(kInner, 0, [&](std::size_t j) {
      if (std::this_thread::get_id() == me) nested_inside.fetch_add(1);
      part[j] = static_cast<long>(i * kInner + j);
    });
    ThreadPool::instance().parallel_for(1, 0, [&](std::size_t) {});
    sums[i] = std::accumulate(part.begin(), part.end(), 0L);
  });
  EXPECT_FALSE(ThreadPool::in_parallel_region());
  long total = std::accumulate(sums.begin(), sums.end(), 0L);
  const long n = static_cast<long>(kOuter * kInner);
  EXPECT_EQ(total, n * (n - 1) / 2);
  EXPECT_EQ(nested_inside.load(), static_cast<int>(kOuter * kInner));  // every inner call on its outer thread
}

TEST(ThreadPool, DefaultSizeIsTheEnvironmentVariableElseTheAffinityMask) {
  const char* saved = std::getenv("CUFUND_NUM_THREADS");
  const std::string keep = saved ? saved : "";
  unsetenv("CUFUND_NUM_THREADS");
  cpu_set_t set;
  ASSERT_EQ(sched_getaffinity(0, sizeof(set), &set), 0);
  EXPECT_EQ(ThreadPool::default_size(), CPU_COUNT(&set));
  setenv("CUFUND_NUM_THREADS", "3", 1);
  EXPECT_EQ(ThreadPool::default_size(), 3);
  setenv("CUFUND_NUM_THREADS", " 7 ", 1);
  EXPECT_EQ(ThreadPool::default_size(), 7);
  for (const char* bad : {"0", "-2", "two", "4x", "99999"}) {
    setenv("CUFUND_NUM_THREADS", bad, 1);
    EXPECT_THROW(ThreadPool::default_size(), std::invalid_argument) << bad;
  }
  if (saved)
    setenv("CUFUND_NUM_THREADS", keep.c_str(), 1);
  else
    unsetenv("CUFUND_NUM_THREADS");
}

TEST(ThreadPool, AffinityMaskOfOneCpuGivesAPoolOfOne) {
  // In a child process (the shared pool is per process): pin to one CPU, then the default is 1.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    unsetenv("CUFUND_NUM_THREADS");
    cpu_set_t one;
    CPU_ZERO(&one);
    cpu_set_t all;
    sched_getaffinity(0, sizeof(all), &all);
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &all)) {
        CPU_SET(c, &one);
        break;
      }
    }
    sched_setaffinity(0, sizeof(one), &one);
    _exit(ThreadPool::default_size() == 1 && ThreadPool::instance().size() == 1 ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(ThreadPool, ForkWhileAnotherThreadRunsALoopGivesAWorkingChild) {
  std::atomic<bool> go{true};
  std::atomic<long> loops{0};
  std::thread busy([&] {
    while (go.load()) {
      ThreadPool::instance().parallel_for(64, 0, [](std::size_t) {
        volatile double x = 0;
        for (int k = 0; k < 2000; ++k) x = x + k;
      });
      loops.fetch_add(1);
    }
  });
  while (loops.load() < 3) std::this_thread::yield();
  for (int rep = 0; rep < 10; ++rep) {
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      std::atomic<long> sum{0};
      ThreadPool::instance().parallel_for(1000, 0, [&](std::size_t i) { sum += static_cast<long>(i); });
      _exit(sum.load() == 999L * 1000 / 2 ? 0 : 1);
    }
    int status = 0;
    // A deadlocked child never exits: give it 20 s, then fail.
    pid_t done = 0;
    for (int k = 0; k < 2000 && done == 0; ++k) {
      done = waitpid(pid, &status, WNOHANG);
      if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    if (done == 0) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      ADD_FAILURE() << "the child deadlocked";
      break;
    }
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
  }
  go.store(false);
  busy.join();
}

}  // namespace
}  // namespace cufund

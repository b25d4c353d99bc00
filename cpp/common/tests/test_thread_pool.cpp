#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <set>
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
      for (int rep = 0; rep < 50; ++rep) pool.parallel_for(100, 0, [&](std::size_t i) { total += static_cast<long>(i); });
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

}  // namespace
}  // namespace cufund

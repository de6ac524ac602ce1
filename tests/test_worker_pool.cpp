// The ray casts' worker threads (reference/worker_pool.hpp): every index
// runs once, whoever calls, however many call at once, and from inside a
// task.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "reference/worker_pool.hpp"

namespace umbra {
namespace {

TEST(WorkerPool, EveryIndexRunsOnceAndTheCallWaitsForAll) {
  EXPECT_GE(worker_count(), 1);
  for (const int count : {0, 1, 2, 7, 1000}) {
    std::vector<std::atomic<int>> runs(static_cast<std::size_t>(count));
    run_on_workers(count, [&](int i) { runs[std::size_t(i)].fetch_add(1); });
    for (int i = 0; i < count; ++i) ASSERT_EQ(runs[std::size_t(i)].load(), 1) << "index " << i << " of " << count;
  }
}

TEST(WorkerPool, CallersAtOnceAndTasksThatCallAgainAllFinish) {
  std::atomic<long> sum{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < 4; ++c)
    callers.emplace_back([&] {
      for (int round = 0; round < 20; ++round)
        run_on_workers(50, [&](int i) {
          // A task that runs a batch of its own: the pool may be busy with
          // the outer batches, and the inner one still finishes.
          if (i % 10 == 0) run_on_workers(5, [&](int j) { sum.fetch_add(j); });
          sum.fetch_add(1);
        });
    });
  for (std::thread& t : callers) t.join();
  // 4 callers x 20 rounds x (50 tasks + 5 inner batches of 0+1+2+3+4).
  EXPECT_EQ(sum.load(), 4L * 20 * (50 + 5 * 10));
}

}  // namespace
}  // namespace umbra

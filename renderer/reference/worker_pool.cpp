#include "reference/worker_pool.hpp"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace umbra {

namespace {

// One call of run_on_workers: its indices are claimed one at a time by
// whoever is free, the caller first among them.
struct Batch {
  const std::function<void(int)>* task = nullptr;
  int count = 0;
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex mutex;
  std::condition_variable finished;

  // Runs indices until none is left; true if it ran the last one to finish.
  void work() {
    for (int i; (i = next.fetch_add(1)) < count;) {
      (*task)(i);
      if (done.fetch_add(1) + 1 == count) {
        std::lock_guard<std::mutex> lock(mutex);
        finished.notify_all();
      }
    }
  }
};

class Pool {
 public:
  explicit Pool(int threads) {
    for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { serve(); });
    // Never joined: the pool lives as long as the process (see pool()).
    for (std::thread& t : threads_) t.detach();
  }

  int size() const { return int(threads_.size()); }

  void run(int count, const std::function<void(int)>& task) {
    if (count <= 0) return;
    auto batch = std::make_shared<Batch>();
    batch->task = &task;
    batch->count = count;
    if (count > 1 && !threads_.empty()) {
      std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_back(batch);
      ready_.notify_all();
    }
    batch->work();
    std::unique_lock<std::mutex> lock(batch->mutex);
    batch->finished.wait(lock, [&] { return batch->done.load() == count; });
  }

 private:
  void serve() {
    for (;;) {
      std::shared_ptr<Batch> batch;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        ready_.wait(lock, [&] { return !queue_.empty(); });
        batch = queue_.front();
        // Every index claimed: nobody else needs to look at it.
        if (batch->next.load() >= batch->count) {
          queue_.pop_front();
          continue;
        }
      }
      batch->work();
    }
  }

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::shared_ptr<Batch>> queue_;
};

Pool& pool() {
  // Leaked on purpose: its threads wait for work until the process ends,
  // and no static destructor may run while they do.
  static Pool* const instance = new Pool(int(std::max(1u, std::thread::hardware_concurrency())) - 1);
  return *instance;
}

}  // namespace

void run_on_workers(int count, const std::function<void(int)>& task) { pool().run(count, task); }

int worker_count() { return pool().size() + 1; }

}  // namespace umbra

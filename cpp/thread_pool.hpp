// A persistent pool of worker threads running one parallel loop at a time.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace sr {

class ThreadPool {
 public:
  // threads <= 0 => one per hardware core. The calling thread is worker 0.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return int(workers_.size()) + 1; }

  // Calls fn(item, worker) for every item in [0, count), items handed out dynamically. Which
  // worker runs an item must not change its result (callers write disjoint outputs), nor how
  // many take part: a worker that has not woken up by the time the caller runs out of items
  // sits the loop out (so a thread just started, or not scheduled on a busy machine, never
  // delays the caller; a Renderer's first frame need not wait for its threads to start).
  // Rethrows the first exception an item threw, after every worker has stopped.
  void parallel_for(std::size_t count, const std::function<void(std::size_t, int)>& fn);

 private:
  void worker_loop(int worker);
  void run_items(int worker);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  const std::function<void(std::size_t, int)>* job_ = nullptr;
  std::size_t count_ = 0;
  std::atomic<std::size_t> next_{0};
  std::atomic<std::size_t> generation_{0};  // written under mutex_, read by spinning workers
  bool open_ = false;          // workers may still join the current loop
  std::atomic<int> busy_{0};   // workers that joined it and are running items
  bool stop_ = false;
  std::exception_ptr error_;
};

}  // namespace sr

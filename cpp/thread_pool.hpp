// A persistent pool of worker threads running one parallel loop at a time.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace sr {

// Largest thread count a pool accepts (the caller included). Each worker reserves a stack (8 MiB
// of address space with Linux's default ulimit -s) and, once it renders a tile, ~120 KB of tile
// scratch: 256 workers already reserve 2 GiB. More threads than cores only add contention, and
// 256 is above the core count of the machines this targets. Exposed to Python as MAX_THREADS.
constexpr int kMaxThreads = 256;

class ThreadPool {
 public:
  // threads == 0 => one per hardware core (at most kMaxThreads). The calling thread is worker 0.
  // Throws std::invalid_argument for threads < 0 or > kMaxThreads, and std::runtime_error naming
  // `threads` when the system refuses a worker thread (ulimit -u or -v, or out of memory); the
  // workers already started are stopped and joined first, so none is left behind.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return size_; }

  // Calls fn(item, worker) for every item in [0, count), items handed out dynamically. Which
  // worker runs an item must not change its result (callers write disjoint outputs), nor how
  // many take part: a worker that has not woken up by the time the caller runs out of items
  // sits the loop out (so a thread just started, or not scheduled on a busy machine, never
  // delays the caller; a Renderer's first frame need not wait for its threads to start).
  // Rethrows the first exception an item threw, after every worker has stopped.
  // In the child of a fork() the pool's threads do not exist: the first loop there starts new
  // ones (and may throw like the constructor when the system refuses them).
  void parallel_for(std::size_t count, const std::function<void(std::size_t, int)>& fn);

 private:
  struct Workers;  // the threads and everything they share, owned by one process

  int size_;
  unsigned forks_;                    // fork_count() when workers_ was started
  std::unique_ptr<Workers> workers_;  // null when size_ == 1, or after a failed restart
};

// Testing only: the n-th worker thread started from now on (1 = the next one) fails as if the
// system had refused it (std::system_error, EAGAIN); 0 turns this off. Lets a test exercise the
// failure path without exhausting the machine (or under AddressSanitizer, which owns the limits).
void fail_thread_start(int n);

}  // namespace sr

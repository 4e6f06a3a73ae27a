// Persistent worker threads; the caller takes part in each loop.
#include "thread_pool.hpp"

#include <chrono>
#include <emmintrin.h>

namespace sr {

namespace {

// How long a thread spins for the next loop (workers) or for the loop's end (the caller) before
// it sleeps on a condition variable. A render runs several loops back to back; waking a sleeping
// thread costs tens of microseconds here, which 0.1-2 ms frames felt (ThreadPool in RESULTS.md).
constexpr auto kSpin = std::chrono::microseconds(50);

template <typename Ready>
void spin_until(Ready ready) {
  const auto start = std::chrono::steady_clock::now();
  for (unsigned i = 1; !ready(); ++i) {
    _mm_pause();
    if (i % 64 == 0 && std::chrono::steady_clock::now() - start > kSpin) return;
  }
}

}  // namespace

ThreadPool::ThreadPool(int threads) {
  if (threads <= 0) threads = int(std::max(1u, std::thread::hardware_concurrency()));
  for (int w = 1; w < threads; ++w) workers_.emplace_back([this, w] { worker_loop(w); });
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void ThreadPool::run_items(int worker) {
  for (;;) {
    const std::size_t item = next_.fetch_add(1, std::memory_order_relaxed);
    if (item >= count_) return;
    try {
      (*job_)(item, worker);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error_) error_ = std::current_exception();
      next_.store(count_, std::memory_order_relaxed);  // stop handing out items
    }
  }
}

void ThreadPool::worker_loop(int worker) {
  std::size_t seen = 0;
  for (;;) {
    spin_until([&] { return generation_.load(std::memory_order_acquire) != seen; });
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      if (!open_) continue;  // woke after the caller finished that loop: nothing left to join
      ++busy_;
    }
    run_items(worker);
    if (busy_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      std::lock_guard<std::mutex> lock(mutex_);  // the caller may be about to wait
      done_.notify_one();
    }
  }
}

void ThreadPool::parallel_for(std::size_t count, const std::function<void(std::size_t, int)>& fn) {
  if (count == 0) return;
  if (workers_.empty() || count == 1) {
    for (std::size_t i = 0; i < count; ++i) fn(i, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &fn;
    count_ = count;
    next_.store(0, std::memory_order_relaxed);
    error_ = nullptr;
    open_ = true;
    ++generation_;
  }
  wake_.notify_all();
  run_items(0);
  spin_until([&] { return busy_.load(std::memory_order_acquire) == 0; });
  std::exception_ptr error;
  {
    // Every item is taken: close the loop to workers not yet awake, wait for those running one.
    std::unique_lock<std::mutex> lock(mutex_);
    open_ = false;
    done_.wait(lock, [&] { return busy_ == 0; });
    job_ = nullptr;
    error = error_;
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace sr

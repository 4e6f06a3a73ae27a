// Persistent worker threads; the caller takes part in each loop.
#include "thread_pool.hpp"

#include <chrono>
#include "simd.hpp"  // SR_X86

#if SR_X86
#include <emmintrin.h>
#endif
#include <pthread.h>
#include <stdexcept>
#include <string>
#include <system_error>

namespace sr {

namespace {

// How long a thread spins for the next loop (workers) or for the loop's end (the caller) before
// it sleeps on a condition variable. A render runs several loops back to back, and waking a
// sleeping thread costs enough for short frames to feel it (benchmarks/RESULTS.md, "Measurements
// behind the code").
constexpr auto kSpin = std::chrono::microseconds(50);

// A spin-wait hint to the CPU.
inline void cpu_relax() {
#if SR_X86
  _mm_pause();
#elif defined(__aarch64__)
  __asm__ __volatile__("yield");
#endif
}

template <typename Ready>
void spin_until(Ready ready) {
  const auto start = std::chrono::steady_clock::now();
  for (unsigned i = 1; !ready(); ++i) {
    cpu_relax();
    if (i % 64 == 0 && std::chrono::steady_clock::now() - start > kSpin) return;
  }
}

// fork() copies only the thread that called it: in the child a pool's workers do not exist, and
// its mutex may be held forever by one of them (workers take it each time they go to sleep or
// wake). Counting forks in the child (a pthread_atfork handler, registered when the library
// loads) tells a pool it was inherited with one relaxed atomic load per loop; getpid() would be a
// system call (glibc stopped caching it in 2.25), and it can also repeat in a grandchild.
std::atomic<unsigned> g_forks{0};
void count_fork_in_child() { g_forks.fetch_add(1, std::memory_order_relaxed); }
[[maybe_unused]] const int g_fork_handler = pthread_atfork(nullptr, nullptr, count_fork_in_child);
unsigned fork_count() { return g_forks.load(std::memory_order_relaxed); }

std::atomic<int> g_fail_thread_start{0};  // fail_thread_start(): countdown, 0 = off

bool injected_thread_failure() {
  int n = g_fail_thread_start.load(std::memory_order_relaxed);
  while (n > 0 && !g_fail_thread_start.compare_exchange_weak(n, n - 1)) {
  }
  return n == 1;
}

}  // namespace

void fail_thread_start(int n) { g_fail_thread_start.store(std::max(n, 0)); }

struct ThreadPool::Workers {
  std::vector<std::thread> threads;
  std::mutex mutex;
  std::condition_variable wake, done;
  const std::function<void(std::size_t, int)>* job = nullptr;
  std::size_t count = 0;
  std::atomic<std::size_t> next{0};
  std::atomic<std::size_t> generation{0};  // written under mutex, read by spinning workers
  bool open = false;          // workers may still join the current loop
  std::atomic<int> busy{0};   // workers that joined it and are running items
  bool stop = false;
  std::exception_ptr error;

  // Starts workers 1 .. pool_size - 1. If the system refuses one, stops and joins those already
  // running (a joinable std::thread must not be destroyed, and ~condition_variable would wait for
  // them forever: Renderer(w, h, threads=200) under ulimit -v hung so), then throws.
  static std::unique_ptr<Workers> start(int pool_size) {
    auto workers = std::make_unique<Workers>();
    workers->threads.reserve(std::size_t(pool_size - 1));  // emplace_back must not reallocate
    for (int w = 1; w < pool_size; ++w) {
      try {
        if (injected_thread_failure())
          throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again));
        workers->threads.emplace_back([p = workers.get(), w] { p->worker_loop(w); });
      } catch (const std::exception& e) {
        workers->stop_and_join();
        throw std::runtime_error(
            "threads=" + std::to_string(pool_size) + ": could not start worker thread " +
            std::to_string(w) + " (" + e.what() +
            "); the process is out of threads or memory (ulimit -u, ulimit -v): use fewer threads");
      }
    }
    return workers;
  }

  void stop_and_join() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    wake.notify_all();
    for (std::thread& t : threads) t.join();
  }

  void run_items(int worker) {
    for (;;) {
      const std::size_t item = next.fetch_add(1, std::memory_order_relaxed);
      if (item >= count) return;
      try {
        (*job)(item, worker);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        next.store(count, std::memory_order_relaxed);  // stop handing out items
      }
    }
  }

  void worker_loop(int worker) {
    std::size_t seen = 0;
    for (;;) {
      spin_until([&] { return generation.load(std::memory_order_acquire) != seen; });
      {
        std::unique_lock<std::mutex> lock(mutex);
        wake.wait(lock, [&] { return stop || generation != seen; });
        if (stop) return;
        seen = generation;
        if (!open) continue;  // woke after the caller finished that loop: nothing left to join
        ++busy;
      }
      run_items(worker);
      if (busy.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        std::lock_guard<std::mutex> lock(mutex);  // the caller may be about to wait
        done.notify_one();
      }
    }
  }

  void run(std::size_t n, const std::function<void(std::size_t, int)>& fn) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      job = &fn;
      count = n;
      next.store(0, std::memory_order_relaxed);
      error = nullptr;
      open = true;
      ++generation;
    }
    wake.notify_all();
    run_items(0);
    spin_until([&] { return busy.load(std::memory_order_acquire) == 0; });
    std::exception_ptr failed;
    {
      // Every item is taken: close the loop to workers not yet awake, wait for those running one.
      std::unique_lock<std::mutex> lock(mutex);
      open = false;
      done.wait(lock, [&] { return busy == 0; });
      job = nullptr;
      failed = error;
    }
    if (failed) std::rethrow_exception(failed);
  }
};

ThreadPool::ThreadPool(int threads) : forks_(fork_count()) {
  if (threads < 0 || threads > kMaxThreads)
    throw std::invalid_argument("threads must be in [0, " + std::to_string(kMaxThreads) +
                                "] (0 = one per core), got " + std::to_string(threads));
  if (threads == 0)
    threads = std::clamp(int(std::thread::hardware_concurrency()), 1, kMaxThreads);
  size_ = threads;
  if (size_ > 1) workers_ = Workers::start(size_);
}

ThreadPool::~ThreadPool() {
  if (!workers_) return;
  if (forks_ != fork_count()) {
    // Inherited through fork(): the threads are the parent's, joining them would wait forever.
    // Leaked on purpose (a few hundred bytes): destroying their std::thread handles would call
    // std::terminate, and the mutex may be locked for good.
    (void)workers_.release();
    return;
  }
  workers_->stop_and_join();
}

void ThreadPool::parallel_for(std::size_t count, const std::function<void(std::size_t, int)>& fn) {
  if (count == 0) return;
  if (size_ == 1 || count == 1) {
    for (std::size_t i = 0; i < count; ++i) fn(i, 0);
    return;
  }
  if (!workers_ || forks_ != fork_count()) {
    // First loop in a forked child (or a retry after the system refused threads there): the
    // workers inherited are leaked, as in ~ThreadPool, and a fresh set with its own mutex and
    // condition variables is started. Renders in the child then match the parent's bits.
    (void)workers_.release();
    workers_ = Workers::start(size_);
    forks_ = fork_count();
  }
  workers_->run(count, fn);
}

}  // namespace sr

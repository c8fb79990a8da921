#pragma once
// The CPU backend's threads. A job is a count of independent work items; the calling thread
// and the workers claim items one at a time from a shared counter, so a worker that the
// operating system does not schedule (a busy machine: the viewer renders beside the
// simulation) simply takes no items: the caller does them and never waits at a barrier for a
// thread that has not started. The caller waits only for items another thread has claimed and
// not finished. Idle workers block in the kernel (futex wait), they do not spin.
// Results must not depend on which thread ran an item: jobs write per-item results that the
// caller combines in item order.
// An exception thrown by an item (on any thread) is not lost and does not end the process:
// the first one is kept, the items not yet started are skipped, and run() rethrows it on the
// caller once every claimed item has finished (so no thread still runs the caller's function
// when its frame is gone).
#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace hpcm::cpu {

class WorkerPool {
 public:
  /// `threads` in all, the caller included (1: everything runs on the caller).
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  /// Runs fn(k) for every k in [0, count) and returns when all have finished. Jobs with
  /// fewer than `min_parallel` items run on the caller alone. If an item throws, the first
  /// exception is rethrown here after all threads have left the job; some items may not run.
  template <class F>
  void run(std::int64_t count, F&& fn, std::int64_t min_parallel = 2) {
    if (count <= 0) return;
    if (workers_.empty() || count < min_parallel) {
      for (std::int64_t k = 0; k < count; ++k) fn(k);
      return;
    }
    dispatch(Job{count, &fn, [](void* f, std::int64_t k) { (*static_cast<F*>(f))(k); }});
  }

 private:
  struct Job {
    std::int64_t count;
    void* fn;
    void (*call)(void*, std::int64_t);
  };
  void dispatch(const Job& job);
  void work(std::uint64_t generation, const Job& job);
  void worker_loop(std::uint64_t seen);
  void record_failure();

  std::vector<std::thread> workers_;
  // The current job, published before its generation (atomics: a late reader may mix fields
  // of two jobs, but then its claim fails, see worker_pool.cpp).
  std::atomic<std::int64_t> job_count_{0};
  std::atomic<void*> job_fn_{nullptr};
  std::atomic<void (*)(void*, std::int64_t)> job_call_{nullptr};
  std::atomic<std::uint64_t> generation_{0};  ///< bumped for every job (workers wait on it)
  std::atomic<std::uint64_t> ticket_{0};      ///< generation << 32 | next item to claim
  std::atomic<std::int64_t> done_{0};         ///< items finished
  std::atomic<bool> stop_{false};
  std::atomic<bool> failed_{false};  ///< an item of the current job threw: skip the rest
  std::mutex error_mutex_;
  std::exception_ptr error_;  ///< the first exception of the current job (under error_mutex_)
};

/// Threads the backend uses: OpenMP's setting (OMP_NUM_THREADS / omp_set_num_threads), at least 1.
int default_thread_count();

}  // namespace hpcm::cpu

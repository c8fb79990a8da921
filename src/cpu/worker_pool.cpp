#include "cpu/worker_pool.hpp"

#include <omp.h>

#include <algorithm>

namespace hpcm::cpu {

namespace {
// The ticket packs (generation << 32 | next item). A thread claims an item by compare-and-swap
// on the ticket of the generation it woke up for, so a thread that is late for one job can
// never claim (or run) an item of the next one.
constexpr std::uint64_t kClosed = ~std::uint64_t{0} << 32;
std::uint64_t ticket_of(std::uint64_t generation, std::uint64_t item) { return (generation << 32) | item; }
}  // namespace

int default_thread_count() { return std::max(1, omp_get_max_threads()); }

WorkerPool::WorkerPool(int threads) {
  // Workers start from generation 0, read here and not in the thread: a thread that starts
  // late must still see every later job (and the stop) as new.
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this] { worker_loop(0); });
}

WorkerPool::~WorkerPool() {
  stop_.store(true);
  generation_.fetch_add(1);
  generation_.notify_all();
  for (auto& w : workers_) w.join();
}

void WorkerPool::dispatch(const Job& job) {
  const std::uint64_t g = (generation_.load() + 1) & 0x7fffffffu;
  ticket_.store(kClosed);  // no late thread can claim while the job is rewritten
  job_count_.store(job.count);
  job_fn_.store(job.fn);
  job_call_.store(job.call);
  done_.store(0);
  failed_.store(false);
  ticket_.store(ticket_of(g, 0));
  generation_.store(g);
  generation_.notify_all();
  work(g, job);
  for (std::int64_t d = done_.load(); d < job.count; d = done_.load()) done_.wait(d);
  // Every item is finished or skipped: no thread touches the job any more.
  if (failed_.load()) {
    std::exception_ptr error;
    {
      const std::lock_guard<std::mutex> lock(error_mutex_);
      error.swap(error_);
    }
    std::rethrow_exception(error);
  }
}

void WorkerPool::record_failure() {
  {
    const std::lock_guard<std::mutex> lock(error_mutex_);
    if (!error_) error_ = std::current_exception();
  }
  failed_.store(true);
}

void WorkerPool::work(std::uint64_t generation, const Job& job) {
  for (;;) {
    std::uint64_t t = ticket_.load();
    std::int64_t item;
    do {
      if ((t >> 32) != generation) return;
      item = static_cast<std::int64_t>(t & 0xffffffffu);
      if (item >= job.count) return;
    } while (!ticket_.compare_exchange_weak(t, t + 1));
    if (!failed_.load()) {
      try {
        job.call(job.fn, item);
      } catch (...) {
        record_failure();
      }
    }
    if (done_.fetch_add(1) + 1 == job.count) done_.notify_all();
  }
}

void WorkerPool::worker_loop(std::uint64_t seen) {
  for (;;) {
    generation_.wait(seen);
    if (stop_.load()) return;
    seen = generation_.load();
    // If the caller has moved on to a later job meanwhile, these may mix two jobs' fields;
    // then the generation in the ticket differs and no claim succeeds.
    const Job job{job_count_.load(), job_fn_.load(), job_call_.load()};
    work(seen, job);
  }
}

}  // namespace hpcm::cpu

// viscd's own executor: a pool whose threads sleep until a stage is handed out and whose caller
// works too. Nothing spins: with every core taken by other processes, the workers simply get no
// core and the caller runs the tasks itself, instead of waiting at a barrier for threads that are
// not running (what an OpenMP team with active waiting does, 16x slower than one thread there).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include "cpu/parallel.hpp"

namespace viscd::detail {
namespace {

class ThreadPool final : public Executor {
 public:
  explicit ThreadPool(int threads) : threads_(std::max(1, threads)) {
    for (int w = 1; w < threads_; ++w) workers_.emplace_back([this] { work(); });
  }
  ~ThreadPool() override {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  [[nodiscard]] int concurrency() const override { return threads_; }

  void run(std::uint32_t count, TaskRef task) override {
    std::unique_lock submit(submit_, std::try_to_lock);
    if (workers_.empty() || count <= 1 || !submit.owns_lock()) {
      // One task, no workers, or the pool is busy with another caller's stage: run it here.
      for (std::uint32_t i = 0; i < count; ++i) task(i);
      return;
    }
    {
      // A worker that woke for the previous stage after it ended may still hold that stage's
      // task (it finds no index left and returns): let it leave before the indices restart.
      std::unique_lock lock(mutex_);
      finished_.wait(lock, [&] { return busy_workers_.load(std::memory_order_relaxed) == 0; });
      task_ = task;
      count_ = count;
      next_.store(0, std::memory_order_relaxed);
      done_.store(0, std::memory_order_relaxed);
      ++generation_;
      published_.store(generation_, std::memory_order_release);
    }
    wake_.notify_all();
    take_tasks(task, count);
    // Wait until every task has finished and no worker is still looking for one (a worker that
    // woke for this stage must not take an index of the next). A worker's last task usually ends
    // within microseconds of the caller's: look briefly before sleeping (kSpin, as the workers),
    // since being woken costs tens of microseconds.
    const auto finished = [&] {
      return done_.load(std::memory_order_acquire) == count && busy_workers_.load(std::memory_order_acquire) == 0;
    };
    const auto until = std::chrono::steady_clock::now() + kSpin;
    for (int k = 1; !finished(); ++k) {
      pause();
      if (k % 64 == 0 && std::chrono::steady_clock::now() > until) break;
    }
    std::unique_lock lock(mutex_);
    finished_.wait(lock, finished);
  }

 private:
  void take_tasks(TaskRef task, std::uint32_t count) {
    for (;;) {
      const std::uint32_t i = next_.fetch_add(1, std::memory_order_relaxed);
      if (i >= count) return;
      task(i);
      done_.fetch_add(1, std::memory_order_acq_rel);
    }
  }

  void work() {
    std::uint64_t seen = 0;
    std::unique_lock lock(mutex_);
    for (;;) {
      if (!stop_ && generation_ == seen) {
        // Stages follow each other within microseconds: look for the next one briefly before
        // sleeping (a futex wake-up costs tens of microseconds). Bounded at kSpin, 20 us: a
        // worker never holds a core for longer than that when there is nothing to do.
        lock.unlock();
        const auto until = std::chrono::steady_clock::now() + kSpin;
        for (int k = 1; published_.load(std::memory_order_acquire) == seen; ++k) {
          pause();
          if (k % 64 == 0 && std::chrono::steady_clock::now() > until) break;
        }
        lock.lock();
      }
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      const TaskRef task = task_;
      const std::uint32_t count = count_;
      busy_workers_.fetch_add(1, std::memory_order_relaxed);
      lock.unlock();
      take_tasks(task, count);
      lock.lock();
      if (busy_workers_.fetch_sub(1, std::memory_order_acq_rel) == 1) finished_.notify_all();
    }
  }

  const int threads_;
  std::vector<std::thread> workers_;
  std::mutex submit_;  // one stage at a time
  std::mutex mutex_;
  std::condition_variable wake_, finished_;
  static constexpr std::chrono::microseconds kSpin{20};
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
  }
  std::uint64_t generation_ = 0;
  std::atomic<std::uint64_t> published_{0};  // generation_, readable without the lock
  bool stop_ = false;
  std::atomic<int> busy_workers_{0};  // changed under mutex_; read without it by a spinning caller
  TaskRef task_;
  std::uint32_t count_ = 0;
  std::atomic<std::uint32_t> next_{0}, done_{0};
};

thread_local Executor* t_current = nullptr;

}  // namespace

int hardware_threads() {
  static const int n = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return n;
}

int resolve_threads(int requested, int available) {
  available = available > 0 ? available : hardware_threads();
  return requested > 0 ? std::min(requested, available) : available;
}

Executor& default_executor() {
  static ThreadPool pool(hardware_threads());
  return pool;
}

Executor& current_executor() { return t_current ? *t_current : default_executor(); }

ExecutorScope::ExecutorScope(Executor* executor) : previous_(t_current) { t_current = executor; }
ExecutorScope::~ExecutorScope() { t_current = previous_; }

}  // namespace viscd::detail

namespace viscd {
Executor& shared_executor() { return detail::default_executor(); }
}  // namespace viscd

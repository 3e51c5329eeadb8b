#pragma once
/// \file executor.hpp
/// Where a detector's parallel work runs. An engine with a job system of its own hands viscd an
/// Executor (Config::executor), so that viscd's stages run on the engine's threads instead of
/// threads of viscd's own; without one, viscd uses a built-in pool (docs/architecture.md,
/// "Threads").

#include <cstdint>
#include <type_traits>
#include <utility>

namespace viscd {

/// A non-owning reference to a callable `void(std::uint32_t task)`; cheap to copy, never
/// allocates. It must not outlive the callable it refers to.
class TaskRef {
 public:
  TaskRef() = default;
  template <class F, class = std::enable_if_t<!std::is_same_v<std::decay_t<F>, TaskRef>>>
  TaskRef(F&& f)  // NOLINT(google-explicit-constructor,bugprone-forwarding-reference-overload): into run()
      : call_([](const void* c, std::uint32_t i) {
          (*static_cast<std::remove_reference_t<F>*>(const_cast<void*>(c)))(i);
        }),
        context_(&f) {}
  void operator()(std::uint32_t task) const { call_(context_, task); }

 private:
  void (*call_)(const void*, std::uint32_t) = nullptr;
  const void* context_ = nullptr;
};

/// Runs a detector's parallel stages. viscd splits a stage into `count` independent tasks and
/// calls run() from the thread that called detect(); run() returns when task(i) has finished
/// for every i in [0, count). Tasks may run in any order and on any threads; the calling thread
/// should take part (then a busy machine degrades to the caller doing the work, instead of the
/// caller waiting for threads that get no core). viscd never calls run() from inside a task.
class Executor {
 public:
  virtual ~Executor() = default;
  /// How many tasks can usefully run at once (>= 1). viscd makes about this many tasks per
  /// stage, more where the work per item varies.
  [[nodiscard]] virtual int concurrency() const = 0;
  virtual void run(std::uint32_t count, TaskRef task) = 0;
};

/// viscd's own pool, which every detector without an executor of its own (Config::executor) uses:
/// one thread per hardware thread but one, the caller taking part, created on first use. The
/// adapters run their own parallel loops on it (or on Config::executor when one is set). A pool
/// busy with another caller's tasks runs new ones on their caller instead of queueing them.
[[nodiscard]] Executor& shared_executor();

/// An Executor that runs every task on the calling thread, in order.
class SerialExecutor final : public Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 1; }
  void run(std::uint32_t count, TaskRef task) override {
    for (std::uint32_t i = 0; i < count; ++i) task(i);
  }
};

}  // namespace viscd

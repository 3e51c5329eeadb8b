#pragma once
// What the Bullet and FCL adapters share: engines' double (or btScalar) bounds rounded outward to
// viscd's float boxes, and vectors lent to one call at a time.

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

namespace viscd::adapter_detail {

/// v rounded down / up to a float: the largest float <= v, the smallest float >= v (v itself for
/// a float). A box rounded this way holds the engine's box, so no overlap is lost. NaN stays NaN;
/// beyond the float range, +-inf (and the largest float on the side toward v).
///
/// The float nearest v, then one step of its bits away from v when it overshot: for a step down
/// the bits of a float with the sign bit clear go down by one, those of one with it set (-0
/// included: -0 less a step is the negative float nearest zero) go up. An overshooting +0 cannot
/// occur (a negative v rounds to -0 or below), nor a -0 rounding up. No branch: the adapters
/// round every bound of every object each frame, and half of them took the step's branch.
template <class T>
[[nodiscard]] float round_down(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    const auto f = static_cast<float>(v);
    const auto bits = std::bit_cast<std::uint32_t>(f);
    const std::uint32_t step = (bits >> 31) != 0 ? 1u : ~0u;                  // +1 or -1 on the bits
    return std::bit_cast<float>(bits + (static_cast<T>(f) > v ? step : 0u));  // f > v: not NaN, not -inf
  }
}
template <class T>
[[nodiscard]] float round_up(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    const auto f = static_cast<float>(v);
    const auto bits = std::bit_cast<std::uint32_t>(f);
    const std::uint32_t step = (bits >> 31) != 0 ? ~0u : 1u;
    return std::bit_cast<float>(bits + (static_cast<T>(f) < v ? step : 0u));  // f < v: not NaN, not +inf
  }
}

/// Vectors lent to one call and given back when it ends, so that calls reuse their memory and a
/// steady state allocates nothing. A call made from inside a callback (which may use the adapter
/// again) borrows another vector; the pool then holds one more.
template <class T>
class VectorPool {
 public:
  class Loan {
   public:
    explicit Loan(VectorPool& pool) : pool_(pool) {
      if (!pool_.free_.empty()) {
        v_ = std::move(pool_.free_.back());
        pool_.free_.pop_back();
      }
      v_.clear();
    }
    ~Loan() { pool_.free_.push_back(std::move(v_)); }
    Loan(const Loan&) = delete;
    Loan& operator=(const Loan&) = delete;
    std::vector<T>& operator*() { return v_; }
    std::vector<T>* operator->() { return &v_; }

   private:
    VectorPool& pool_;
    std::vector<T> v_;
  };
  [[nodiscard]] Loan take() { return Loan(*this); }

 private:
  std::vector<std::vector<T>> free_;
};

}  // namespace viscd::adapter_detail

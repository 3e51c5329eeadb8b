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

/// The float next to f toward -inf / +inf, for f not NaN and not already at that end: a step of
/// its bits (what std::nextafter does, without the call: it ran for half of every bound).
[[nodiscard]] inline float float_below(float f) {
  if (f == 0) return -std::numeric_limits<float>::denorm_min();
  const auto b = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>(f > 0 ? b - 1 : b + 1);
}
[[nodiscard]] inline float float_above(float f) {
  if (f == 0) return std::numeric_limits<float>::denorm_min();
  const auto b = std::bit_cast<std::uint32_t>(f);
  return std::bit_cast<float>(f > 0 ? b + 1 : b - 1);
}

/// v rounded down / up to a float: the largest float <= v, the smallest float >= v (v itself for
/// a float). A box rounded this way holds the engine's box, so no overlap is lost. NaN stays NaN;
/// beyond the float range, +-inf (and the largest float on the side toward v).
template <class T>
[[nodiscard]] float round_down(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    const auto f = static_cast<float>(v);
    return static_cast<T>(f) > v ? float_below(f) : f;  // f > v: not NaN, not -inf
  }
}
template <class T>
[[nodiscard]] float round_up(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    const auto f = static_cast<float>(v);
    return static_cast<T>(f) < v ? float_above(f) : f;  // f < v: not NaN, not +inf
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

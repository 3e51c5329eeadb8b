#pragma once
// What the Bullet and FCL adapters share: engines' double (or btScalar) bounds rounded outward to
// viscd's float boxes, and vectors lent to one call at a time.

#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

namespace viscd::adapter_detail {

/// v rounded down / up to a float: the largest float <= v, the smallest float >= v (v itself for
/// a float). A box rounded this way holds the engine's box, so no overlap is lost. NaN stays NaN.
template <class T>
[[nodiscard]] float round_down(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    float f = static_cast<float>(v);
    if (static_cast<T>(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    return f;
  }
}
template <class T>
[[nodiscard]] float round_up(T v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    float f = static_cast<float>(v);
    if (static_cast<T>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
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

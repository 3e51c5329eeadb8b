#pragma once
// What the Bullet and FCL adapters share: engines' double (or btScalar) bounds rounded outward to
// viscd's float boxes, vectors lent to one call at a time, and an index of an engine's objects.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
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

/// Pointers (never null) to indices, for an engine's objects: an open-addressing table with
/// linear probing, at most half full, so that a lookup reads one cache line in the common case
/// (std::unordered_map reads its bucket array, then a node allocated on its own: two or three
/// misses per object an engine names). Removal shifts the entries after the slot back, so the
/// table never holds tombstones.
class PointerIndex {
 public:
  static constexpr std::uint32_t kMissing = ~0u;

  [[nodiscard]] std::size_t size() const { return size_; }
  /// The value of p, or kMissing.
  [[nodiscard]] std::uint32_t find(const void* p) const {
    if (p == nullptr || slots_.empty()) return kMissing;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = home(p);; i = (i + 1) & mask) {
      if (slots_[i].key == p) return slots_[i].value;
      if (slots_[i].key == nullptr) return kMissing;
    }
  }
  /// Where find(p) starts reading, to fetch it a few lookups ahead (nullptr for an empty table).
  [[nodiscard]] const void* slot_of(const void* p) const { return slots_.empty() ? nullptr : &slots_[home(p)]; }
  /// Adds p -> value; false, and nothing changes, when p is there already or null.
  bool insert(const void* p, std::uint32_t value) {
    if (p == nullptr) return false;
    if (2 * (size_ + 1) > slots_.size()) rehash(std::max<std::size_t>(16, 2 * slots_.size()));
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t i = home(p);; i = (i + 1) & mask) {  // one probe: p's slot, or the first hole
      if (slots_[i].key == p) return false;
      if (slots_[i].key == nullptr) {
        slots_[i] = Slot{p, value};
        ++size_;
        return true;
      }
    }
  }
  /// Sets the value of p, which is there.
  void assign(const void* p, std::uint32_t value) {
    const std::size_t mask = slots_.size() - 1;
    std::size_t i = home(p);
    while (slots_[i].key != p) i = (i + 1) & mask;
    slots_[i].value = value;
  }
  /// Removes p; false when it is not there.
  bool erase(const void* p) {
    if (p == nullptr || slots_.empty()) return false;
    const std::size_t mask = slots_.size() - 1;
    std::size_t i = home(p);
    for (; slots_[i].key != p; i = (i + 1) & mask)
      if (slots_[i].key == nullptr) return false;
    // The entries after i up to the next empty slot: each moves back into the hole unless its
    // home lies cyclically in (hole, its slot], where a lookup would no longer pass the hole.
    for (std::size_t j = (i + 1) & mask; slots_[j].key != nullptr; j = (j + 1) & mask) {
      const std::size_t k = home(slots_[j].key);
      const bool stays = i <= j ? (i < k && k <= j) : (i < k || k <= j);
      if (!stays) {
        slots_[i] = slots_[j];
        i = j;
      }
    }
    slots_[i] = Slot{};
    --size_;
    return true;
  }
  void clear() {
    std::fill(slots_.begin(), slots_.end(), Slot{});
    size_ = 0;
  }
  /// Room for n pointers without rehashing.
  void reserve(std::size_t n) {
    if (2 * n > slots_.size()) rehash(std::bit_ceil(std::max<std::size_t>(16, 2 * n)));
  }

 private:
  struct Slot {
    const void* key = nullptr;
    std::uint32_t value = 0;
  };
  // Fibonacci hashing: the top bits of the pointer times 2^64 / phi (allocations' low bits are
  // alike; the product's top bits mix all of them).
  [[nodiscard]] std::size_t home(const void* p) const {
    return static_cast<std::size_t>((reinterpret_cast<std::uintptr_t>(p) * 0x9E3779B97F4A7C15ull) >> shift_);
  }
  void rehash(std::size_t capacity) {  // a power of two
    std::vector<Slot> old(capacity);
    old.swap(slots_);
    shift_ = 64 - std::countr_zero(capacity);
    const std::size_t mask = capacity - 1;
    for (const Slot& s : old) {
      if (s.key == nullptr) continue;
      std::size_t i = home(s.key);
      while (slots_[i].key != nullptr) i = (i + 1) & mask;
      slots_[i] = s;
    }
  }

  std::vector<Slot> slots_;
  std::size_t size_ = 0;
  int shift_ = 64;
};

}  // namespace viscd::adapter_detail

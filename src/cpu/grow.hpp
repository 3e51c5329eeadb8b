#pragma once
// Buffers sized by the active count grow with headroom: the active set changes from frame to frame
// (objects cross lambda), and growing to exactly n would allocate on every frame that sets a new
// high. Nothing ever shrinks mid-run.

#include <cstddef>
#include <vector>

namespace viscd::detail {

/// v.resize(n), reserving n + n / 2 first when the capacity is short.
template <class T>
void resize_with_headroom(std::vector<T>& v, std::size_t n) {
  if (v.capacity() < n) v.reserve(n + n / 2);
  v.resize(n);
}

}  // namespace viscd::detail

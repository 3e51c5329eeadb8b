#pragma once
// The Morton layout and quantisation rules (docs/architecture.md, "Morton layout") as plain
// functions over plain arrays, compiled for the host and, in the cuda backend, for the device:
// core/morton.cpp and src/cuda/gpu.cu call these same definitions, so a layout planned on the GPU
// and a code computed there are the host's, bit for bit. C++17 and no library calls beyond the
// C maths functions, which CUDA provides on the device too.
#include <cmath>
#include <cstdint>

#if defined(__CUDACC__)
#define VISCD_HD __host__ __device__
#else
#define VISCD_HD
#endif

namespace viscd::detail::rule {

/// core/morton.hpp's MortonLayout without std::array.
struct Layout {
  int bits = 32;
  int axis_bits[3] = {0, 0, 0};
  std::uint8_t order[3] = {0, 1, 2};
  std::int8_t position[3][32] = {};
};

/// Fills `position` from the top bit of the code down; each bit goes to the axis whose current
/// cell is the largest (extent / 2^bits already given), ties in `order`, skipping axes whose bits
/// are used up. The used bits occupy the low sum(axis_bits) positions of the code. With equal
/// extents this is the classic round robin in `order`; for a flat world it keeps the flat axis's
/// few bits for the levels where the other axes' cells have become as thin as it is. The caller
/// guarantees sum(axis_bits) <= bits.
VISCD_HD inline void assign_positions(Layout& l, double cx, double cy, double cz) {
  double cell[3] = {cx, cy, cz};
  int left[3] = {l.axis_bits[0], l.axis_bits[1], l.axis_bits[2]};
  const int total = left[0] + left[1] + left[2];
  for (int pos = total - 1; pos >= 0; --pos) {
    int pick = -1;
    for (int k = 0; k < 3; ++k) {
      const int axis = l.order[k];
      if (left[axis] > 0 && (pick < 0 || cell[axis] > cell[pick])) pick = axis;
    }
    --left[pick];
    l.position[pick][left[pick]] = static_cast<std::int8_t>(pos);
    cell[pick] *= 0.5;
  }
}

/// The extended layout: axes by extent (ties x, y, z); the smallest gets min(cap, floor(m/3))
/// bits with cap = max(1, ceil(log2(extent_smallest / mean_diameter))); the other two share the
/// rest, the larger taking the extra bit. `extent` holds max(0, hi - lo) per axis.
VISCD_HD inline Layout extended_layout(int bits, const float extent[3], float mean_diameter) {
  Layout l;
  l.bits = bits;
  std::uint8_t order[3] = {0, 1, 2};
  for (int i = 1; i < 3; ++i)  // stable insertion sort, largest first
    for (int k = i; k > 0 && extent[order[k]] > extent[order[k - 1]]; --k) {
      const std::uint8_t t = order[k];
      order[k] = order[k - 1];
      order[k - 1] = t;
    }
  for (int k = 0; k < 3; ++k) l.order[k] = order[k];
  // Bits finer than an object are wasted on the flattest axis.
  int cap = 1;
  const double ratio = static_cast<double>(extent[order[2]]) / static_cast<double>(mean_diameter);
  if (ratio > 1.0) {  // log2 <= 0 (and NaN from 0/0) leave cap at 1; an infinite ratio caps at m/3
    if (std::isinf(ratio)) {
      cap = bits;
    } else {
      const int c = static_cast<int>(std::ceil(std::log2(ratio)));
      cap = c > 1 ? c : 1;
    }
  }
  const int smallest = cap < bits / 3 ? cap : bits / 3;
  const int rest = bits - smallest;
  l.axis_bits[order[0]] = rest - rest / 2;
  l.axis_bits[order[1]] = rest / 2;
  l.axis_bits[order[2]] = smallest;
  assign_positions(l, extent[0], extent[1], extent[2]);
  return l;
}

/// Plain interleaving x, y, z with floor(m/3) bits each.
VISCD_HD inline Layout plain_layout(int bits) {
  Layout l;
  l.bits = bits;
  for (int a = 0; a < 3; ++a) l.axis_bits[a] = bits / 3;
  assign_positions(l, 1.0, 1.0, 1.0);
  return l;
}

/// The quantisation grid of one axis with `axis_bits` bits over [lo, hi]: a coordinate v goes
/// to cell (v - lo) * scale in double, clamped to [0, max_cell].
VISCD_HD inline void axis_grid(int axis_bits, float lo, float hi, double& out_lo, double& scale, double& max_cell) {
  const double cells = std::ldexp(1.0, axis_bits);
  const double extent = static_cast<double>(hi) - static_cast<double>(lo);
  out_lo = lo;
  scale = (extent > 0.0 && std::isfinite(extent)) ? cells / extent : 0.0;
  max_cell = cells - 1.0;
}

/// The cell of a coordinate on an axis's grid; NaN and cells <= 0 go to 0.
VISCD_HD inline std::uint32_t quantize(float v, double lo, double scale, double max_cell) {
  const double q = (static_cast<double>(v) - lo) * scale;
  if (!(q > 0.0)) return 0;  // also catches NaN
  return q >= max_cell ? static_cast<std::uint32_t>(max_cell) : static_cast<std::uint32_t>(q);
}

}  // namespace viscd::detail::rule

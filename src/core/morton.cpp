#include "core/morton.hpp"

#include <algorithm>
#include <cmath>

#include "viscd/assert.hpp"

namespace viscd::detail {
namespace {

// Fills `position` from the top bit of the code down; each bit goes to the axis whose current
// cell is the largest (extent / 2^bits already given), ties in `order`, skipping axes whose bits
// are used up. The used bits occupy the low sum(axis_bits) positions of the code.
//
// With equal extents (the plain layout passes {1, 1, 1}) this is the classic round robin in
// `order`. For a flat world it keeps the flat axis's few bits for the levels where the other
// axes' cells have become as thin as it is, so cells stay near cubic all the way down instead of
// slicing the flat axis at the root (as a plain round robin would; docs/architecture.md,
// "Morton layout", has the measurement).
void assign_positions(MortonLayout& l, std::array<double, 3> cell) {
  const int total = l.axis_bits[0] + l.axis_bits[1] + l.axis_bits[2];
  VISCD_ASSERT(total <= l.bits, "layout uses more bits than the code has");
  std::array<int, 3> left = l.axis_bits;
  for (int pos = total - 1; pos >= 0; --pos) {
    int pick = -1;
    for (std::uint8_t axis : l.order)
      if (left[axis] > 0 && (pick < 0 || cell[axis] > cell[pick])) pick = axis;
    --left[pick];
    l.position[pick][left[pick]] = static_cast<std::int8_t>(pos);
    cell[pick] *= 0.5;
  }
}

}  // namespace

MortonLayoutInfo MortonLayout::info() const {
  MortonLayoutInfo i;
  for (int k = 0; k < 3; ++k) {
    i.order[k] = order[k];
    i.axis_bits[k] = static_cast<std::uint8_t>(axis_bits[k]);
  }
  return i;
}

MortonLayout extended_layout(int bits, const Aabb& b, float mean_diameter) {
  MortonLayout l;
  l.bits = bits;
  const std::array<float, 3> extent = {std::max(0.f, b.hi.x - b.lo.x), std::max(0.f, b.hi.y - b.lo.y),
                                       std::max(0.f, b.hi.z - b.lo.z)};
  std::array<std::uint8_t, 3> order{0, 1, 2};
  // Stable insertion sort by extent, largest first (std::stable_sort would allocate a buffer).
  for (int i = 1; i < 3; ++i)
    for (int k = i; k > 0 && extent[order[k]] > extent[order[k - 1]]; --k) std::swap(order[k], order[k - 1]);
  l.order = order;

  // Bits finer than an object are wasted on the flattest axis.
  int cap = 1;
  const double ratio = static_cast<double>(extent[order[2]]) / static_cast<double>(mean_diameter);
  if (ratio > 1.0) {  // log2 <= 0 (and NaN from 0/0) leave cap at 1; an infinite ratio caps at m/3
    cap = std::isinf(ratio) ? bits : std::max(1, static_cast<int>(std::ceil(std::log2(ratio))));
  }
  const int smallest = std::min(cap, bits / 3);
  const int rest = bits - smallest;
  l.axis_bits[order[0]] = rest - rest / 2;
  l.axis_bits[order[1]] = rest / 2;
  l.axis_bits[order[2]] = smallest;
  assign_positions(l, {extent[0], extent[1], extent[2]});
  return l;
}

MortonLayout plain_layout(int bits) {
  MortonLayout l;
  l.bits = bits;
  l.axis_bits = {bits / 3, bits / 3, bits / 3};
  l.order = {0, 1, 2};
  assign_positions(l, {1.0, 1.0, 1.0});
  return l;
}

MortonLayout make_layout(Layout kind, int bits, const Aabb& centre_bounds, float mean_diameter) {
  return kind == Layout::plain ? plain_layout(bits) : extended_layout(bits, centre_bounds, mean_diameter);
}

int bits_for_mean_pixels(double mu, float a, float b) {
  if (mu < a) return 16;
  if (mu < b) return 32;
  return 64;
}

MortonGrid morton_grid(const MortonLayout& layout, const Aabb& bounds) {
  const std::array<float, 3> lo = {bounds.lo.x, bounds.lo.y, bounds.lo.z};
  const std::array<float, 3> hi = {bounds.hi.x, bounds.hi.y, bounds.hi.z};
  MortonGrid g;
  for (int axis = 0; axis < 3; ++axis) {
    const int nb = layout.axis_bits[axis];
    VISCD_ASSERT(nb >= 0 && nb <= 32, "an axis has more than 32 bits");
    const double cells = std::ldexp(1.0, nb);
    const double extent = static_cast<double>(hi[axis]) - static_cast<double>(lo[axis]);
    g.lo[axis] = lo[axis];
    g.scale[axis] = (extent > 0.0 && std::isfinite(extent)) ? cells / extent : 0.0;
    g.max_cell[axis] = cells - 1.0;
  }
  return g;
}

int choose_bits(const Config& config, bool has_camera, double mu, std::size_t objects) {
  if (config.bits != Bits::adaptive) return static_cast<int>(config.bits);
  if (!has_camera) return 32;
  const int m = bits_for_mean_pixels(mu, config.pixels_for_32_bits, config.pixels_for_64_bits);
  return m == 16 && objects > kMostObjectsFor16Bits ? 32 : m;
}

MortonEncoder::MortonEncoder(const MortonLayout& layout, const Aabb& bounds) {
  const MortonGrid g = morton_grid(layout, bounds);
  lo_ = g.lo;
  scale_ = g.scale;
  max_cell_ = g.max_cell;
  int most = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const int nb = layout.axis_bits[axis];
    most = std::max(most, nb);
    // Bytes at or above an axis's bits stay zero (table_ starts zeroed): quantize() never sets them.
    for (int byte = 0; byte < 4 && 8 * byte < nb; ++byte) {
      for (int v = 0; v < 256; ++v) {
        std::uint64_t code = 0;
        for (int bit = 0; bit < 8; ++bit) {
          const int axis_bit = 8 * byte + bit;
          if (axis_bit < nb && ((v >> bit) & 1)) code |= std::uint64_t{1} << layout.position[axis][axis_bit];
        }
        table_[axis][byte][v] = code;
      }
    }
  }
  two_bytes_ = most <= 16;
}

}  // namespace viscd::detail

namespace viscd {

std::string format_layout(const MortonLayoutInfo& layout, bool ascii) {
  static constexpr char kAxisNames[] = "xyz";
  std::string s;
  for (int k = 0; k < 3; ++k) {
    const int axis = layout.order[k];
    if (axis > 2 || layout.axis_bits[axis] == 0) continue;
    if (!s.empty()) s += ascii ? "->" : "→";
    s += kAxisNames[axis];
    s += '(';
    s += std::to_string(layout.axis_bits[axis]);
    s += ')';
  }
  return s;
}

}  // namespace viscd

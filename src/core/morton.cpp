#include "core/morton.hpp"

#include <algorithm>
#include <cmath>

#include "core/morton_rule.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {
namespace {

// The shared rule's plain layout as the host's MortonLayout.
MortonLayout from_rule(const rule::Layout& r) {
  MortonLayout l;
  l.bits = r.bits;
  for (int a = 0; a < 3; ++a) {
    const auto axis = static_cast<std::size_t>(a);
    l.axis_bits[axis] = r.axis_bits[a];
    l.order[axis] = r.order[a];
    for (std::size_t b = 0; b < 32; ++b) l.position[axis][b] = r.position[a][b];
  }
  VISCD_ASSERT(l.axis_bits[0] + l.axis_bits[1] + l.axis_bits[2] <= l.bits, "layout uses more bits than the code has");
  return l;
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
  const float extent[3] = {std::max(0.f, b.hi.x - b.lo.x), std::max(0.f, b.hi.y - b.lo.y),
                           std::max(0.f, b.hi.z - b.lo.z)};
  return from_rule(rule::extended_layout(bits, extent, mean_diameter));
}

MortonLayout plain_layout(int bits) { return from_rule(rule::plain_layout(bits)); }

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
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const int nb = layout.axis_bits[axis];
    VISCD_ASSERT(nb >= 0 && nb <= 32, "an axis has more than 32 bits");
    rule::axis_grid(nb, lo[axis], hi[axis], g.lo[axis], g.scale[axis], g.max_cell[axis]);
  }
  return g;
}

int choose_bits(const Config& config, bool has_camera, double mu, std::size_t objects) {
  if (config.bits != Bits::adaptive) return static_cast<int>(config.bits);
  if (!has_camera) return 32;
  const int m = bits_for_mean_pixels(mu, config.pixels_for_32_bits, config.pixels_for_64_bits);
  return m == 16 && objects > kMostObjectsFor16Bits ? 32 : m;
}

void MortonEncoder::reset(const MortonLayout& layout, const Aabb& bounds) {
  const MortonGrid g = morton_grid(layout, bounds);
  lo_ = g.lo;
  scale_ = g.scale;
  max_cell_ = g.max_cell;
  if (has_tables_ && table_bits_ == layout.axis_bits && table_position_ == layout.position) return;
  has_tables_ = true;
  table_bits_ = layout.axis_bits;
  table_position_ = layout.position;
  table_ = {};
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

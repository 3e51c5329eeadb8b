#pragma once
// Morton layouts (stage 4) and codes (stage 5); the layout rule is docs/architecture.md,
// "Morton layout".
//
// A layout says which axis supplies each bit of an m-bit code, most significant first. The
// extended layout (after Vinkler et al. 2017, "Extended Morton Codes", and the paper's Table 2)
// orders the axes by the extent of the active centres and gives the flattest axis no more bits
// than resolve an object there. The bits are then interleaved by largest cell: from the most
// significant bit down, each bit goes to the axis whose cell (extent / 2^bits given so far) is
// the largest (ties to the larger extent), skipping axes whose bits are used up. For the paper's
// flat world (x 200, z 180, y 6 wide) that yields
//   m = 16:  x(7)→z(6)→y(3)    code bits 15..0:  x z x z x z x z x z x y z x y y
// so y is split only once the x and z cells have become about as thin as the world is flat.
// With equal extents (and for the plain layout) the interleave is the classic round robin.
// Encoding quantises each axis to its bit count over the bounds of the active centres, then
// scatters the axis bits to their code positions with byte-wise lookup tables (4 bytes x 3 axes).

#include <array>
#include <cstdint>
#include <string>

#include "core/geometry.hpp"
#include "core/morton_rule.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"

namespace viscd::detail {

struct MortonLayout {
  int bits = 32;                               ///< m: code width, 16, 32 or 64
  std::array<int, 3> axis_bits{};              ///< bits given to x, y, z (sum <= bits)
  std::array<std::uint8_t, 3> order{0, 1, 2};  ///< axes, the one that gets the first (highest) bit first
  /// Code bit position (0 = least significant) of each axis bit, indexed [axis][bit of axis value].
  std::array<std::array<std::int8_t, 32>, 3> position{};

  /// The public summary (axis order and bits per axis) that FrameStats reports.
  [[nodiscard]] MortonLayoutInfo info() const;
};

/// The extended layout (docs/architecture.md, "Morton layout"): axes by extent (ties x, y, z); the
/// smallest gets min(cap, floor(m/3)) bits with cap = max(1, ceil(log2(extent_smallest /
/// mean_diameter))); the other two share the rest, the larger taking the extra bit. Bits are
/// interleaved by largest cell: each next bit, from the most significant down, goes to the axis
/// whose cell (extent / 2^bits given so far) is then the largest (ties to the larger extent),
/// skipping axes whose bits are used up.
[[nodiscard]] MortonLayout extended_layout(int bits, const Aabb& centre_bounds, float mean_diameter);
/// Plain interleaving x, y, z with floor(m/3) bits each: 5/5/5, 10/10/10, 21/21/21.
[[nodiscard]] MortonLayout plain_layout(int bits);
/// Layout by kind.
[[nodiscard]] MortonLayout make_layout(Layout kind, int bits, const Aabb& centre_bounds, float mean_diameter);

/// Eq. (1): m from mu and the thresholds.
[[nodiscard]] int bits_for_mean_pixels(double mu, float a, float b);

/// Above this many objects in the tree, adaptive m is at least 32: 16-bit codes leave 65 536
/// cells, and with more than two objects per cell on average the tree's leaves group objects
/// that share a cell in no spatial order, so the query grows faster than N (measured on the ring
/// scene without culling: 1.3x slower than 32 bits at 3 x 10^5 objects, 4.2x at 10^7;
/// docs/benchmarks.md, "Ten million objects").
inline constexpr std::size_t kMostObjectsFor16Bits = std::size_t{1} << 17;

/// The frame's m, the one rule every backend applies: Config::bits when fixed; else Eq. (1)
/// from mu, raised from 16 to 32 when more than kMostObjectsFor16Bits objects enter the tree
/// (`objects`: the active moving ones); a frame without a camera has no mu, and adaptive falls
/// back to the paper's 32 bits.
[[nodiscard]] int choose_bits(const Config& config, bool has_camera, double mu, std::size_t objects);

/// The quantisation grid of a layout over given bounds, per axis: a centre coordinate v goes to
/// cell q = (v - lo) * scale (in double), clamped to [0, max_cell] (NaN and q <= 0 to 0). Every
/// backend encodes with these numbers (the gl backend hands them to its shader), so codes are
/// equal bit for bit.
struct MortonGrid {
  std::array<double, 3> lo{}, scale{}, max_cell{};
};
[[nodiscard]] MortonGrid morton_grid(const MortonLayout& layout, const Aabb& bounds);

/// Encodes centres into codes of a layout, over given bounds.
class MortonEncoder {
 public:
  MortonEncoder() = default;  ///< encodes nothing until reset()
  MortonEncoder(const MortonLayout& layout, const Aabb& bounds) { reset(layout, bounds); }
  /// Encodes on `layout` over `bounds` from now on. The bit tables depend on the layout alone and
  /// are made again only when it differs from the last one (making them costs more than coding a
  /// few hundred centres: the small trees of a followed frame are built every frame).
  void reset(const MortonLayout& layout, const Aabb& bounds);
  /// Code of a centre; centres outside the bounds clamp to the border cells.
  [[nodiscard]] std::uint64_t encode(float x, float y, float z) const {
    return scatter(0, quantize(0, x)) | scatter(1, quantize(1, y)) | scatter(2, quantize(2, z));
  }

 private:
  [[nodiscard]] std::uint32_t quantize(int axis, float v) const {
    return rule::quantize(v, lo_[axis], scale_[axis], max_cell_[axis]);
  }
  [[nodiscard]] std::uint64_t scatter(int axis, std::uint32_t q) const {
    const auto& t = table_[axis];
    if (two_bytes_) return t[0][q & 0xFF] | t[1][(q >> 8) & 0xFF];  // every axis has at most 16 bits
    return t[0][q & 0xFF] | t[1][(q >> 8) & 0xFF] | t[2][(q >> 16) & 0xFF] | t[3][q >> 24];
  }

  std::array<double, 3> lo_{}, scale_{}, max_cell_{};  // morton_grid()
  std::array<std::array<std::array<std::uint64_t, 256>, 4>, 3> table_{};
  bool two_bytes_ = false;  // no axis has more than 16 bits: quantize() stays below 2^16
  bool has_tables_ = false;
  std::array<int, 3> table_bits_{};                              // the layout table_ was made for:
  std::array<std::array<std::int8_t, 32>, 3> table_position_{};  // its axis_bits and position
};

}  // namespace viscd::detail

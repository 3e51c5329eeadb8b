#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>
#include <vector>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"

namespace viscd::detail {
namespace {

// The paper's flat world: x extent >= z extent, y spread 6 mean diameters (in (4, 8]).
Aabb flat_world() { return Aabb{{-100, -3, -90}, {100, 3, 90}}; }

TEST(MortonLayout, ReproducesPaperTable2) {
  EXPECT_EQ(format_layout(extended_layout(16, flat_world(), 1.0f).info()), "x(7)→z(6)→y(3)");
  EXPECT_EQ(format_layout(extended_layout(32, flat_world(), 1.0f).info()), "x(15)→z(14)→y(3)");
  EXPECT_EQ(format_layout(extended_layout(64, flat_world(), 1.0f).info()), "x(31)→z(30)→y(3)");
}

TEST(MortonLayout, SmallestAxisCapFollowsDiameter) {
  // y spread = 4.0 diameters exactly: ceil(log2 4) = 2 bits.
  EXPECT_EQ(format_layout(extended_layout(32, Aabb{{0, 0, 0}, {100, 4, 50}}, 1.0f).info()), "x(15)→z(15)→y(2)");
  // Thinner than one object: 1 bit (the cap's floor).
  EXPECT_EQ(format_layout(extended_layout(32, Aabb{{0, 0, 0}, {100, 0.5f, 50}}, 1.0f).info()), "x(16)→z(15)→y(1)");
  // A cube: ceil(log2(1e6)) = 20 bits for the last axis; at 1e9 the m/3 = 21 cap applies.
  EXPECT_EQ(format_layout(extended_layout(64, Aabb{{0, 0, 0}, {1e6f, 1e6f, 1e6f}}, 1.0f).info()), "x(22)→y(22)→z(20)");
  EXPECT_EQ(format_layout(extended_layout(64, Aabb{{0, 0, 0}, {1e9f, 1e9f, 1e9f}}, 1.0f).info()), "x(22)→y(21)→z(21)");
  // Ties order x, y, z.
  EXPECT_EQ(format_layout(extended_layout(16, Aabb{{0, 0, 0}, {8, 8, 8}}, 1.0f).info()), "x(7)→y(6)→z(3)");
}

TEST(MortonLayout, DegenerateExtents) {
  // All centres equal: no extent anywhere, zero diameter (points).
  const MortonLayout l = extended_layout(16, Aabb{{1, 1, 1}, {1, 1, 1}}, 0.0f);
  EXPECT_EQ(l.axis_bits[0] + l.axis_bits[1] + l.axis_bits[2], 16);
  // Points spread over a line: infinite ratio caps the smallest axis at m/3.
  const MortonLayout p = extended_layout(64, Aabb{{0, 0, 0}, {5, 5, 5}}, 0.0f);
  for (int a = 0; a < 3; ++a) EXPECT_LE(p.axis_bits[a], 32);
  EXPECT_EQ(p.axis_bits[0] + p.axis_bits[1] + p.axis_bits[2], 64);
}

TEST(MortonLayout, PlainLayouts) {
  EXPECT_EQ(format_layout(plain_layout(16).info()), "x(5)→y(5)→z(5)");
  EXPECT_EQ(format_layout(plain_layout(32).info()), "x(10)→y(10)→z(10)");
  EXPECT_EQ(format_layout(plain_layout(64).info()), "x(21)→y(21)→z(21)");
}

TEST(MortonLayout, HandWorkedBitPositions16) {
  // x(7)→z(6)→y(3) over x 200, z 180, y 6 wide; each bit to the axis with the largest cell:
  // x 200 z 180 x 100 z 90 x 50 z 45 x 25 z 22.5 x 12.5 z 11.25 (cells x 6.25, y 6, z 5.6)
  // x 6.25 y 6 z 5.6 (z done) x 3.1 (x done) y 3 y 1.5, so code bits 15..0 are:
  const MortonLayout l = extended_layout(16, flat_world(), 1.0f);
  const char want[] = "xzxzxzxzxzxyzxyy";
  for (int pos = 15; pos >= 0; --pos) {
    int owner = -1;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < l.axis_bits[a]; ++b)
        if (l.position[a][b] == pos) owner = a;
    ASSERT_GE(owner, 0) << "bit " << pos << " unassigned";
    EXPECT_EQ("xyz"[owner], want[15 - pos]) << "bit " << pos;
  }
}

// Independent encoder: quantise, then emit bits one at a time, each from the axis whose cell is
// currently largest (equal extents for the plain layout), ties in the layout's order.
std::uint64_t naive_encode(const MortonLayout& l, const Aabb& b, float x, float y, float z, bool plain) {
  const double v[3] = {x, y, z}, lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
  std::uint64_t q[3];
  for (int a = 0; a < 3; ++a) {
    const double cells = std::ldexp(1.0, l.axis_bits[a]);
    const double e = hi[a] - lo[a];
    double c = e > 0 ? std::floor((v[a] - lo[a]) / e * cells) : 0;
    c = std::clamp(c, 0.0, cells - 1);
    q[a] = static_cast<std::uint64_t>(c);
  }
  std::uint64_t code = 0;
  int left[3] = {l.axis_bits[0], l.axis_bits[1], l.axis_bits[2]};
  double cell[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
  if (plain) cell[0] = cell[1] = cell[2] = 1;
  for (int remaining = left[0] + left[1] + left[2]; remaining > 0; --remaining) {
    int a = -1;
    for (int k = 0; k < 3; ++k) {
      const int c = l.order[k];
      if (left[c] > 0 && (a < 0 || cell[c] > cell[a])) a = c;
    }
    --left[a];
    cell[a] /= 2;
    code = (code << 1) | ((q[a] >> left[a]) & 1);
  }
  return code;
}

TEST(MortonEncoder, MatchesNaiveEncoder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-120, 120);
  for (int bits : {16, 32, 64}) {
    for (Layout kind : {Layout::extended, Layout::plain}) {
      const Aabb b = flat_world();
      const MortonLayout l = make_layout(kind, bits, b, 1.0f);
      const MortonEncoder enc(l, b);
      for (int k = 0; k < 2000; ++k) {
        const float x = u(rng), y = u(rng) / 30, z = u(rng);
        const std::uint64_t got = enc.encode(x, y, z), want = naive_encode(l, b, x, y, z, kind == Layout::plain);
        ASSERT_EQ(got, want) << "m=" << bits << " at (" << x << "," << y << "," << z << ")";
        if (bits < 64) {
          ASSERT_LT(got, std::uint64_t{1} << bits);
        }
      }
    }
  }
}

// One encoder reset again and again (as a tree's sort keeps it between builds): over other bounds
// with the same layout (tables kept), then with another layout (tables made again), then back;
// every code against the independent encoder.
TEST(MortonEncoder, ResetKeepsOrRemakesItsTables) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-120, 120);
  const Aabb wide = flat_world(), small{{-4, -1, -2}, {6, 1, 3}}, tall{{-2, -80, -2}, {2, 80, 2}};
  struct Step {
    Layout kind;
    int bits;
    Aabb layout_bounds, bounds;
  };
  // The plain layout does not depend on the bounds (its tables are kept over other bounds); the
  // extended one does, and the independent encoder orders its bits by the bounds it is given, so
  // those steps encode over the bounds their layout was made for.
  const Step steps[] = {
      {Layout::extended, 32, wide, wide},   {Layout::extended, 32, wide, wide}, {Layout::plain, 32, wide, wide},
      {Layout::plain, 32, wide, small},     {Layout::plain, 32, tall, tall},    {Layout::extended, 32, tall, tall},
      {Layout::extended, 16, small, small}, {Layout::plain, 64, small, wide},   {Layout::extended, 64, wide, wide},
      {Layout::extended, 32, wide, wide},
  };
  MortonEncoder enc;
  for (const Step& st : steps) {
    const MortonLayout l = make_layout(st.kind, st.bits, st.layout_bounds, 1.0f);
    enc.reset(l, st.bounds);
    for (int k = 0; k < 500; ++k) {
      const float x = u(rng), y = u(rng) / 3, z = u(rng);
      ASSERT_EQ(enc.encode(x, y, z), naive_encode(l, st.bounds, x, y, z, st.kind == Layout::plain))
          << "m=" << st.bits << " at (" << x << "," << y << "," << z << ")";
    }
  }
}

TEST(MortonEncoder, CornersAndZeroExtent) {
  const Aabb b = flat_world();
  const MortonLayout l = extended_layout(32, b, 1.0f);
  const MortonEncoder enc(l, b);
  EXPECT_EQ(enc.encode(-100, -3, -90), 0u);
  EXPECT_EQ(enc.encode(100, 3, 90), (std::uint64_t{1} << 32) - 1);  // top cell of every axis
  const MortonEncoder flat(extended_layout(32, Aabb{{0, 0, 0}, {0, 0, 0}}, 0), Aabb{{0, 0, 0}, {0, 0, 0}});
  EXPECT_EQ(flat.encode(0, 0, 0), 0u);
}

TEST(AdaptiveBits, Equation1Boundaries) {
  EXPECT_EQ(bits_for_mean_pixels(0.0, 100, 400), 16);
  EXPECT_EQ(bits_for_mean_pixels(99.999, 100, 400), 16);
  EXPECT_EQ(bits_for_mean_pixels(100.0, 100, 400), 32);
  EXPECT_EQ(bits_for_mean_pixels(399.99, 100, 400), 32);
  EXPECT_EQ(bits_for_mean_pixels(400.0, 100, 400), 64);
  EXPECT_EQ(bits_for_mean_pixels(1e9, 100, 400), 64);
}

// Beyond Eq. (1): 16 bits become 32 past 2^17 active objects; fixed widths and frames without a
// camera are untouched.
TEST(AdaptiveBits, SixteenBitsBecome32ForManyObjects) {
  const Config c;  // adaptive, a = 100, b = 400
  EXPECT_EQ(choose_bits(c, true, 5.0, 0), 16);
  EXPECT_EQ(choose_bits(c, true, 5.0, std::size_t{1} << 17), 16);
  EXPECT_EQ(choose_bits(c, true, 5.0, (std::size_t{1} << 17) + 1), 32);
  EXPECT_EQ(choose_bits(c, true, 150.0, std::size_t{1} << 20), 32);
  EXPECT_EQ(choose_bits(c, true, 500.0, std::size_t{1} << 20), 64);
  EXPECT_EQ(choose_bits(c, false, 0.0, std::size_t{1} << 20), 32);
  Config fixed = c;
  fixed.bits = Bits::b16;
  EXPECT_EQ(choose_bits(fixed, true, 5.0, std::size_t{1} << 20), 16);
}

// The map is left out for adaptive bits only where no map can change m: culling off, more than
// 2^17 objects, and fewer screen pixels than a per object (mu <= screen pixels / N < a).
TEST(AdaptiveBits, WhenTheMapCannotChangeM) {
  Camera cam;
  cam.width = 1000, cam.height = 1000;  // 10^6 screen pixels
  const std::size_t many = (std::size_t{1} << 17) + 1;
  std::vector<Sphere> spheres(many);
  FrameInput in;
  in.camera = &cam;
  Config c;
  c.culling = false;
  c.pixels_for_32_bits = 100;
  in.spheres = spheres;  // 131 073 objects: 10^6 < 100 x N
  EXPECT_FALSE(adaptive_bits_need_pixels(in, c));
  EXPECT_FALSE(renders_own_map(in, c));
  std::vector<Box> boxes(many);
  FrameInput box_in = in;
  box_in.spheres = {};
  box_in.boxes = boxes;
  EXPECT_FALSE(renders_own_map(box_in, c)) << "boxes count alike";
  in.spheres = std::span<const Sphere>(spheres).first(many - 1);  // 2^17: 16 bits stay possible
  EXPECT_TRUE(adaptive_bits_need_pixels(in, c));
  in.spheres = spheres;
  cam.width = 100 * static_cast<int>(many) / 1000 + 1;  // screen pixels >= a N: mu may reach a
  EXPECT_TRUE(adaptive_bits_need_pixels(in, c));
  cam.width = 1000;
  Config culling = c;
  culling.culling = true;
  EXPECT_TRUE(renders_own_map(in, culling));
  Config shade = c;
  shade.shade = true;
  EXPECT_TRUE(renders_own_map(in, shade));
  Config report = c;
  report.report_pixels = true;
  EXPECT_TRUE(renders_own_map(in, report));
  Config lower_a = c;
  lower_a.pixels_for_32_bits = 1;  // 10^6 screen pixels >= 1 x N
  EXPECT_TRUE(renders_own_map(in, lower_a));
}

}  // namespace
}  // namespace viscd::detail

// libFuzzer target: sequences of frames on a cpu detector that follows change
// (Config::follow_change) against one that rebuilds every frame and against an independent
// brute force: objects start and stop moving, jiggle inside the margin, jump, appear and vanish,
// change filters and never-culled flags; the static set changes; the caller's moved list is given
// or not.
//
// Checks (any failure aborts with a short message on stderr): both detectors succeed on every
// frame; their pairs, states and contact events are equal; the pairs equal an O(N^2) loop of the
// exact tests (and the static pairs) over the objects, filters applied; a moved list that
// FrameInput::moved rules refuse fails on both; a frame with an invalid object (a NaN: the
// follower checks only the objects that changed) fails on both with the same message, and the
// frames after it are checked as any other.
//
// Input format, read front to back; reads past the end give zero bytes:
//   flags   bit 0 boxes; bit 1 a margin (the next byte / 64 world units); bit 2 the moved list is
//           given; bit 3 filters; bit 4 never-culled flags; bit 5 a static set of 6 objects; bit 6
//           two threads
//   count   N = byte % 40 + 1 objects, each 3 bytes on a grid of unit 1/4 (x, y, z), radius from the
//           third byte's top bits
//   ops     until the input ends, a byte each: bits 0-2 what, the rest (and a following byte) whom:
//           0 a frame (with bits 6-7 set: a frame in which object k is NaN, then k as it was); 1 move object k by a
//           grid step; 2 jiggle object k by a 1/64 step; 3 jump object k anywhere; 4 N changes (grows or shrinks by up
//           to 8); 5 object k's filter; 6 object k's never-culled flag; 7 a static object moves

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "viscd/detector.hpp"

namespace {

using namespace viscd;

constexpr const char* kTarget = "fuzz_sequence";

struct Reader {
  const std::uint8_t* data;
  std::size_t size, at = 0;
  std::uint8_t byte() { return at < size ? data[at++] : 0; }
  [[nodiscard]] bool done() const { return at >= size; }
};

Sphere grid_sphere(std::uint8_t a, std::uint8_t b, std::uint8_t c) {
  const float u = 0.25f;
  return Sphere{static_cast<float>(a % 32) * u, static_cast<float>(b % 8) * u, static_cast<float>(c % 32) * u,
                static_cast<float>(c >> 5) * u * 0.5f};
}

Box box_of(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

std::vector<Pair> oracle(const std::vector<Sphere>& s, bool boxes, const std::vector<Filter>& filters,
                         const std::vector<Sphere>& st) {
  auto f = [&](std::size_t k) { return filters.empty() ? Filter{} : filters[k]; };
  std::vector<Pair> out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (std::size_t j = i + 1; j < s.size(); ++j) {
      const bool hit = boxes ? boxes_overlap(box_of(s[i]), box_of(s[j])) : spheres_overlap(s[i], s[j]);
      if (hit && pair_passes_filter(f(i), f(j)))
        out.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
    }
    for (std::size_t k = 0; k < st.size(); ++k) {
      const bool hit = boxes ? boxes_overlap(box_of(s[i]), box_of(st[k])) : spheres_overlap(s[i], st[k]);
      if (hit && pair_passes_filter(f(i), Filter{}))
        out.push_back({static_cast<std::uint32_t>(i), static_index(static_cast<std::uint32_t>(k))});
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader in{data, size};
  const std::uint8_t flags = in.byte();
  const bool boxes = flags & 1, listed = flags & 4, filtered = flags & 8, never = flags & 16, with_static = flags & 32;
  Config on;
  on.follow_change = true;
  on.contact_events = true;
  on.threads = (flags & 64) ? 2 : 1;
  if (flags & 2) on.rest_margin = static_cast<float>(in.byte()) / 64.0f;
  on.move_margin = static_cast<float>(in.byte() % 17);  // 0 (none) to 16 moves
  Config off = on;
  off.follow_change = false;
  auto a = make_cpu_detector(on);
  auto b = make_cpu_detector(off);

  std::vector<Sphere> s(in.byte() % 40 + 1);
  for (Sphere& x : s) {
    const std::uint8_t p = in.byte(), q = in.byte(), r = in.byte();
    x = grid_sphere(p, q, r);
  }
  std::vector<Filter> filters;
  if (filtered) filters.assign(s.size(), Filter{});
  std::vector<std::uint8_t> always;
  if (never) always.assign(s.size(), 0);
  std::vector<Sphere> st;
  if (with_static) {
    for (std::uint32_t k = 0; k < 6; ++k) {
      st.push_back(grid_sphere(static_cast<std::uint8_t>(k * 5), static_cast<std::uint8_t>(k),
                               static_cast<std::uint8_t>(k * 7 + 64)));
      const bool ok = boxes ? a->add_static_box(box_of(st.back())).ok() && b->add_static_box(box_of(st.back())).ok()
                            : a->add_static_sphere(st.back()).ok() && b->add_static_sphere(st.back()).ok();
      if (!ok) viscd::fuzz::fail(kTarget, "adding a static object failed");
    }
  }

  std::vector<std::uint32_t> moved;
  bool resized = false;
  FrameResult fa, fb;
  auto frame = [&](const std::size_t* poison = nullptr) {
    const Sphere kept = poison ? s[*poison] : Sphere{};
    if (poison) {
      s[*poison].y = std::numeric_limits<float>::quiet_NaN();
      moved.push_back(static_cast<std::uint32_t>(*poison));
    }
    std::vector<Box> bx;
    if (boxes)
      for (const Sphere& x : s) bx.push_back(box_of(x));
    FrameInput fi;
    if (boxes)
      fi.boxes = bx;
    else
      fi.spheres = s;
    fi.filters = filters;
    fi.always_active = always;
    std::sort(moved.begin(), moved.end());
    moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
    if (listed && !resized) {
      fi.moved = moved;
      fi.moved_listed = true;
    }
    const Status sa = a->detect(fi, fa);
    fi.moved = {};
    fi.moved_listed = false;
    const Status sb = b->detect(fi, fb);
    if (poison) {
      s[*poison] = kept;  // the moved list keeps it: it changed since the last frame that ran
      if (sa.ok() || sb.ok()) viscd::fuzz::fail(kTarget, "a frame with a NaN object succeeded");
      if (sa.error() != sb.error())
        viscd::fuzz::fail(kTarget, "the NaN's messages differ", sa.error() + " | " + sb.error());
      return;
    }
    if (!sa.ok() || !sb.ok()) viscd::fuzz::fail(kTarget, "a frame failed", sa.ok() ? sb.error() : sa.error());
    if (fa.pairs != fb.pairs) viscd::fuzz::fail(kTarget, "pairs differ from the rebuilding detector's");
    if (fa.state != fb.state) viscd::fuzz::fail(kTarget, "states differ");
    if (fa.began != fb.began || fa.ended != fb.ended) viscd::fuzz::fail(kTarget, "contact events differ");
    if (fa.pairs != oracle(s, boxes, filters, st)) viscd::fuzz::fail(kTarget, "pairs differ from brute force");
    moved.clear();
    resized = false;
  };
  frame();
  while (!in.done()) {
    const std::uint8_t op = in.byte();
    const std::size_t k = (static_cast<std::size_t>(op >> 3) | (static_cast<std::size_t>(in.byte()) << 5)) % s.size();
    auto touched = [&] { moved.push_back(static_cast<std::uint32_t>(k)); };
    switch (op & 7) {
      case 0:
        if ((op >> 6) == 3)
          frame(&k);
        else
          frame();
        break;
      case 1:
        s[k].x += 0.25f * static_cast<float>(static_cast<int>(op >> 6) - 1);
        touched();
        break;
      case 2:
        s[k].z += 1.0f / 64.0f * static_cast<float>(static_cast<int>(op >> 6) - 2);
        touched();
        break;
      case 3: {
        const std::uint8_t p = in.byte(), q = in.byte(), r = in.byte();
        s[k] = grid_sphere(p, q, r);
        touched();
        break;
      }
      case 4: {
        const std::size_t n = std::clamp<std::size_t>(s.size() + (op >> 6) * 3 - 4, 1, 48);
        const std::size_t old = s.size();
        s.resize(n);
        for (std::size_t t = old; t < n; ++t)
          s[t] = grid_sphere(static_cast<std::uint8_t>(t * 3), 1, static_cast<std::uint8_t>(t * 11));
        if (filtered) filters.resize(n, Filter{});
        if (never) always.resize(n, 0);
        resized = true;
        break;
      }
      case 5:
        if (filtered) filters[k] = Filter{1u + (op >> 6), (op & 0x40) ? 0x3u : 0xFFFFFFFFu};
        break;
      case 6:
        if (never) always[k] ^= 1;
        break;
      default:
        if (with_static) {
          const std::uint32_t slot = static_cast<std::uint32_t>(k % st.size());
          st[slot].y += 0.25f;
          const bool ok =
              boxes ? a->move_static_box(slot, box_of(st[slot])).ok() && b->move_static_box(slot, box_of(st[slot])).ok()
                    : a->move_static_sphere(slot, st[slot]).ok() && b->move_static_sphere(slot, st[slot]).ok();
          if (!ok) viscd::fuzz::fail(kTarget, "moving a static object failed");
        }
        break;
    }
  }
  frame();
  return 0;
}

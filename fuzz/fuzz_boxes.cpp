// libFuzzer target: frames of boxes with a static set, on the cpu backend against the reference
// backend and against an independent brute force; up to 48 moving and 48 static boxes decoded
// from the input, then a few static-set changes and a second frame on the same detectors.
//
// Checks (any failure aborts with a short message on stderr):
// - cpu and reference accept and refuse the same boxes and static changes, never without a
//   message; a box with a non-finite bound, a magnitude beyond kMaxCoordinate or min > max is
//   always refused;
// - on success both frames' pairs are sorted, unique, equal between the backends and equal to a
//   loop over the moving boxes and the slot model of the static set written here: the moving
//   pairs, then each moving box with each static box it meets as {i, static_index(k)}, never
//   two static boxes; the object states follow the pairs;
// - queries (a box from the input) give the same objects on both backends.
//
// Input, front to back (reads past the end give zero bytes): a byte n_moving % 49, a byte
// n_static % 49, then boxes of 7 bytes: an encoding byte (0-5 grid: min = o + (b % 16 - 8) u per
// axis, size = (b % 5) u / 2 per axis, so faces, edges and corners touch; 6 raw floats: 24 bytes
// follow as six floats; 7 grid with min and max swapped on an axis), and after them up to 8
// changes of 3 bytes (op % 3: remove, move, add; a slot byte; a box from the grid).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "viscd/detector.hpp"

namespace {

using viscd::Box;
using viscd::Pair;

[[noreturn]] void fail(const char* what, std::string_view detail = {}) {
  viscd::fuzz::fail("fuzz_boxes", what, detail);
}

struct Reader {
  const std::uint8_t* data;
  std::size_t size, at = 0;
  std::uint8_t byte() { return at < size ? data[at++] : 0; }
  float raw() {
    std::uint8_t b[4] = {byte(), byte(), byte(), byte()};
    float f = 0;
    std::memcpy(&f, b, 4);
    return f;
  }
  Box grid() {
    Box x;
    for (int k = 0; k < 3; ++k) {
      const std::uint8_t b = byte();
      x.min[k] = static_cast<float>(b % 16) - 8.0f;
      x.max[k] = x.min[k] + static_cast<float>((b / 16) % 5) * 0.5f;
    }
    return x;
  }
  Box box() {
    const std::uint8_t e = byte() % 8;
    if (e == 6) {
      Box x;
      for (float& v : x.min) v = raw();
      for (float& v : x.max) v = raw();
      return x;
    }
    Box x = grid();
    if (e == 7) std::swap(x.min[1], x.max[1]);
    return x;
  }
};

bool meets(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!(a.min[k] <= b.max[k] && b.min[k] <= a.max[k])) return false;
  return true;
}

bool valid(const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(b.min[k]) || !std::isfinite(b.max[k]) || std::fabs(b.min[k]) > viscd::kMaxCoordinate ||
        std::fabs(b.max[k]) > viscd::kMaxCoordinate || !(b.min[k] <= b.max[k]))
      return false;
  return true;
}

std::vector<Pair> oracle(const std::vector<Box>& moving, const std::map<std::uint32_t, Box>& statics) {
  std::vector<Pair> out;
  for (std::uint32_t i = 0; i < moving.size(); ++i) {
    for (std::uint32_t j = i + 1; j < moving.size(); ++j)
      if (meets(moving[i], moving[j])) out.push_back({i, j});
    for (const auto& [k, b] : statics)
      if (meets(moving[i], b)) out.push_back({i, viscd::static_index(k)});
  }
  std::sort(out.begin(), out.end());
  return out;
}

void same_status(const viscd::Status& a, const viscd::Status& b, const char* what) {
  if (a.ok() != b.ok()) fail(what, a.ok() ? b.error() : a.error());
  if (!a.ok() && (a.error().empty() || b.error().empty())) fail("a refusal without a message", what);
}

void frame(viscd::Detector& cpu, viscd::Detector& ref, const std::vector<Box>& moving,
           const std::map<std::uint32_t, Box>& statics, bool moving_valid, Reader& in) {
  viscd::FrameInput input;
  input.boxes = moving;
  viscd::FrameResult a, b;
  const viscd::Status sa = cpu.detect(input, a), sb = ref.detect(input, b);
  same_status(sa, sb, "cpu and reference disagree on a frame");
  if (sa.ok() != moving_valid) fail(moving_valid ? "valid boxes refused" : "invalid boxes accepted", sa.error());
  if (!sa.ok()) return;
  const std::vector<Pair> want = oracle(moving, statics);
  if (a.pairs != want) fail("cpu pairs differ from the brute force");
  if (b.pairs != want) fail("reference pairs differ from the brute force");
  if (a.state != b.state) fail("object states differ");
  for (const Pair& p : want)
    if (a.state[p.i] != viscd::ObjectState::colliding) fail("an object in a pair is not colliding");
  const Box q = in.grid();
  std::vector<std::uint32_t> qa, qb;
  cpu.overlap_box(q, qa);
  ref.overlap_box(q, qb);
  if (qa != qb) fail("box queries differ");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader in{data, size};
  const std::size_t n_moving = in.byte() % 49, n_static = in.byte() % 49;
  std::vector<Box> moving(n_moving), statics(n_static);
  for (Box& b : moving) b = in.box();
  for (Box& b : statics) b = in.box();
  auto cpu = viscd::make_cpu_detector(), ref = viscd::make_reference_detector();
  const bool statics_valid = std::all_of(statics.begin(), statics.end(), valid);
  const viscd::Status sc = cpu->set_static_boxes(statics), sr = ref->set_static_boxes(statics);
  same_status(sc, sr, "cpu and reference disagree on a static set");
  if (sc.ok() != statics_valid) fail(statics_valid ? "a valid static set refused" : "an invalid static set accepted");
  std::map<std::uint32_t, Box> model;
  if (sc.ok())
    for (std::uint32_t k = 0; k < statics.size(); ++k) model[k] = statics[k];
  const bool moving_valid = std::all_of(moving.begin(), moving.end(), valid);
  frame(*cpu, *ref, moving, model, moving_valid, in);
  for (int c = 0; c < 8 && in.at < in.size; ++c) {
    const int op = in.byte() % 3;
    const std::uint32_t slot = in.byte() % 64;
    const Box b = in.grid();
    if (op == 0) {
      const viscd::Status x = cpu->remove_static(slot), y = ref->remove_static(slot);
      same_status(x, y, "remove_static");
      if (x.ok() != (model.count(slot) == 1)) fail("remove_static of a slot the model disagrees on");
      model.erase(slot);
    } else if (op == 1) {
      const viscd::Status x = cpu->move_static_box(slot, b), y = ref->move_static_box(slot, b);
      same_status(x, y, "move_static_box");
      if (x.ok() != (model.count(slot) == 1)) fail("move_static_box of a slot the model disagrees on");
      if (x.ok()) model[slot] = b;
    } else {
      const auto x = cpu->add_static_box(b), y = ref->add_static_box(b);
      same_status(x.status(), y.status(), "add_static_box");
      if (!x.ok()) fail("a valid box refused by add_static_box", x.error());
      if (x.value() != y.value()) fail("add_static_box gave different slots");
      std::uint32_t want = 0;
      while (model.count(want)) ++want;
      if (x.value() != want) fail("add_static_box did not take the smallest free slot");
      model[x.value()] = b;
    }
  }
  frame(*cpu, *ref, moving, model, moving_valid, in);
  return 0;
}

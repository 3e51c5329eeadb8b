// Conformance, frames that follow change: sequences where a few objects move each frame (the rest
// keep their bounds bit for bit), some jump across the world, N grows and shrinks, and the caller
// names the movers (FrameInput::moved) or not. Every backend must give the oracle's frame each
// time (the cpu backend follows change there; the others check the list and rebuild), and refuse a
// list that is out of range, out of order or repeated, changing nothing.
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

TEST_P(ConformanceFrames, MovedListsAndRestingObjects) {
  std::vector<Sphere> s = random_cloud(400, 21, 7.0f, 0.2f, 0.6f);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> u(-7, 7), step(-0.3f, 0.3f);
  FrameResult f;
  const Config c = detector_->config();
  for (int frame = 0; frame < 14; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    std::vector<std::uint32_t> moved;
    bool listed = frame % 3 != 2;
    if (frame == 9) {  // N shrinks, then grows: new objects need no listing
      s.resize(350);
      listed = false;
    } else if (frame == 11) {
      for (int k = 0; k < 30; ++k) s.push_back(Sphere{u(rng), u(rng), u(rng), 0.4f});
      listed = false;
    } else if (frame > 0) {
      for (std::uint32_t k = static_cast<std::uint32_t>(frame) % 7; k < s.size(); k += 23) {
        if (k % 5 == 0)
          s[k] = Sphere{u(rng), u(rng), u(rng), s[k].r};  // a jump
        else
          s[k].x += step(rng);
        moved.push_back(k);
      }
    }
    FrameInput in;
    in.spheres = s;
    in.moved = moved;
    in.moved_listed = listed;
    if (!listed) in.moved = {};
    const Status st = detector_->detect(in, f);
    ASSERT_TRUE(st.ok()) << st.error();
    check_frame(f, s, nullptr, c, expect_frame(s, nullptr, c, false));
  }

  // Bad lists fail alike on every backend, and the next frame is exact.
  const std::uint32_t beyond[] = {3, static_cast<std::uint32_t>(s.size())};
  const std::uint32_t unsorted[] = {9, 3};
  const std::uint32_t repeated[] = {3, 3};
  for (const std::span<const std::uint32_t> bad :
       {std::span<const std::uint32_t>(beyond), std::span<const std::uint32_t>(unsorted),
        std::span<const std::uint32_t>(repeated)}) {
    FrameInput in;
    in.spheres = s;
    in.moved = bad;
    in.moved_listed = true;
    const Status st = detector_->detect(in, f);
    EXPECT_FALSE(st.ok());
    EXPECT_EQ(st.kind(), ErrorKind::invalid_input) << st.error();
    EXPECT_NE(st.error().find("moved[1]"), std::string::npos) << st.error();
  }
  s[5].y += 1;
  FrameInput in;
  in.spheres = s;
  const std::uint32_t five[] = {5};
  in.moved = five;
  in.moved_listed = true;
  ASSERT_TRUE(detector_->detect(in, f).ok());
  check_frame(f, s, nullptr, c, expect_frame(s, nullptr, c, false));
}

}  // namespace
}  // namespace viscd::conformance

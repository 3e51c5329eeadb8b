// The public API's small parts: Status and Result kinds, the layout formatter, the stage accessor.

#include <gtest/gtest.h>

#include "viscd/viscd.hpp"

namespace viscd {
namespace {

TEST(Status, CarriesKindAndMessage) {
  const Status ok;
  EXPECT_TRUE(ok.ok());
  EXPECT_EQ(ok.kind(), ErrorKind::none);
  EXPECT_TRUE(ok.error().empty());
  const Status bad = Status::failure(ErrorKind::pair_cap, "too many pairs");
  EXPECT_FALSE(bad.ok());
  EXPECT_FALSE(static_cast<bool>(bad));
  EXPECT_EQ(bad.kind(), ErrorKind::pair_cap);
  EXPECT_EQ(bad.error(), "too many pairs");
  // A failure never reads as success, even when given the kind `none`.
  EXPECT_FALSE(Status::failure(ErrorKind::none, "x").ok());
}

TEST(Result, CarriesValueOrStatus) {
  const Result<int> v = 7;
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(v.value(), 7);
  EXPECT_EQ(v.kind(), ErrorKind::none);
  const auto f = Result<int>::failure(ErrorKind::io_failure, "cannot open");
  EXPECT_FALSE(f.ok());
  EXPECT_EQ(f.kind(), ErrorKind::io_failure);
  EXPECT_EQ(f.error(), "cannot open");
  const auto g = Result<int>::failure(f.status());
  EXPECT_EQ(g.kind(), ErrorKind::io_failure);
  EXPECT_EQ(g.error(), "cannot open");
}

TEST(ErrorKind, EveryKindHasAName) {
  for (ErrorKind k : {ErrorKind::none, ErrorKind::invalid_input, ErrorKind::unsupported_input, ErrorKind::pair_cap,
                      ErrorKind::out_of_memory, ErrorKind::backend_failure, ErrorKind::io_failure})
    EXPECT_NE(error_kind_name(k), "unknown");
  EXPECT_EQ(error_kind_name(ErrorKind::invalid_input), "invalid_input");
}

TEST(FormatLayout, PrintsTheTableTwoNotation) {
  EXPECT_EQ(format_layout(MortonLayoutInfo{.order = {0, 2, 1}, .axis_bits = {7, 3, 6}}), "x(7)→z(6)→y(3)");
  EXPECT_EQ(format_layout(MortonLayoutInfo{.order = {0, 2, 1}, .axis_bits = {31, 3, 30}}, true), "x(31)->z(30)->y(3)");
  // An axis without bits is left out; no bits at all is empty.
  EXPECT_EQ(format_layout(MortonLayoutInfo{.order = {1, 0, 2}, .axis_bits = {0, 16, 0}}), "y(16)");
  EXPECT_EQ(format_layout(MortonLayoutInfo{}), "");
  EXPECT_EQ((MortonLayoutInfo{.order = {0, 2, 1}, .axis_bits = {7, 3, 6}}).total_bits(), 16);
}

TEST(FrameStats, StageAccessorIsTheArray) {
  FrameStats s;
  s.ms(Stage::sort) = 1.5;
  s.ms(Stage::query) = 2.0;
  EXPECT_EQ(s.stage_ms[static_cast<std::size_t>(Stage::sort)], 1.5);
  EXPECT_EQ(static_cast<const FrameStats&>(s).ms(Stage::query), 2.0);
  EXPECT_EQ(s.total_ms(), 3.5);
}

TEST(Detector, ReportsItsBackendAndConfig) {
  Config c;
  c.lambda = 50;
  c.pixels_for_32_bits = 10;
  c.pixels_for_64_bits = 20;
  auto d = make_cpu_detector(c);
  EXPECT_EQ(d->name(), "cpu");
  EXPECT_EQ(d->config().pixels_for_64_bits, 20);
  c.keep_order = false;
  d->set_config(c);
  EXPECT_FALSE(d->config().keep_order);
  auto unknown = make_detector("vulkan");
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.kind(), ErrorKind::invalid_input);
}

}  // namespace
}  // namespace viscd

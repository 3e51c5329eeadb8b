// Tests of the box CSV reader (parse_box_table, read_box_table), the reader of either kind
// (read_object_table), the box writer and the static count in the stats JSON: the box format is
// the sphere CSV's with the six columns minx,miny,minz,maxx,maxy,maxz, and its messages are the
// same (docs/usage.md, "Boxes").
#include <gtest/gtest.h>

#include <array>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "file_test_util.hpp"
#include "viscd/detector.hpp"
#include "viscd/io.hpp"

namespace viscd {
namespace {

using test::TempDir;
using test::write_file;

void expect_box(const Box& b, std::array<float, 6> v) {
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(b.min[k], v[static_cast<std::size_t>(k)]) << "min " << k;
    EXPECT_EQ(b.max[k], v[static_cast<std::size_t>(k) + 3]) << "max " << k;
  }
}

std::string box_error(std::string_view text, std::string_view source = "b.csv") {
  auto r = parse_box_table(text, source);
  EXPECT_FALSE(r.ok()) << "expected an error for:\n" << text;
  return r.ok() ? std::string() : r.error();
}

constexpr const char* kHeader = "minx,miny,minz,maxx,maxy,maxz\n";

// ---------------------------------------------------------------------------------------------

TEST(BoxCsv, HeaderThenData) {
  auto r = parse_box_table("minx,miny,minz,maxx,maxy,maxz\n0,0,0,1,2,3\n-1.5,+2,-3e2,-1.5,2.5,1e18\n", "b.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().boxes.size(), 2u);
  expect_box(r.value().boxes[0], {0, 0, 0, 1, 2, 3});
  expect_box(r.value().boxes[1], {-1.5f, 2, -300, -1.5f, 2.5f, 1e18f});
  EXPECT_TRUE(r.value().filters.empty());
  EXPECT_TRUE(r.value().always_active.empty());
}

TEST(BoxCsv, SpacesCrlfBlankLinesAndByteOrderMark) {
  auto r = parse_box_table("\xEF\xBB\xBF minx , miny,minz ,maxx,maxy, maxz \r\n\r\n 1 , 2,3 ,4,5,6\r\n", "b.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().boxes.size(), 1u);
  expect_box(r.value().boxes[0], {1, 2, 3, 4, 5, 6});
}

TEST(BoxCsv, EmptyTextAndHeaderOnlyAreZeroBoxes) {
  for (const char* text : {"", "\n\n", kHeader}) {
    auto r = parse_box_table(text, "b.csv");
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_TRUE(r.value().boxes.empty());
  }
}

TEST(BoxCsv, FlatAndPointBoxesAreAllowed) {
  auto r = parse_box_table(std::string(kHeader) + "0,0,0,0,0,0\n1,2,3,1,5,6\n", "b.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().boxes.size(), 2u);
  expect_box(r.value().boxes[0], {0, 0, 0, 0, 0, 0});
}

TEST(BoxCsv, MissingOrWrongHeaderIsAnErrorAtItsLine) {
  for (const char* text : {"0,0,0,1,1,1\n", "minx,miny,minz,maxx,maxy\n0,0,0,1,1\n", "x0,y0,z0,x1,y1,z1\n",
                           "minx miny minz maxx maxy maxz\n", "maxx,maxy,maxz,minx,miny,minz\n",
                           "minx,miny,minz,maxx,maxy,maxz,extra\n", "minx,miny,minz,maxx,maxy,maxz,group\n"}) {
    const std::string e = box_error(text);
    EXPECT_CONTAINS(e, "b.csv:1: expected the header `minx,miny,minz,maxx,maxy,maxz` or") << text;
  }
  EXPECT_CONTAINS(box_error("\n\nfoo\n"), "b.csv:3: expected the header");
}

TEST(BoxCsv, ASphereFileIsCalledOne) {
  for (const char* text : {"x,y,z,r\n0,0,0,1\n", "x,y,z,r,group,mask\n"}) {
    const std::string e = box_error(text);
    EXPECT_CONTAINS(e, "b.csv:1: expected the header `minx,miny,minz,maxx,maxy,maxz`") << text;
    EXPECT_CONTAINS(e, "a sphere file, where boxes were expected") << text;
  }
  // And the other way round.
  auto s = parse_sphere_table(std::string(kHeader) + "0,0,0,1,1,1\n", "s.csv");
  ASSERT_FALSE(s.ok());
  EXPECT_CONTAINS(s.error(), "s.csv:1: expected the header `x,y,z,r`");
  EXPECT_CONTAINS(s.error(), "a box file, where spheres were expected");
}

TEST(BoxCsv, MissingOrExtraColumnsNameTheLine) {
  const std::string head = std::string(kHeader) + "0,0,0,1,1,1\n";
  EXPECT_CONTAINS(box_error(head + "0,0,0,1,1\n"),
                  "b.csv:3: expected 6 numbers `minx,miny,minz,maxx,maxy,maxz`, found 5 fields");
  EXPECT_CONTAINS(box_error(head + "0,0,0,1,1,1,\n"), "b.csv:3: expected 6 numbers");
  EXPECT_CONTAINS(box_error(head + "0\n"),
                  "b.csv:3: expected 6 numbers `minx,miny,minz,maxx,maxy,maxz`, found 1 field");
  // Blanks do not separate CSV fields.
  EXPECT_CONTAINS(box_error(head + "0 0 0 1 1 1\n"), "b.csv:3:");
  EXPECT_CONTAINS(box_error("minx,miny,minz,maxx,maxy,maxz,group,mask\n0,0,0,1,1,1,1\n"),
                  "b.csv:2: expected 8 fields `minx,miny,minz,maxx,maxy,maxz,group,mask`, found 7");
  EXPECT_CONTAINS(box_error("minx,miny,minz,maxx,maxy,maxz,always_active\n0,0,0,1,1,1\n"),
                  "b.csv:2: expected 7 fields `minx,miny,minz,maxx,maxy,maxz,always_active`, found 6");
}

TEST(BoxCsv, BadValuesNameTheLineTheColumnAndWhatWasExpected) {
  const std::string head = std::string(kHeader) + "0,0,0,1,1,1\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"nan,0,0,1,1,1", "b.csv:3: minx = nan is not finite (NaN and infinity are not allowed)"},
      {"0,inf,0,1,1,1", "b.csv:3: miny = inf is not finite"},
      {"0,0,-inf,1,1,1", "b.csv:3: minz = -inf is not finite"},
      {"0,0,0,NaN,1,1", "b.csv:3: maxx = NaN is not finite"},
      {"0,0,0,1,2e18,1", "b.csv:3: maxy = 2e18 exceeds the supported magnitude 1e18"},
      {"-1e19,0,0,1,1,1", "b.csv:3: minx = -1e19 exceeds the supported magnitude 1e18"},
      {"0,0,0,1,1,1e39", "b.csv:3: maxz = '1e39' is out of float range"},
      {"0,zero,0,1,1,1", "b.csv:3: miny: expected a number, found 'zero'"},
      {"0,0,,1,1,1", "b.csv:3: minz: expected a number, found ''"},
      {"0,0,0,1x,1,1", "b.csv:3: maxx: expected a number, found '1x'"},
      {"2,0,0,1,1,1", "b.csv:3: minx = 2 exceeds maxx = 1 (a box needs min <= max on every axis)"},
      {"0,5,0,1,-5,1", "b.csv:3: miny = 5 exceeds maxy = -5"},
      {"0,0,1.5,1,1,1.25", "b.csv:3: minz = 1.5 exceeds maxz = 1.25"},
  };
  for (const auto& [row, want] : cases) EXPECT_CONTAINS(box_error(head + row + "\n"), want) << row;
}

TEST(BoxCsv, FiltersAndAlwaysActiveAsForSpheres) {
  auto r = parse_box_table(
      "minx,miny,minz,maxx,maxy,maxz,group,mask,always_active\n"
      "0,0,0,1,1,1,1,4294967295,0\n"
      "2,2,2,3,3,3, 0x2 ,0X0000000F,1\n",
      "b.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().boxes.size(), 2u);
  ASSERT_EQ(r.value().filters.size(), 2u);
  EXPECT_EQ(r.value().filters[0].group, 1u);
  EXPECT_EQ(r.value().filters[0].mask, 0xFFFFFFFFu);
  EXPECT_EQ(r.value().filters[1].group, 2u);
  EXPECT_EQ(r.value().filters[1].mask, 15u);
  EXPECT_EQ(r.value().always_active, (std::vector<std::uint8_t>{0, 1}));
  expect_box(r.value().boxes[1], {2, 2, 2, 3, 3, 3});

  auto a = parse_box_table("minx,miny,minz,maxx,maxy,maxz,always_active\n0,0,0,1,1,1,1\n", "b.csv");
  ASSERT_TRUE(a.ok()) << a.error();
  EXPECT_TRUE(a.value().filters.empty());
  EXPECT_EQ(a.value().always_active, (std::vector<std::uint8_t>{1}));

  const std::string fh = "minx,miny,minz,maxx,maxy,maxz,group,mask\n";
  EXPECT_CONTAINS(box_error(fh + "0,0,0,1,1,1,-1,1\n"), "b.csv:2: group: expected an unsigned 32-bit integer");
  EXPECT_CONTAINS(box_error(fh + "0,0,0,1,1,1,1,0x100000000\n"), "b.csv:2: mask = 0x100000000 does not fit in 32 bits");
  EXPECT_CONTAINS(box_error("minx,miny,minz,maxx,maxy,maxz,always_active\n0,0,0,1,1,1,2\n"),
                  "b.csv:2: always_active: expected 0 or 1, found '2'");
}

TEST(BoxCsv, MessagesEscapeWhatTheyQuote) {
  const std::string e = box_error(std::string(kHeader) + "0,\x01\x1b[31m,0,1,1,1\n");
  EXPECT_CONTAINS(e, "b.csv:2: miny: expected a number, found '\\x01\\x1B[31m'");
}

TEST(BoxCsv, ParsedBoxesPassValidationAndRoundTripThroughTheWriter) {
  TempDir dir;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1e6f, 1e6f), side(0, 100);
  std::vector<Box> boxes(300);
  for (Box& b : boxes)
    for (int k = 0; k < 3; ++k) {
      b.min[k] = u(rng);
      b.max[k] = b.min[k] + side(rng);
    }
  boxes[0] = Box{{-1e18f, -1e18f, -1e18f}, {1e18f, 1e18f, 1e18f}};
  boxes[1] = Box{{1e-30f, 0, -0.0f}, {1e-30f, 0, 0}};
  ASSERT_TRUE(write_boxes_csv(dir / "b.csv", boxes).ok());
  auto r = read_box_table(dir / "b.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().boxes.size(), boxes.size());
  EXPECT_TRUE(validate_boxes(r.value().boxes).ok());
  for (std::size_t i = 0; i < boxes.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(std::bit_cast<std::uint32_t>(r.value().boxes[i].min[k]), std::bit_cast<std::uint32_t>(boxes[i].min[k]))
          << i;
      EXPECT_EQ(std::bit_cast<std::uint32_t>(r.value().boxes[i].max[k]), std::bit_cast<std::uint32_t>(boxes[i].max[k]))
          << i;
    }
}

TEST(ReadBoxTable, AnyExtensionIsCsvAndErrorsNameThePath) {
  TempDir dir;
  write_file(dir / "crates.txt", std::string(kHeader) + "0,0,0,1,1,1\n");
  auto r = read_box_table(dir / "crates.txt");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value().boxes.size(), 1u);
  write_file(dir / "bad.csv", std::string(kHeader) + "0,0,0,1,1,1\n1,1,1,0,1,1\n");
  auto bad = read_box_table(dir / "bad.csv");
  ASSERT_FALSE(bad.ok());
  EXPECT_CONTAINS(bad.error(), (dir / "bad.csv").string() + ":3: minx = 1 exceeds maxx = 0");
  auto missing = read_box_table(dir / "none.csv");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().kind(), ErrorKind::io_failure);
  EXPECT_CONTAINS(missing.error(), "none.csv");
  EXPECT_CONTAINS(missing.error(), "No such file or directory");
}

TEST(ReadObjectTable, TheFileTellsItsKindAndTheLineThatTellsIt) {
  TempDir dir;
  write_file(dir / "b.csv", std::string("\n") + kHeader + "0,0,0,1,1,1\n");
  write_file(dir / "b.txt", std::string(kHeader) + "0,0,0,1,1,1\n2,2,2,3,3,3\n");
  write_file(dir / "s.csv", "x,y,z,r,group,mask\n0,0,0,1,1,2\n");
  write_file(dir / "s.xyzr", "# rocks\n\n0 0 0 1\n5 5 5 1\n");
  write_file(dir / "empty.xyzr", "# nothing\n");
  write_file(dir / "header.csv", "x,y,z,r\n");
  struct Case {
    const char* name;
    ShapeKind kind;
    std::size_t count, line;
  };
  for (const Case& c : {Case{"b.csv", ShapeKind::box, 1, 2}, Case{"b.txt", ShapeKind::box, 2, 1},
                        Case{"s.csv", ShapeKind::sphere, 1, 1}, Case{"s.xyzr", ShapeKind::sphere, 2, 3},
                        Case{"empty.xyzr", ShapeKind::sphere, 0, 0}, Case{"header.csv", ShapeKind::sphere, 0, 1}}) {
    auto r = read_object_table(dir / c.name);
    ASSERT_TRUE(r.ok()) << c.name << ": " << r.error();
    EXPECT_EQ(r.value().kind, c.kind) << c.name;
    EXPECT_EQ(r.value().size(), c.count) << c.name;
    EXPECT_EQ(r.value().kind_line, c.line) << c.name;
  }
  auto s = read_object_table(dir / "s.csv");
  ASSERT_EQ(s.value().spheres.filters.size(), 1u);
  EXPECT_EQ(s.value().spheres.filters[0].mask, 2u);
  // A bad file of either kind is the reader's error.
  write_file(dir / "bad.csv", std::string(kHeader) + "0,0,0,1,1\n");
  auto bad = read_object_table(dir / "bad.csv");
  ASSERT_FALSE(bad.ok());
  EXPECT_CONTAINS(bad.error(), "bad.csv:2: expected 6 numbers");
}

TEST(StatsJsonStatic, NamesTheStaticCount) {
  FrameStats st;
  st.objects = 10;
  st.static_objects = 4;
  const auto j = nlohmann::json::parse(stats_json(st, "cpu"));
  EXPECT_EQ(j["objects"].get<std::uint32_t>(), 10u);
  EXPECT_EQ(j["static_objects"].get<std::uint32_t>(), 4u);
}

}  // namespace
}  // namespace viscd

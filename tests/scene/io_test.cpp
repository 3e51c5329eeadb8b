// Tests of the file formats the world sees (docs/usage.md, "File formats"): XYZR and CSV sphere
// readers, the camera JSON reader and writer, the pairs/spheres/stats writers and pairs_hash.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "file_test_util.hpp"
#include "viscd/detector.hpp"
#include "viscd/io.hpp"

namespace viscd {
namespace {

namespace fs = std::filesystem;
using test::read_file;
using test::TempDir;
using test::write_file;

bool bits_equal(const Sphere& a, const Sphere& b) {
  return std::bit_cast<std::uint32_t>(a.x) == std::bit_cast<std::uint32_t>(b.x) &&
         std::bit_cast<std::uint32_t>(a.y) == std::bit_cast<std::uint32_t>(b.y) &&
         std::bit_cast<std::uint32_t>(a.z) == std::bit_cast<std::uint32_t>(b.z) &&
         std::bit_cast<std::uint32_t>(a.r) == std::bit_cast<std::uint32_t>(b.r);
}

void expect_sphere(const Sphere& s, float x, float y, float z, float r) {
  EXPECT_EQ(s.x, x);
  EXPECT_EQ(s.y, y);
  EXPECT_EQ(s.z, z);
  EXPECT_EQ(s.r, r);
}

// Parses XYZR text that must fail and returns the error (fails the test if it parsed).
std::string xyzr_error(std::string_view text, std::string_view source = "in.xyzr") {
  auto r = parse_xyzr(text, source);
  EXPECT_FALSE(r.ok()) << "expected an error for:\n" << text;
  return r.ok() ? std::string() : r.error();
}

std::string csv_error(std::string_view text, std::string_view source = "in.csv") {
  auto r = parse_csv(text, source);
  EXPECT_FALSE(r.ok()) << "expected an error for:\n" << text;
  return r.ok() ? std::string() : r.error();
}

std::string camera_error(std::string_view text, std::string_view source = "cam.json") {
  auto r = parse_camera(text, source);
  EXPECT_FALSE(r.ok()) << "expected an error for:\n" << text;
  return r.ok() ? std::string() : r.error();
}

// ---------------------------------------------------------------------------------------------
// XYZR

TEST(Xyzr, ParsesBlankSeparatedLines) {
  auto r = parse_xyzr("1 2 3 4\n-1.5\t2.25   -3e2 0.5\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  expect_sphere(r.value()[1], -1.5f, 2.25f, -300.0f, 0.5f);
}

TEST(Xyzr, ParsesCommaSeparatedAndMixedSeparators) {
  auto r = parse_xyzr("1,2,3,4\n5, 6 ,7\t,8\n9 10,11 12\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 3u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  expect_sphere(r.value()[1], 5, 6, 7, 8);
  expect_sphere(r.value()[2], 9, 10, 11, 12);
}

TEST(Xyzr, CommentsAndBlankLinesAreIgnored) {
  const char* text =
      "# a whole-line comment\n"
      "\n"
      "   \t  \n"
      "1 2 3 0.5   # a trailing comment with numbers 9 9 9 9\n"
      "    # indented comment\n"
      "4 5 6 1.5#no space before the hash\n"
      "\n";
  auto r = parse_xyzr(text, "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[0], 1, 2, 3, 0.5f);
  expect_sphere(r.value()[1], 4, 5, 6, 1.5f);
}

TEST(Xyzr, CrlfLineEndings) {
  auto r = parse_xyzr("# header\r\n1 2 3 4\r\n\r\n5 6 7 8 # c\r\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  expect_sphere(r.value()[1], 5, 6, 7, 8);
}

TEST(Xyzr, CrlfErrorLineNumbersCountLines) {
  const std::string e = xyzr_error("1 2 3 4\r\n\r\n1 2 3\r\n", "f.xyzr");
  EXPECT_CONTAINS(e, "f.xyzr:3:");
}

TEST(Xyzr, LastLineWithoutNewline) {
  auto r = parse_xyzr("1 2 3 4\n5 6 7 8", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[1], 5, 6, 7, 8);
}

TEST(Xyzr, EmptyTextIsZeroSpheres) {
  for (const char* text : {"", "\n", "\n\n  \n", "# only a comment\n", "# c\r\n\r\n"}) {
    auto r = parse_xyzr(text, "s");
    ASSERT_TRUE(r.ok()) << "text '" << text << "': " << r.error();
    EXPECT_TRUE(r.value().empty()) << "text '" << text << "'";
  }
}

TEST(Xyzr, ZeroRadiusIsAPoint) {
  auto r = parse_xyzr("1 2 3 0\n4 5 6 0.0\n7 8 9 -0\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 3u);
  EXPECT_EQ(r.value()[0].r, 0.0f);
  EXPECT_EQ(r.value()[1].r, 0.0f);
  EXPECT_EQ(r.value()[2].r, 0.0f);
}

TEST(Xyzr, NumberForms) {
  auto r = parse_xyzr("+1 -2 .5 1.\n1e3 -1E-3 +2.5e+2 3\n1e18 -1e18 0 1e18\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 3u);
  expect_sphere(r.value()[0], 1, -2, 0.5f, 1);
  expect_sphere(r.value()[1], 1000, -1e-3f, 250, 3);
  expect_sphere(r.value()[2], 1e18f, -1e18f, 0, 1e18f);
}

TEST(Xyzr, ThreeFieldsIsAnErrorAtItsLine) {
  const std::string e = xyzr_error("# c\n1 2 3 4\n\n1 2 3\n5 6 7 8\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:4:");
  EXPECT_CONTAINS(e, "expected 4 numbers");
  EXPECT_CONTAINS(e, "found 3");
}

TEST(Xyzr, FiveFieldsIsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n1 2 3 4 5\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:2:");
  EXPECT_CONTAINS(e, "expected 4 numbers");
  EXPECT_CONTAINS(e, "found 5");
}

TEST(Xyzr, OneFieldIsAnError) {
  const std::string e = xyzr_error("7\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:1:");
  EXPECT_CONTAINS(e, "expected 4 numbers");
}

TEST(Xyzr, WordInsteadOfNumber) {
  const std::string e = xyzr_error("1 2 3 4\n1 two 3 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:2:");
  EXPECT_CONTAINS(e, "expected a number");
  EXPECT_CONTAINS(e, "'two'");
}

TEST(Xyzr, NumberWithTrailingGarbage) {
  const std::string e = xyzr_error("1 2 3x 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:1:");
  EXPECT_CONTAINS(e, "expected a number");
  EXPECT_CONTAINS(e, "3x");
}

TEST(Xyzr, LoneSignIsNotANumber) {
  const std::string e = xyzr_error("1 2 + 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:1:");
  EXPECT_CONTAINS(e, "expected a number");
}

TEST(Xyzr, NanIsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n\nnan 2 3 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:3:");
  EXPECT_CONTAINS(e, "not finite");
}

TEST(Xyzr, InfIsAnError) {
  const std::string e = xyzr_error("1 inf 3 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:1:");
  EXPECT_CONTAINS(e, "not finite");
}

TEST(Xyzr, MinusInfIsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n1 2 -inf 4\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:2:");
  EXPECT_CONTAINS(e, "not finite");
}

TEST(Xyzr, InfRadiusIsAnError) {
  const std::string e = xyzr_error("1 2 3 infinity\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:1:");
  EXPECT_CONTAINS(e, "not finite");
}

TEST(Xyzr, NegativeRadiusIsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n# c\n1 2 3 -0.5\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:3:");
  EXPECT_CONTAINS(e, "negative");
}

TEST(Xyzr, ValueBeyond1e18IsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n2e18 0 0 1\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:2:");
  EXPECT_CONTAINS(e, "1e18");
  const std::string e2 = xyzr_error("0 0 -5e18 1\n", "scene.xyzr");
  EXPECT_CONTAINS(e2, "scene.xyzr:1:");
  EXPECT_CONTAINS(e2, "1e18");
  const std::string e3 = xyzr_error("0 0 0 1e30\n", "scene.xyzr");
  EXPECT_CONTAINS(e3, "scene.xyzr:1:");
  EXPECT_CONTAINS(e3, "1e18");
}

TEST(Xyzr, FloatOverflowIsAnError) {
  const std::string e = xyzr_error("1 2 3 4\n1 2 3 4\n1e39 0 0 1\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:3:");
  EXPECT_CONTAINS(e, "out of float range");
  const std::string e2 = xyzr_error("0 -1e39 0 1\n", "scene.xyzr");
  EXPECT_CONTAINS(e2, "scene.xyzr:1:");
  EXPECT_CONTAINS(e2, "out of float range");
}

TEST(Xyzr, ErrorStopsAtFirstBadLine) {
  const std::string e = xyzr_error("1 2 3 4\nbad\n1 2 3\n", "scene.xyzr");
  EXPECT_CONTAINS(e, "scene.xyzr:2:");
  EXPECT_EQ(e.find("scene.xyzr:3:"), std::string::npos);
}

TEST(Xyzr, ErrorStartsWithSourceAndLine) {
  const std::string e = xyzr_error("1 2 3\n", "some/dir/file.xyzr");
  EXPECT_EQ(e.rfind("some/dir/file.xyzr:1: ", 0), 0u) << e;
}

TEST(Xyzr, ParsedSpheresPassValidation) {
  auto r = parse_xyzr("0 0 0 0\n1e18 -1e18 1e18 1e18\n-3 4 5 6\n", "s");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_TRUE(validate_spheres(r.value()).ok());
}

// ---------------------------------------------------------------------------------------------
// CSV

TEST(Csv, HeaderThenData) {
  auto r = parse_csv("x,y,z,r\n1,2,3,4\n-1.5,2.5,-3,0\n", "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  expect_sphere(r.value()[1], -1.5f, 2.5f, -3, 0);
}

TEST(Csv, SpacesAroundFieldsAndCrlf) {
  auto r = parse_csv(" x , y ,z, r \r\n 1 , 2,3 ,4\r\n\r\n5,6,7,8\r\n", "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  expect_sphere(r.value()[1], 5, 6, 7, 8);
}

TEST(Csv, HeaderOnlyIsZeroSpheres) {
  auto r = parse_csv("x,y,z,r\n", "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_TRUE(r.value().empty());
}

TEST(Csv, EmptyTextIsZeroSpheres) {
  auto r = parse_csv("", "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_TRUE(r.value().empty());
}

TEST(Csv, MissingHeaderIsAnErrorAtLine1) {
  const std::string e = csv_error("1,2,3,4\n5,6,7,8\n", "data.csv");
  EXPECT_CONTAINS(e, "data.csv:1:");
  EXPECT_CONTAINS(e, "header");
  EXPECT_CONTAINS(e, "x,y,z,r");
}

TEST(Csv, WrongHeaderIsAnErrorAtLine1) {
  for (const char* text : {"x,y,z,radius\n1,2,3,4\n", "x,y,z\n1,2,3\n", "r,x,y,z\n1,2,3,4\n", "x y z r\n1,2,3,4\n",
                           "x,y,z,r,w\n1,2,3,4,5\n"}) {
    const std::string e = csv_error(text, "data.csv");
    EXPECT_CONTAINS(e, "data.csv:1:") << text;
    EXPECT_CONTAINS(e, "header") << text;
  }
}

TEST(Csv, EmptyFieldIsAnError) {
  const std::string e = csv_error("x,y,z,r\n1,2,3,4\n1,,3,4\n", "data.csv");
  EXPECT_CONTAINS(e, "data.csv:3:");
  EXPECT_CONTAINS(e, "expected a number");
  const std::string e2 = csv_error("x,y,z,r\n1,2,3,\n", "data.csv");
  EXPECT_CONTAINS(e2, "data.csv:2:");
  EXPECT_CONTAINS(e2, "expected a number");
}

TEST(Csv, WrongFieldCountIsAnError) {
  const std::string e = csv_error("x,y,z,r\n1,2,3\n", "data.csv");
  EXPECT_CONTAINS(e, "data.csv:2:");
  EXPECT_CONTAINS(e, "expected 4 numbers");
  const std::string e2 = csv_error("x,y,z,r\n1,2,3,4,\n", "data.csv");
  EXPECT_CONTAINS(e2, "data.csv:2:");
  EXPECT_CONTAINS(e2, "expected 4 numbers");
  // Blanks do not separate CSV fields.
  const std::string e3 = csv_error("x,y,z,r\n1 2 3 4\n", "data.csv");
  EXPECT_CONTAINS(e3, "data.csv:2:");
}

TEST(Csv, BadValuesAreErrors) {
  EXPECT_CONTAINS(csv_error("x,y,z,r\nnan,0,0,1\n"), "in.csv:2:");
  EXPECT_CONTAINS(csv_error("x,y,z,r\n0,inf,0,1\n"), "not finite");
  EXPECT_CONTAINS(csv_error("x,y,z,r\n0,0,0,-1\n"), "negative");
  EXPECT_CONTAINS(csv_error("x,y,z,r\n0,0,1e39,1\n"), "out of float range");
  EXPECT_CONTAINS(csv_error("x,y,z,r\n0,0,3e18,1\n"), "1e18");
  EXPECT_CONTAINS(csv_error("x,y,z,r\n0,zero,0,1\n"), "expected a number");
}

// ---------------------------------------------------------------------------------------------
// CSV with group and mask columns

std::string table_error(std::string_view text, std::string_view source = "in.csv") {
  auto r = parse_sphere_table(text, source);
  EXPECT_FALSE(r.ok()) << "expected an error for:\n" << text;
  return r.ok() ? std::string() : r.error();
}

TEST(CsvFilters, DecimalAndHexValues) {
  auto r = parse_sphere_table(
      "x,y,z,r,group,mask\n"
      "1,2,3,4,1,4294967295\n"
      "0,0,0,0.5, 0x2 ,0X0000000F\n"
      "5,6,7,8,0,0\n"
      "9,9,9,1,0xFFFFFFFF,0x80000000\n",
      "f.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().spheres.size(), 4u);
  ASSERT_EQ(r.value().filters.size(), 4u);
  expect_sphere(r.value().spheres[1], 0, 0, 0, 0.5f);
  const std::vector<std::pair<std::uint32_t, std::uint32_t>> want = {
      {1, 0xFFFFFFFFu}, {2, 15}, {0, 0}, {0xFFFFFFFFu, 0x80000000u}};
  for (std::size_t k = 0; k < want.size(); ++k) {
    EXPECT_EQ(r.value().filters[k].group, want[k].first) << k;
    EXPECT_EQ(r.value().filters[k].mask, want[k].second) << k;
  }
}

TEST(CsvFilters, WithoutTheColumnsThereAreNoFilters) {
  auto r = parse_sphere_table("x,y,z,r\n1,2,3,4\n", "f.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value().spheres.size(), 1u);
  EXPECT_TRUE(r.value().filters.empty());
  auto h = parse_sphere_table("x,y,z,r,group,mask\n", "f.csv");
  ASSERT_TRUE(h.ok()) << h.error();
  EXPECT_TRUE(h.value().spheres.empty() && h.value().filters.empty());
}

TEST(CsvAlwaysActive, ColumnAfterTheSpheresOrTheFilters) {
  auto r = parse_sphere_table("x,y,z,r,always_active\n1,2,3,4,1\n5,6,7,8, 0 \n", "f.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().spheres.size(), 2u);
  EXPECT_TRUE(r.value().filters.empty());
  EXPECT_EQ(r.value().always_active, (std::vector<std::uint8_t>{1, 0}));
  expect_sphere(r.value().spheres[1], 5, 6, 7, 8);
  auto f = parse_sphere_table("x,y,z,r,group,mask,always_active\n1,2,3,4,2,0x3,0\n0,0,0,1,1,1,1\n", "f.csv");
  ASSERT_TRUE(f.ok()) << f.error();
  ASSERT_EQ(f.value().filters.size(), 2u);
  EXPECT_EQ(f.value().filters[0].group, 2u);
  EXPECT_EQ(f.value().filters[0].mask, 3u);
  EXPECT_EQ(f.value().always_active, (std::vector<std::uint8_t>{0, 1}));
  // Without the column there are no flags; the plain reader checks the column and drops it.
  auto none = parse_sphere_table("x,y,z,r\n1,2,3,4\n", "f.csv");
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(none.value().always_active.empty());
  auto plain = parse_csv("x,y,z,r,always_active\n1,2,3,4,1\n", "f.csv");
  ASSERT_TRUE(plain.ok()) << plain.error();
  EXPECT_EQ(plain.value().size(), 1u);
}

TEST(CsvAlwaysActive, BadValuesAndHeadersNameTheLine) {
  const char* head = "x,y,z,r,always_active\n0,0,0,1,1\n";
  for (const char* row : {"0,0,0,1,2", "0,0,0,1,-1", "0,0,0,1,yes", "0,0,0,1,", "0,0,0,1,0x1", "0,0,0,1,1.0"}) {
    const std::string e = table_error(std::string(head) + row + "\n", "f.csv");
    EXPECT_CONTAINS(e, "f.csv:3: always_active: expected 0 or 1") << row;
  }
  EXPECT_CONTAINS(table_error(std::string(head) + "0,0,0,1\n", "f.csv"), "f.csv:3: expected 5 fields");
  EXPECT_CONTAINS(table_error("x,y,z,r,group,mask,always_active\n0,0,0,1,1,1\n", "f.csv"),
                  "f.csv:2: expected 7 fields `x,y,z,r,group,mask,always_active`");
  // The column comes last, once.
  for (const char* text : {"x,y,z,r,always_active,group,mask\n", "x,y,z,r,always_active,always_active\n",
                           "x,y,z,always_active,r\n", "x,y,z,r,active\n"}) {
    const std::string e = table_error(text, "f.csv");
    EXPECT_CONTAINS(e, "f.csv:1: expected the header") << text;
    EXPECT_CONTAINS(e, "always_active") << text;
  }
}

TEST(CsvFilters, PlainReaderTakesTheSpheresOnly) {
  auto r = parse_csv("x,y,z,r,group,mask\n1,2,3,4,2,0x1\n", "f.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 1u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);
  // ... but still checks the columns.
  EXPECT_CONTAINS(csv_error("x,y,z,r,group,mask\n1,2,3,4,2,x\n", "f.csv"), "f.csv:2: mask");
}

TEST(CsvFilters, BadValuesNameTheLineAndWhatWasExpected) {
  const char* head = "x,y,z,r,group,mask\n0,0,0,1,1,1\n";
  for (const char* row : {"0,0,0,1,-1,1", "0,0,0,1,+1,1", "0,0,0,1,1.5,1", "0,0,0,1,one,1", "0,0,0,1,,1",
                          "0,0,0,1,0x,1", "0,0,0,1,0xG1,1", "0,0,0,1,1e3,1", "0,0,0,1,1 2,1"}) {
    const std::string e = table_error(std::string(head) + row + "\n", "f.csv");
    EXPECT_CONTAINS(e, "f.csv:3: group: expected an unsigned 32-bit integer") << row;
  }
  for (const char* row : {"0,0,0,1,1,4294967296", "0,0,0,1,1,0x100000000", "0,0,0,1,1,99999999999999999999999"}) {
    const std::string e = table_error(std::string(head) + row + "\n", "f.csv");
    EXPECT_CONTAINS(e, "f.csv:3: mask = ") << row;
    EXPECT_CONTAINS(e, "does not fit in 32 bits") << row;
  }
  EXPECT_CONTAINS(table_error(std::string(head) + "0,0,0,1,1\n", "f.csv"), "f.csv:3: expected 6 fields");
  EXPECT_CONTAINS(table_error(std::string(head) + "0,0,0,1,1,1,1\n", "f.csv"), "expected 6 fields");
  EXPECT_CONTAINS(table_error(std::string(head) + "0,0,0,-1,1,1\n", "f.csv"), "f.csv:3: r = -1 is negative");
  // Headers: group without mask, or in another order, are errors at line 1.
  for (const char* text : {"x,y,z,r,group\n0,0,0,1,1\n", "x,y,z,r,mask,group\n0,0,0,1,1,1\n",
                           "x,y,z,r,group,mask,extra\n0,0,0,1,1,1,1\n"}) {
    const std::string e = table_error(text, "f.csv");
    EXPECT_CONTAINS(e, "f.csv:1:") << text;
    EXPECT_CONTAINS(e, "x,y,z,r,group,mask") << text;
  }
}

TEST(CsvFilters, ReadSphereTable) {
  TempDir dir;
  write_file(dir / "f.csv", "x,y,z,r,group,mask\n1,2,3,4,3,0x6\n");
  auto r = read_sphere_table(dir / "f.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().filters.size(), 1u);
  EXPECT_EQ(r.value().filters[0].group, 3u);
  EXPECT_EQ(r.value().filters[0].mask, 6u);
  write_file(dir / "f.xyzr", "1 2 3 4\n");
  auto x = read_sphere_table(dir / "f.xyzr");
  ASSERT_TRUE(x.ok()) << x.error();
  EXPECT_EQ(x.value().spheres.size(), 1u);
  EXPECT_TRUE(x.value().filters.empty());
  auto missing = read_sphere_table(dir / "none.csv");
  ASSERT_FALSE(missing.ok());
  EXPECT_CONTAINS(missing.error(), "none.csv");
}

// ---------------------------------------------------------------------------------------------
// read_spheres

TEST(ReadSpheres, MissingFileNamesThePath) {
  TempDir dir;
  const fs::path p = dir / "does_not_exist.xyzr";
  auto r = read_spheres(p);
  ASSERT_FALSE(r.ok());
  EXPECT_CONTAINS(r.error(), p.string());
}

TEST(ReadSpheres, DirectoryIsAnErrorNamingThePath) {
  // A folder is not a sphere file: reading it must fail, not give zero spheres.
  TempDir dir;
  fs::create_directories(dir / "folder.xyzr");
  auto r = read_spheres(dir / "folder.xyzr");
  ASSERT_FALSE(r.ok()) << "reading a directory gave " << r.value().size() << " spheres instead of an error";
  EXPECT_CONTAINS(r.error(), (dir / "folder.xyzr").string());
}

TEST(ReadSpheres, XyzrFileAndErrorsNameTheFile) {
  TempDir dir;
  const fs::path good = dir / "good.xyzr";
  write_file(good, "1 2 3 4\n5 6 7 8\n");
  auto r = read_spheres(good);
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 2u);
  expect_sphere(r.value()[1], 5, 6, 7, 8);

  const fs::path bad = dir / "bad.xyzr";
  write_file(bad, "1 2 3 4\n5 6 7 8\n1 2 3\n");
  auto e = read_spheres(bad);
  ASSERT_FALSE(e.ok());
  EXPECT_CONTAINS(e.error(), bad.string() + ":3:");
}

TEST(ReadSpheres, EmptyFileIsZeroSpheres) {
  TempDir dir;
  write_file(dir / "empty.xyzr", "");
  write_file(dir / "empty.csv", "");
  auto a = read_spheres(dir / "empty.xyzr");
  ASSERT_TRUE(a.ok()) << a.error();
  EXPECT_TRUE(a.value().empty());
  auto b = read_spheres(dir / "empty.csv");
  ASSERT_TRUE(b.ok()) << b.error();
  EXPECT_TRUE(b.value().empty());
}

TEST(ReadSpheres, CsvExtensionSelectsCsv) {
  TempDir dir;
  write_file(dir / "s.csv", "x,y,z,r\n1,2,3,4\n");
  auto r = read_spheres(dir / "s.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 1u);
  expect_sphere(r.value()[0], 1, 2, 3, 4);

  // The same text under another extension is read as XYZR, where the header is an error.
  write_file(dir / "s.txt", "x,y,z,r\n1,2,3,4\n");
  auto x = read_spheres(dir / "s.txt");
  ASSERT_FALSE(x.ok());
  EXPECT_CONTAINS(x.error(), (dir / "s.txt").string() + ":1:");

  // And a .csv without its header is a CSV error at line 1.
  write_file(dir / "nohdr.csv", "1,2,3,4\n");
  auto h = read_spheres(dir / "nohdr.csv");
  ASSERT_FALSE(h.ok());
  EXPECT_CONTAINS(h.error(), (dir / "nohdr.csv").string() + ":1:");
  EXPECT_CONTAINS(h.error(), "header");
}

TEST(ReadSpheres, FixtureFiles) {
  const fs::path data = VISCD_TEST_DATA_DIR;
  auto x = read_spheres(data / "four.xyzr");
  ASSERT_TRUE(x.ok()) << x.error();
  auto c = read_spheres(data / "four.csv");
  ASSERT_TRUE(c.ok()) << c.error();
  ASSERT_EQ(x.value().size(), 4u);
  ASSERT_EQ(c.value().size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_TRUE(bits_equal(x.value()[k], c.value()[k])) << k;
  auto bad = read_spheres(data / "bad_line3.xyzr");
  ASSERT_FALSE(bad.ok());
  EXPECT_CONTAINS(bad.error(), (data / "bad_line3.xyzr").string() + ":3:");
}

// ---------------------------------------------------------------------------------------------
// Camera JSON

TEST(CameraJson, FullFileParsesEveryField) {
  const char* text = R"({
  "eye": [1.5, -2, 30],
  "target": [0.25, 4, -5],
  "up": [0, 0, 1],
  "fov_y_deg": 45.5,
  "near": 0.5,
  "far": 2500,
  "width": 640,
  "height": 480
})";
  auto r = parse_camera(text, "cam.json");
  ASSERT_TRUE(r.ok()) << r.error();
  const Camera& c = r.value();
  EXPECT_EQ(c.eye[0], 1.5f);
  EXPECT_EQ(c.eye[1], -2.0f);
  EXPECT_EQ(c.eye[2], 30.0f);
  EXPECT_EQ(c.target[0], 0.25f);
  EXPECT_EQ(c.target[1], 4.0f);
  EXPECT_EQ(c.target[2], -5.0f);
  EXPECT_EQ(c.up[0], 0.0f);
  EXPECT_EQ(c.up[1], 0.0f);
  EXPECT_EQ(c.up[2], 1.0f);
  EXPECT_EQ(c.fov_y_deg, 45.5f);
  EXPECT_EQ(c.near_plane, 0.5f);
  EXPECT_EQ(c.far_plane, 2500.0f);
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
}

TEST(CameraJson, MissingKeysTakeDefaults) {
  const Camera d;
  // The documented defaults.
  EXPECT_EQ(d.up[1], 1.0f);
  EXPECT_EQ(d.fov_y_deg, 60.0f);
  EXPECT_EQ(d.near_plane, 0.1f);
  EXPECT_EQ(d.far_plane, 1000.0f);
  EXPECT_EQ(d.width, 1280);
  EXPECT_EQ(d.height, 720);

  auto r = parse_camera("{}", "cam.json");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(camera_json(r.value()), camera_json(d));

  auto p = parse_camera(R"({"eye": [5, 6, 7], "width": 100})", "cam.json");
  ASSERT_TRUE(p.ok()) << p.error();
  EXPECT_EQ(p.value().eye[0], 5.0f);
  EXPECT_EQ(p.value().eye[1], 6.0f);
  EXPECT_EQ(p.value().eye[2], 7.0f);
  EXPECT_EQ(p.value().width, 100);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(p.value().target[k], d.target[k]);
    EXPECT_EQ(p.value().up[k], d.up[k]);
  }
  EXPECT_EQ(p.value().fov_y_deg, d.fov_y_deg);
  EXPECT_EQ(p.value().near_plane, d.near_plane);
  EXPECT_EQ(p.value().far_plane, d.far_plane);
  EXPECT_EQ(p.value().height, d.height);
}

TEST(CameraJson, InvalidJsonNamesTheLine) {
  // Missing comma at the end of line 3: the parser trips on line 4.
  const char* text = "{\n  \"eye\": [0, 0, 10],\n  \"target\": [0, 0, 0]\n  \"width\": 100\n}\n";
  const std::string e = camera_error(text, "cam.json");
  EXPECT_CONTAINS(e, "cam.json:4:");
  EXPECT_CONTAINS(e, "invalid JSON");

  const std::string e1 = camera_error("not json", "cam.json");
  EXPECT_CONTAINS(e1, "cam.json:1:");
  EXPECT_CONTAINS(e1, "invalid JSON");

  const std::string e2 = camera_error("{\n\"eye\": [1, 2,\n", "cam.json");
  EXPECT_CONTAINS(e2, "invalid JSON");
  EXPECT_CONTAINS(e2, "cam.json:");
}

TEST(CameraJson, NotAnObjectIsAnError) {
  const std::string e = camera_error("[1, 2, 3]", "cam.json");
  EXPECT_CONTAINS(e, "cam.json");
  EXPECT_CONTAINS(e, "object");
}

TEST(CameraJson, UnknownKeyIsNamed) {
  const std::string e = camera_error(R"({"eye": [0, 0, 10], "zoom": 2})", "cam.json");
  EXPECT_CONTAINS(e, "cam.json");
  EXPECT_CONTAINS(e, "unknown key");
  EXPECT_CONTAINS(e, "\"zoom\"");
}

TEST(CameraJson, WrongTypeForEye) {
  for (const char* text : {R"({"eye": "0 0 10"})", R"({"eye": [0, 10]})", R"({"eye": [0, 0, 10, 1]})",
                           R"({"eye": [0, "0", 10]})", R"({"eye": 10})", R"({"eye": null})"}) {
    const std::string e = camera_error(text, "cam.json");
    EXPECT_CONTAINS(e, "\"eye\"") << text;
    EXPECT_CONTAINS(e, "array of 3 numbers") << text;
  }
  EXPECT_CONTAINS(camera_error(R"({"up": [0, 1]})"), "\"up\"");
  EXPECT_CONTAINS(camera_error(R"({"target": {}})"), "\"target\"");
}

TEST(CameraJson, WrongTypeForNumbers) {
  EXPECT_CONTAINS(camera_error(R"({"fov_y_deg": "60"})"), "\"fov_y_deg\": expected a number");
  EXPECT_CONTAINS(camera_error(R"({"near": [0.1]})"), "\"near\": expected a number");
  EXPECT_CONTAINS(camera_error(R"({"far": true})"), "\"far\": expected a number");
}

TEST(CameraJson, WidthAndHeightMustBePositiveIntegers) {
  for (const char* text :
       {R"({"width": 0})", R"({"width": -5})", R"({"width": 1.5})", R"({"width": "640"})", R"({"width": 100000})"}) {
    const std::string e = camera_error(text, "cam.json");
    EXPECT_CONTAINS(e, "\"width\"") << text;
    EXPECT_CONTAINS(e, "integer") << text;
  }
  EXPECT_CONTAINS(camera_error(R"({"height": 0})"), "\"height\"");
}

TEST(CameraJson, NearMustBeBelowFar) {
  for (const char* text :
       {R"({"near": 10, "far": 10})", R"({"near": 20, "far": 10})", R"({"near": 0})", R"({"near": -1})"}) {
    const std::string e = camera_error(text, "cam.json");
    EXPECT_CONTAINS(e, "cam.json") << text;
    EXPECT_CONTAINS(e, "near") << text;
  }
}

TEST(CameraJson, EyeEqualToTargetIsAnError) {
  const std::string e = camera_error(R"({"eye": [1, 2, 3], "target": [1, 2, 3]})", "cam.json");
  EXPECT_CONTAINS(e, "cam.json");
  EXPECT_CONTAINS(e, "eye and target coincide");
}

TEST(CameraJson, UpParallelToViewIsAnError) {
  // Looking straight down with up = y.
  const std::string e = camera_error(R"({"eye": [0, 10, 0], "target": [0, 0, 0], "up": [0, 1, 0]})", "cam.json");
  EXPECT_CONTAINS(e, "cam.json");
  EXPECT_CONTAINS(e, "parallel");
  // Anti-parallel and zero up.
  EXPECT_CONTAINS(camera_error(R"({"eye": [0, 0, 10], "up": [0, 0, -3]})"), "parallel");
  EXPECT_CONTAINS(camera_error(R"({"up": [0, 0, 0]})"), "up");
}

TEST(CameraJson, FovOutOfRangeIsAnError) {
  EXPECT_CONTAINS(camera_error(R"({"fov_y_deg": 0})"), "fov_y_deg");
  EXPECT_CONTAINS(camera_error(R"({"fov_y_deg": 180})"), "fov_y_deg");
}

TEST(CameraJson, ParsedCamerasAreValid) {
  auto r = parse_camera(R"({"eye": [3, 4, 5], "target": [0, 1, 0], "near": 0.01, "far": 50})", "c");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_TRUE(validate_camera(r.value()).ok());
}

TEST(CameraJson, CameraJsonRoundTrips) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<float> u(-1000.0f, 1000.0f);
  for (int t = 0; t < 50; ++t) {
    Camera c;
    for (int k = 0; k < 3; ++k) c.eye[k] = u(rng), c.target[k] = u(rng);
    c.up[0] = 0.1f * u(rng), c.up[1] = 1.0f / 3.0f, c.up[2] = 1e-7f;
    c.fov_y_deg = 10.0f + std::fabs(u(rng)) / 1000.0f * 150.0f;
    c.near_plane = 1e-3f + std::fabs(u(rng)) / 7.0f;
    c.far_plane = c.near_plane * 1234.567f;
    c.width = 1 + t * 37;
    c.height = 65536 - t;
    ASSERT_TRUE(validate_camera(c).ok()) << t;
    const std::string text = camera_json(c);
    auto back = parse_camera(text, "round-trip");
    ASSERT_TRUE(back.ok()) << back.error() << "\n" << text;
    const Camera& b = back.value();
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(std::bit_cast<std::uint32_t>(b.eye[k]), std::bit_cast<std::uint32_t>(c.eye[k]));
      EXPECT_EQ(std::bit_cast<std::uint32_t>(b.target[k]), std::bit_cast<std::uint32_t>(c.target[k]));
      EXPECT_EQ(std::bit_cast<std::uint32_t>(b.up[k]), std::bit_cast<std::uint32_t>(c.up[k]));
    }
    EXPECT_EQ(std::bit_cast<std::uint32_t>(b.fov_y_deg), std::bit_cast<std::uint32_t>(c.fov_y_deg));
    EXPECT_EQ(std::bit_cast<std::uint32_t>(b.near_plane), std::bit_cast<std::uint32_t>(c.near_plane));
    EXPECT_EQ(std::bit_cast<std::uint32_t>(b.far_plane), std::bit_cast<std::uint32_t>(c.far_plane));
    EXPECT_EQ(b.width, c.width);
    EXPECT_EQ(b.height, c.height);
    EXPECT_EQ(camera_json(b), text);
  }
}

TEST(CameraJson, ReadCameraFromFile) {
  TempDir dir;
  const Camera c{{1, 2, 3}, {4, 5, 6}, {0, 1, 0}, 50, 0.25f, 500, 320, 200};
  ASSERT_TRUE(write_text(dir / "cam.json", camera_json(c)).ok());
  auto r = read_camera(dir / "cam.json");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(camera_json(r.value()), camera_json(c));

  auto missing = read_camera(dir / "missing.json");
  ASSERT_FALSE(missing.ok());
  EXPECT_CONTAINS(missing.error(), (dir / "missing.json").string());

  write_file(dir / "bad.json", "{\n\"eye\": [0, 0, 10],\n\"bogus\": 1\n}\n");
  auto bad = read_camera(dir / "bad.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_CONTAINS(bad.error(), (dir / "bad.json").string());
  EXPECT_CONTAINS(bad.error(), "\"bogus\"");
}

// ---------------------------------------------------------------------------------------------
// Writers

TEST(WriteSpheresCsv, RoundTripsBitExactly) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> exponent(-30.0, 17.0);
  std::uniform_real_distribution<double> mantissa(1.0, 10.0);
  std::bernoulli_distribution negative(0.5);
  auto random_value = [&](bool allow_negative) {
    const double v = mantissa(rng) * std::pow(10.0, std::floor(exponent(rng)));
    return static_cast<float>(allow_negative && negative(rng) ? -v : v);
  };
  std::vector<Sphere> spheres = {
      {0, 0, 0, 0},
      {-0.0f, 0.0f, -0.0f, 0.0f},
      {1e-30f, -1e-30f, 1e17f, 1e17f},
      {-1e17f, 1e18f, -1e18f, 1e18f},
      {0.1f, 1.0f / 3.0f, -2.0f / 3.0f, 0.7f},
      {std::numeric_limits<float>::min(), -std::numeric_limits<float>::min(), 1.17549435e-38f, 1e-38f},
      {std::numeric_limits<float>::denorm_min(), -1e-40f, 3e-39f, 1e-45f},
      {16777217.0f, -16777215.0f, 8388607.5f, 0.5f},
  };
  for (int k = 0; k < 2000; ++k)
    spheres.push_back({random_value(true), random_value(true), random_value(true), random_value(false)});
  // A few values with fully random mantissa bits in a moderate range.
  std::uniform_int_distribution<std::uint32_t> bits(0, 0x7FFFFFu);
  for (int k = 0; k < 500; ++k) {
    auto f = [&](std::uint32_t exp, bool neg) {
      return std::bit_cast<float>((neg ? 0x80000000u : 0u) | (exp << 23) | bits(rng));
    };
    spheres.push_back({f(100 + k % 60, k % 2 == 0), f(127, k % 3 == 0), f(20 + k % 100, true), f(90 + k % 70, false)});
  }
  ASSERT_TRUE(validate_spheres(spheres).ok());

  TempDir dir;
  const fs::path p = dir / "sub" / "spheres.csv";
  ASSERT_TRUE(write_spheres_csv(p, spheres).ok());
  EXPECT_EQ(read_file(p).rfind("x,y,z,r\n", 0), 0u);
  auto back = read_spheres(p);
  ASSERT_TRUE(back.ok()) << back.error();
  ASSERT_EQ(back.value().size(), spheres.size());
  int mismatches = 0;
  for (std::size_t k = 0; k < spheres.size(); ++k) {
    if (!bits_equal(back.value()[k], spheres[k]) && ++mismatches <= 10) {
      const Sphere& a = spheres[k];
      const Sphere& b = back.value()[k];
      ADD_FAILURE() << "sphere " << k << ": wrote " << a.x << ' ' << a.y << ' ' << a.z << ' ' << a.r << ", read " << b.x
                    << ' ' << b.y << ' ' << b.z << ' ' << b.r;
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(WriteSpheresCsv, EmptyListIsHeaderOnly) {
  TempDir dir;
  ASSERT_TRUE(write_spheres_csv(dir / "e.csv", {}).ok());
  EXPECT_EQ(read_file(dir / "e.csv"), "x,y,z,r\n");
  auto r = read_spheres(dir / "e.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_TRUE(r.value().empty());
}

TEST(WritePairsCsv, HeaderAndLines) {
  TempDir dir;
  const std::vector<Pair> pairs = {{0, 1}, {2, 3}, {7, 12345}, {4000000000u, 4294967295u}};
  ASSERT_TRUE(write_pairs_csv(dir / "p.csv", pairs).ok());
  EXPECT_EQ(read_file(dir / "p.csv"), "i,j\n0,1\n2,3\n7,12345\n4000000000,4294967295\n");
}

TEST(WritePairsCsv, EmptyListIsHeaderOnly) {
  TempDir dir;
  ASSERT_TRUE(write_pairs_csv(dir / "p.csv", {}).ok());
  EXPECT_EQ(read_file(dir / "p.csv"), "i,j\n");
}

TEST(WritePairsCsv, CreatesParentFolders) {
  TempDir dir;
  const fs::path p = dir / "a" / "b" / "pairs.csv";
  const std::vector<Pair> pairs = {{1, 2}};
  ASSERT_TRUE(write_pairs_csv(p, pairs).ok());
  EXPECT_EQ(read_file(p), "i,j\n1,2\n");
}

TEST(WriteText, UnwritablePathIsAnErrorNamingIt) {
  TempDir dir;
  write_file(dir / "file", "x");
  // A path below a regular file cannot be created.
  const fs::path p = dir / "file" / "out.txt";
  Status s = write_text(p, "hello");
  ASSERT_FALSE(s.ok());
  EXPECT_CONTAINS(s.error(), p.string());
}

TEST(WritePng, WritesPngAndRejectsWrongSizes) {
  TempDir dir;
  std::vector<std::uint8_t> rgba(4 * 3 * 2, 200);
  ASSERT_TRUE(write_png(dir / "img" / "a.png", rgba, 3, 2).ok());
  const std::string bytes = read_file(dir / "img" / "a.png");
  ASSERT_GE(bytes.size(), 8u);
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_FALSE(write_png(dir / "b.png", rgba, 4, 2).ok());
  EXPECT_FALSE(write_png(dir / "c.png", {}, 0, 0).ok());
}

// ---------------------------------------------------------------------------------------------
// stats_json

FrameStats sample_stats(bool has_camera) {
  FrameStats st;
  st.objects = 10000;
  st.active = 1234;
  st.has_camera = has_camera;
  st.mean_pixels = has_camera ? 87.5 : 0.0;
  st.bits = 16;
  st.layout = MortonLayoutInfo{.order = {0, 2, 1}, .axis_bits = {7, 3, 6}};  // x(7)→z(6)→y(3)
  st.pairs = 4321;
  for (std::size_t s = 0; s < kStageCount; ++s) st.stage_ms[s] = 0.25 * static_cast<double>(s + 1);
  return st;
}

TEST(StatsJson, ValidJsonWithTheKeys) {
  const std::string text = stats_json(sample_stats(true), "cpu");
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(text)) << text;
  ASSERT_TRUE(j.is_object());
  for (const char* key : {"objects", "active", "mean_pixels", "bits", "layout", "pairs", "stage_ms"})
    EXPECT_TRUE(j.contains(key)) << "missing key " << key << " in\n" << text;
  EXPECT_EQ(j["objects"].get<std::uint64_t>(), 10000u);
  EXPECT_EQ(j["active"].get<std::uint64_t>(), 1234u);
  ASSERT_TRUE(j["mean_pixels"].is_number());
  EXPECT_DOUBLE_EQ(j["mean_pixels"].get<double>(), 87.5);
  EXPECT_EQ(j["bits"].get<int>(), 16);
  EXPECT_EQ(j["layout"].get<std::string>(), "x(7)→z(6)→y(3)");
  EXPECT_EQ(j["pairs"].get<std::uint64_t>(), 4321u);
  ASSERT_TRUE(j["stage_ms"].is_object());
  EXPECT_EQ(j["stage_ms"].size(), kStageCount);
  for (std::size_t s = 0; s < kStageCount; ++s) {
    const std::string name(stage_name(static_cast<Stage>(s)));
    ASSERT_TRUE(j["stage_ms"].contains(name)) << name;
    EXPECT_DOUBLE_EQ(j["stage_ms"][name].get<double>(), 0.25 * static_cast<double>(s + 1)) << name;
  }
  if (j.contains("backend")) {
    EXPECT_EQ(j["backend"].get<std::string>(), "cpu");
  }
}

TEST(StatsJson, MeanPixelsIsNullWithoutCamera) {
  const std::string text = stats_json(sample_stats(false), "reference");
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(text)) << text;
  ASSERT_TRUE(j.contains("mean_pixels"));
  EXPECT_TRUE(j["mean_pixels"].is_null()) << text;
  EXPECT_EQ(j["pairs"].get<std::uint64_t>(), 4321u);
}

TEST(StatsJson, LargePairCountsAreExact) {
  FrameStats st = sample_stats(true);
  st.pairs = (1ull << 40) + 7;
  const auto j = nlohmann::json::parse(stats_json(st, "cpu"));
  EXPECT_EQ(j["pairs"].get<std::uint64_t>(), (1ull << 40) + 7);
}

// ---------------------------------------------------------------------------------------------
// pairs_hash

// Independent FNV-1a 64 over the little-endian bytes of i then j of every pair.
std::uint64_t fnv1a_oracle(const std::vector<Pair>& pairs) {
  std::uint64_t h = 14695981039346656037ull;
  for (const Pair& p : pairs) {
    unsigned char bytes[8];
    for (int b = 0; b < 4; ++b) {
      bytes[b] = static_cast<unsigned char>(p.i >> (8 * b));
      bytes[4 + b] = static_cast<unsigned char>(p.j >> (8 * b));
    }
    for (unsigned char c : bytes) {
      h ^= c;
      h *= 1099511628211ull;
    }
  }
  return h;
}

TEST(PairsHash, EmptyListIsTheOffsetBasis) { EXPECT_EQ(pairs_hash({}), 0xcbf29ce484222325ull); }

TEST(PairsHash, EqualListsEqualHashes) {
  const std::vector<Pair> a = {{0, 1}, {2, 3}, {5, 900}};
  const std::vector<Pair> b = a;
  EXPECT_EQ(pairs_hash(a), pairs_hash(b));
}

TEST(PairsHash, OrderMatters) {
  const std::vector<Pair> a = {{0, 1}, {2, 3}};
  const std::vector<Pair> b = {{2, 3}, {0, 1}};
  EXPECT_NE(pairs_hash(a), pairs_hash(b));
  EXPECT_NE(pairs_hash(std::vector<Pair>{{0, 1}}), pairs_hash(std::vector<Pair>{{1, 0}}));
  EXPECT_NE(pairs_hash(std::vector<Pair>{{0, 1}}), pairs_hash(std::vector<Pair>{{0, 2}}));
  EXPECT_NE(pairs_hash(std::vector<Pair>{{0, 1}}), pairs_hash({}));
}

TEST(PairsHash, IsFnv1aOverLittleEndianIndices) {
  std::mt19937 rng(7);
  std::vector<Pair> pairs;
  for (int k = 0; k < 100; ++k) pairs.push_back({static_cast<std::uint32_t>(rng()), static_cast<std::uint32_t>(rng())});
  EXPECT_EQ(pairs_hash(pairs), fnv1a_oracle(pairs));
  EXPECT_EQ(pairs_hash(std::vector<Pair>{{0, 1}}), fnv1a_oracle({{0, 1}}));
}

// ---------------------------------------------------------------------------------------------
// Hostile input: messages that stay printable, byte-order marks, out-of-range camera values,
// outputs written whole or not at all.

TEST(Printable, EscapesControlCharactersAndInvalidUtf8) {
  EXPECT_EQ(printable("plain text 1.5e3"), "plain text 1.5e3");
  EXPECT_EQ(printable(std::string_view("a\0b", 3)), "a\\x00b");
  EXPECT_EQ(printable("tab\there\r\n"), "tab\\there\\r\\n");
  EXPECT_EQ(printable("\x1b[31mred\x7f"), "\\x1B[31mred\\x7F");
  EXPECT_EQ(printable("\xff\xfe"), "\\xFF\\xFE");           // never valid in UTF-8
  EXPECT_EQ(printable("\xc0\x80"), "\\xC0\\x80");           // overlong NUL
  EXPECT_EQ(printable("\xed\xa0\x80"), "\\xED\\xA0\\x80");  // a UTF-16 surrogate
  EXPECT_EQ(printable("\xe2\x86"), "\\xE2\\x86");           // cut sequence
  EXPECT_EQ(printable("caf\xc3\xa9 x\xe2\x86\x92y \xf0\x9f\x98\x80"), "caf\xc3\xa9 x\xe2\x86\x92y \xf0\x9f\x98\x80");
}

TEST(Printable, CutsLongTextByCharacters) {
  EXPECT_EQ(printable(std::string(10, 'a'), 10), std::string(10, 'a'));
  EXPECT_EQ(printable(std::string(11, 'a'), 10), std::string(10, 'a') + "\xE2\x80\xA6");
  // Multi-byte characters count once.
  std::string arrows;
  for (int k = 0; k < 5; ++k) arrows += "\xe2\x86\x92";
  EXPECT_EQ(printable(arrows, 5), arrows);
  EXPECT_EQ(printable(std::string(1000000, 'z')).size(), 40u + 3u);
}

TEST(Xyzr, ByteOrderMarkIsSkipped) {
  auto r = parse_xyzr(
      "\xEF\xBB\xBF"
      "1 2 3 0.5\n",
      "bom.xyzr");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 1u);
  expect_sphere(r.value()[0], 1, 2, 3, 0.5f);
}

TEST(Csv, ByteOrderMarkIsSkipped) {
  auto r = parse_csv("\xEF\xBB\xBFx,y,z,r\n1,2,3,0.5\n", "bom.csv");
  ASSERT_TRUE(r.ok()) << r.error();
  ASSERT_EQ(r.value().size(), 1u);
}

TEST(Xyzr, BinaryFieldIsEscapedInTheMessage) {
  static constexpr char kText[] = "0 0 0 1\n1 \x01\0\x02 0 1\n";
  const std::string e = xyzr_error(std::string(kText, sizeof kText - 1));
  EXPECT_CONTAINS(e, "in.xyzr:2:");
  EXPECT_CONTAINS(e, "\\x01\\x00\\x02");
  for (char ch : e) EXPECT_FALSE(static_cast<unsigned char>(ch) < 0x20) << e;
}

TEST(Xyzr, HugeFieldIsCutInTheMessage) {
  const std::string e = xyzr_error("0 0 0 " + std::string(1000000, '9') + "\n");
  EXPECT_LT(e.size(), 200u) << e.substr(0, 300);
  EXPECT_CONTAINS(e, "\xE2\x80\xA6");
}

TEST(ReadSpheres, OpenErrorSaysWhy) {
  TempDir dir;
  auto r = read_spheres(dir / "missing.xyzr");
  ASSERT_FALSE(r.ok());
  EXPECT_CONTAINS(r.error(), "No such file or directory");
}

TEST(CameraJson, NumberBeyondDoubleIsAnErrorNotAnException) {
  const std::string e = camera_error(R"({"eye": [0, 0, 10], "far": 1e400})");
  EXPECT_CONTAINS(e, "cam.json");
  EXPECT_CONTAINS(e, "invalid JSON");
}

TEST(CameraJson, ValuesBeyond1e18AreErrors) {
  EXPECT_CONTAINS(camera_error(R"({"eye": [0, 1e30, 1e30]})"), "\"eye\"");
  EXPECT_CONTAINS(camera_error(R"({"target": [1e19, 0, 0]})"), "\"target\"");
  EXPECT_CONTAINS(camera_error(R"({"far": 1e300})"), "\"far\"");
  EXPECT_CONTAINS(camera_error(R"({"up": [0, 1e20, 0]})"), "\"up\"");
  EXPECT_CONTAINS(camera_error(R"({"width": 18446744073709551615})"), "\"width\"");
  EXPECT_CONTAINS(camera_error(R"({"height": 1e5})"), "\"height\"");
  auto ok = parse_camera(R"({"eye": [0, 1e18, 1e18], "far": 1e18})", "cam.json");
  EXPECT_TRUE(ok.ok()) << ok.error();
}

TEST(CameraJson, SyntaxErrorGivesLineColumnAndTheWholeReason) {
  const std::string e = camera_error("{\"eye\": [1, 2,\n  3x]}");
  EXPECT_CONTAINS(e, "cam.json:2:");
  EXPECT_CONTAINS(e, "syntax error while parsing array");
  EXPECT_CONTAINS(e, "last read");
}

TEST(CameraJson, ByteOrderMarkIsSkipped) {
  auto r = parse_camera("\xEF\xBB\xBF{\"eye\": [0, 0, 5]}", "bom.json");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value().eye[2], 5.0f);
}

TEST(CameraJson, KeysWithControlCharactersAreEscaped) {
  const std::string e = camera_error("{\"a\\u001bb\": 1}");
  EXPECT_CONTAINS(e, "\\x1B");
  for (char ch : e) EXPECT_FALSE(static_cast<unsigned char>(ch) < 0x20) << e;
}

// Files in a folder other than `keep`.
std::vector<std::string> files_in(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(AtomicFile, UncommittedLeavesTheOldFileAndNoTemporary) {
  TempDir dir;
  write_file(dir / "out.csv", "old\n");
  {
    auto f = AtomicFile::create(dir / "out.csv");
    ASSERT_TRUE(f.ok()) << f.error();
    ASSERT_TRUE(f.value().write("new, but never committed\n").ok());
    EXPECT_EQ(files_in(dir.path()).size(), 2u);  // out.csv and the temporary
  }
  EXPECT_EQ(read_file(dir / "out.csv"), "old\n");
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"out.csv"});
}

TEST(AtomicFile, CommitReplacesWholeWithOrdinaryPermissions) {
  TempDir dir;
  write_file(dir / "out.csv", "old\n");
  auto f = AtomicFile::create(dir / "out.csv");
  ASSERT_TRUE(f.ok()) << f.error();
  ASSERT_TRUE(f.value().write("new\n").ok());
  EXPECT_EQ(read_file(dir / "out.csv"), "old\n");  // not yet
  ASSERT_TRUE(f.value().commit().ok());
  EXPECT_EQ(read_file(dir / "out.csv"), "new\n");
  EXPECT_EQ(files_in(dir.path()), std::vector<std::string>{"out.csv"});
  const mode_t mask = ::umask(0);
  ::umask(mask);
  const auto perms = static_cast<mode_t>(fs::status(dir / "out.csv").permissions());
  EXPECT_EQ(perms & 0777, 0666 & ~mask);
}

TEST(AtomicFile, WritesThroughASymbolicLink) {
  TempDir dir;
  write_file(dir / "target.csv", "old\n");
  fs::create_symlink(dir / "target.csv", dir / "link.csv");
  ASSERT_TRUE(write_text(dir / "link.csv", "new\n").ok());
  EXPECT_TRUE(fs::is_symlink(dir / "link.csv"));
  EXPECT_EQ(read_file(dir / "target.csv"), "new\n");
}

TEST(AtomicFile, FolderIsAnError) {
  TempDir dir;
  auto f = AtomicFile::create(dir.path());
  ASSERT_FALSE(f.ok());
  EXPECT_CONTAINS(f.error(), "is a folder");
}

TEST(WritePairsCsv, StreamsManyBlocksExactly) {
  // More than one 1 MiB block of text; the expected text is built here independently.
  TempDir dir;
  std::vector<Pair> pairs;
  std::ostringstream want;
  want << "i,j\n";
  for (std::uint32_t k = 0; k < 300000; ++k) {
    pairs.push_back({k, k * 7 + 1});
    want << k << ',' << (k * 7 + 1) << '\n';
  }
  ASSERT_TRUE(write_pairs_csv(dir / "p.csv", pairs).ok());
  EXPECT_EQ(read_file(dir / "p.csv"), want.str());
}

}  // namespace
}  // namespace viscd

namespace viscd {
namespace {

// The tools' environment knobs (the library itself reads none).
TEST(Environment, MapsVariablesOntoConfig) {
  unsetenv("VISCD_SIMD");
  unsetenv("VISCD_KEEP_ORDER");
  Config c;
  ASSERT_TRUE(apply_environment(c).ok());
  EXPECT_EQ(c.simd, Simd::best);
  EXPECT_TRUE(c.keep_order);
  setenv("VISCD_SIMD", "scalar", 1);
  setenv("VISCD_KEEP_ORDER", "0", 1);
  ASSERT_TRUE(apply_environment(c).ok());
  EXPECT_EQ(c.simd, Simd::scalar);
  EXPECT_FALSE(c.keep_order);
  setenv("VISCD_SIMD", "sse2", 1);
  setenv("VISCD_KEEP_ORDER", "1", 1);
  ASSERT_TRUE(apply_environment(c).ok());
  EXPECT_EQ(c.simd, Simd::sse2);
  EXPECT_TRUE(c.keep_order);
  setenv("VISCD_SIMD", "avx9\n", 1);
  Status s = apply_environment(c);
  EXPECT_EQ(s.kind(), ErrorKind::invalid_input);
  EXPECT_NE(s.error().find("VISCD_SIMD=avx9\\n"), std::string::npos) << s.error();
  unsetenv("VISCD_SIMD");
  setenv("VISCD_KEEP_ORDER", "yes", 1);
  s = apply_environment(c);
  EXPECT_EQ(s.kind(), ErrorKind::invalid_input);
  EXPECT_NE(s.error().find("VISCD_KEEP_ORDER"), std::string::npos) << s.error();
  unsetenv("VISCD_KEEP_ORDER");
}

}  // namespace
}  // namespace viscd

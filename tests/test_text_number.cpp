// Numbers in text files: quoting, whole-text finite parsing, parsing with the decimal point
// moved (exact mm → m), and shortest formatting that reads back bit-exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <string>

#include "stepcal/common/text_number.hpp"

namespace stepcal {
namespace {

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(TextNumber, InQuotes) {
  EXPECT_EQ(inQuotes("x_mm"), "'x_mm'");
  EXPECT_EQ(inQuotes(""), "''");
  EXPECT_EQ(inQuotes(" a,b "), "' a,b '");
}

// A message is read by a person: a file's content is quoted as its first characters and size.
TEST(TextNumber, InQuotesCutsAFilesContent) {
  const std::string long_value(kQuotedCharsMax, 'x');
  EXPECT_EQ(inQuotes(long_value), "'" + long_value + "'");  // a long path stays whole
  const std::string table = "seq,pose_id,set,load_kg,q1_deg,q2_deg,q3_deg,x_mm\n1,p1,geometry";
  EXPECT_EQ(inQuotes(table), "'seq,pose_id,set,load_kg,q1_deg,q2_deg,q3…' (" +
                                 std::to_string(table.size()) + " bytes)");
  EXPECT_EQ(inQuotes("a\r\nb"), "'a…' (4 bytes)");
  EXPECT_EQ(inQuotes(long_value + "x"), "'" + long_value.substr(0, kQuotedExcerptChars) + "…' (" +
                                            std::to_string(kQuotedCharsMax + 1) + " bytes)");
  // Cut between characters, not inside one: 'é' is two bytes.
  std::string accents;
  while (accents.size() <= kQuotedCharsMax) accents += "\xC3\xA9";
  const std::string quoted = inQuotes(accents);
  EXPECT_EQ(quoted.substr(0, quoted.find("\xE2\x80\xA6")), "'" + accents.substr(0, 40));
}

TEST(TextNumber, ParseFiniteAcceptsDecimalAndExponentForms) {
  EXPECT_EQ(parseFinite("0"), 0.0);
  EXPECT_EQ(parseFinite("21.5"), 21.5);
  EXPECT_EQ(parseFinite("-196.133"), -196.133);
  EXPECT_EQ(parseFinite(".5"), 0.5);
  EXPECT_EQ(parseFinite("1."), 1.0);
  EXPECT_EQ(parseFinite("1e1"), 10.0);
  EXPECT_EQ(parseFinite("2E2"), 200.0);
  EXPECT_EQ(parseFinite("1.5e-3"), 1.5e-3);
  EXPECT_EQ(parseFinite("1e+3"), 1000.0);
  EXPECT_EQ(parseFinite("1.7976931348623157e308"), std::numeric_limits<double>::max());
  EXPECT_EQ(parseFinite("5e-324"), std::numeric_limits<double>::denorm_min());
}

TEST(TextNumber, ParseFiniteKeepsTheSignOfZero) {
  const std::optional<double> plus = parseFinite("0"), minus = parseFinite("-0");
  ASSERT_TRUE(plus && minus);
  EXPECT_FALSE(std::signbit(*plus));
  EXPECT_TRUE(std::signbit(*minus));
  EXPECT_TRUE(std::signbit(*parseFinite("-0.0e5")));
}

TEST(TextNumber, ParseFiniteRefusesWhatIsNotAWholeFiniteNumber) {
  for (const char* text : {"", " ", "abc", "1.5x", " 1", "1 ", "+1", "1,5", "1e", "1e+-5",
                           "1e--5", "0x10", "nan", "-nan", "inf", "-inf", "infinity", "1e999",
                           "-1e999"}) {
    EXPECT_EQ(parseFinite(text), std::nullopt) << "'" << text << "'";
  }
}

TEST(TextNumber, ParseFiniteShiftedMovesTheDecimalPoint) {
  // mm → m: the same doubles as the metre texts, not as a division by 1000.
  EXPECT_EQ(parseFiniteShifted("1000.5", -3), 1.0005);
  EXPECT_EQ(parseFiniteShifted("-200.125", -3), -0.200125);
  EXPECT_EQ(parseFiniteShifted("383.97123", -3), 0.38397123);
  EXPECT_EQ(parseFiniteShifted("0.3", 3), 300.0);
  EXPECT_EQ(parseFiniteShifted("12", 0), 12.0);
  // Exponent forms: the shift is added to the exponent.
  EXPECT_EQ(parseFiniteShifted("1.5e-3", -3), 1.5e-6);
  EXPECT_EQ(parseFiniteShifted("2E2", -3), 0.2);
  EXPECT_EQ(parseFiniteShifted("1e+3", -3), 1.0);
  EXPECT_EQ(parseFiniteShifted("5e-321", -3), std::numeric_limits<double>::denorm_min());
}

TEST(TextNumber, ParseFiniteShiftedRoundsOnceWhereDividingWouldNot) {
  // Random millimetre texts dddd.ddddd against their metre texts d.dddddddd written out: the
  // shifted parse is always that metre double, a parse divided by 1000 sometimes is not.
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int> whole(1000, 9999), fraction(0, 99999);
  int division_misses = 0;
  for (int i = 0; i < 2000; ++i) {
    const int w = whole(rng), f = fraction(rng);
    char mm[32], m[32];
    std::snprintf(mm, sizeof mm, "%d.%05d", w, f);
    std::snprintf(m, sizeof m, "%d.%03d%05d", w / 1000, w % 1000, f);
    const std::optional<double> shifted = parseFiniteShifted(mm, -3), metres = parseFinite(m);
    ASSERT_TRUE(shifted && metres) << mm;
    EXPECT_TRUE(sameBits(*shifted, *metres)) << mm << " mm vs " << m << " m";
    division_misses += *parseFinite(mm) / 1e3 != *metres;
  }
  EXPECT_GT(division_misses, 0) << "the case for moving the point is no longer demonstrated";
}

TEST(TextNumber, ParseFiniteShiftedKeepsTheSignOfZero) {
  EXPECT_FALSE(std::signbit(*parseFiniteShifted("0", -3)));
  EXPECT_TRUE(std::signbit(*parseFiniteShifted("-0", -3)));
  EXPECT_TRUE(std::signbit(*parseFiniteShifted("-0e7", 3)));
}

TEST(TextNumber, ParseFiniteShiftedRefusesWhatParseFiniteRefuses) {
  for (const char* text : {"", "abc", "1.5x", " 1", "+1", "1,5", "1e", "1e+", "1e+-5", "1e--5",
                           "1e5e3", "e5", "nan", "inf", "infinity"}) {
    EXPECT_EQ(parseFiniteShifted(text, -3), std::nullopt) << "'" << text << "'";
  }
}

TEST(TextNumber, ParseFiniteShiftedRefusesOverflowAndUnderflowAfterTheShift) {
  // In range only before the shift.
  EXPECT_EQ(parseFinite("1e306"), 1e306);
  EXPECT_EQ(parseFiniteShifted("1e306", 3), std::nullopt);
  EXPECT_EQ(parseFiniteShifted("1e-322", -3), std::nullopt);
  EXPECT_EQ(parseFiniteShifted("1e999", -3), std::nullopt);
  // Exponents at the ends of long long: saturated, not wrapped.
  EXPECT_EQ(parseFiniteShifted("1e9223372036854775807", 3), std::nullopt);
  EXPECT_EQ(parseFiniteShifted("1e-9223372036854775808", -3), std::nullopt);
  EXPECT_EQ(parseFiniteShifted("1e99999999999999999999", -3), std::nullopt);
}

TEST(TextNumber, FormatShortestReadsBackBitExactly) {
  EXPECT_EQ(formatShortest(0.1), "0.1");
  EXPECT_EQ(formatShortest(12000.0), "12000");
  EXPECT_EQ(formatShortest(0.0), "0");
  EXPECT_EQ(formatShortest(-0.0), "-0");
  EXPECT_EQ(formatShortest(1e300), "1e+300");
  EXPECT_EQ(formatShortest(std::numeric_limits<double>::infinity()), "inf");
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<uint64_t> bits;
  for (int i = 0; i < 10000; ++i) {
    const uint64_t b = bits(rng);
    double v = 0.0;
    std::memcpy(&v, &b, sizeof v);
    if (!std::isfinite(v)) continue;
    const std::string text = formatShortest(v);
    const std::optional<double> back = parseFinite(text);
    ASSERT_TRUE(back) << text;
    EXPECT_TRUE(sameBits(*back, v)) << text;
  }
  const double extremes[] = {std::numeric_limits<double>::max(),
                             -std::numeric_limits<double>::max(),
                             std::numeric_limits<double>::min(),
                             std::numeric_limits<double>::denorm_min(), -0.0};
  for (const double v : extremes) EXPECT_TRUE(sameBits(*parseFinite(formatShortest(v)), v));
}

}  // namespace
}  // namespace stepcal

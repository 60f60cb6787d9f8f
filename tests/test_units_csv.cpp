// The shared boundary helpers: unit constants (units.hpp), the text-table splitter every reader
// uses (csv.hpp) and the pose ↔ (position, quaternion) converters (pose_quaternion.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "stepcal/common/csv.hpp"
#include "stepcal/common/lie.hpp"
#include "stepcal/common/pose_quaternion.hpp"
#include "stepcal/common/units.hpp"

namespace stepcal {
namespace {

using Lines = std::vector<std::string_view>;

TEST(Units, ConstantsAreTheDoublesTheyName) {
  EXPECT_EQ(kPi, M_PI);
  EXPECT_EQ(kRadPerDeg, M_PI / 180.0);
  EXPECT_EQ(kDegPerRad, 180.0 / M_PI);
  EXPECT_EQ(kMPerMm, 0.001);
  EXPECT_EQ(kMmPerM, 1000.0);
  EXPECT_EQ(90.0 * kRadPerDeg, kPi / 2);
  EXPECT_EQ(kPi * kDegPerRad, 180.0);
  EXPECT_EQ(static_cast<double>(kRadPerDegExtended), kRadPerDeg);
}

TEST(Units, TheReplacedSpellingsGiveTheSameBits) {
  // Constants that were written x * M_PI / 180 before there was kRadPerDeg.
  for (const double x : {0.005, 0.01, 0.03, 1.0, 1.25, 2.0, -2.0, 15.0, 60.0}) {
    EXPECT_EQ(x * kRadPerDeg, x * M_PI / 180.0) << x;
  }
  EXPECT_EQ(2.0 * kRadPerDeg, 2.0 / kDegPerRad);
}

TEST(Csv, SplitLinesTakesTheLastNewlineAsOptional) {
  EXPECT_EQ(splitLines("a\nb"), (Lines{"a", "b"}));
  EXPECT_EQ(splitLines("a\nb\n"), (Lines{"a", "b"}));
  EXPECT_EQ(splitLines("a\nb\n\n"), (Lines{"a", "b", ""}));  // the reader judges the blank line
  EXPECT_EQ(splitLines("a\n\nb"), (Lines{"a", "", "b"}));
  EXPECT_EQ(splitLines(""), Lines{});
  EXPECT_EQ(splitLines("\n"), Lines{""});
}

TEST(Csv, SplitLinesReadsCrlfAsLf) {
  EXPECT_EQ(splitLines("a\r\nb\r\n"), (Lines{"a", "b"}));
  EXPECT_EQ(splitLines("a\r\nb"), (Lines{"a", "b"}));
  EXPECT_EQ(splitLines("a\r\n\r\n"), (Lines{"a", ""}));
  EXPECT_EQ(splitLines("a\rb\r"), (Lines{"a\rb"}));      // a lone '\r' ends no line
  EXPECT_EQ(splitLines("a\r\r\n"), (Lines{"a\r"}));      // one '\r' is dropped
}

TEST(Csv, SplitLinesKeepsEveryOtherCharacter) {
  const std::string text("a\0b\n c ,\t\n", 9);
  EXPECT_EQ(splitLines(text), (Lines{std::string_view("a\0b", 3), " c ,\t"}));
}

// The byte-order mark rule, one for every table reader: a UTF-8 BOM at the start is skipped.
TEST(Csv, SplitLinesSkipsAByteOrderMarkAtTheStart) {
  EXPECT_EQ(splitLines("\xEF\xBB\xBFseq,x\n1,2\n"), (Lines{"seq,x", "1,2"}));
  EXPECT_EQ(splitLines("\xEF\xBB\xBF"), Lines{});
  EXPECT_EQ(splitLines("a\n\xEF\xBB\xBF"), (Lines{"a", "\xEF\xBB\xBF"}));  // only at the start
  EXPECT_EQ(withoutByteOrderMark("\xEF\xBB\xBF\xEF\xBB\xBF" "a"), "\xEF\xBB\xBF" "a");  // one
  EXPECT_EQ(withoutByteOrderMark("\xEF\xBB" "a"), "\xEF\xBB" "a");  // not a whole mark
}

TEST(Csv, SplitFieldsKeepsEmptyFields) {
  EXPECT_EQ(splitFields("a,b,c"), (Lines{"a", "b", "c"}));
  EXPECT_EQ(splitFields("a,,b"), (Lines{"a", "", "b"}));
  EXPECT_EQ(splitFields("a,b,"), (Lines{"a", "b", ""}));
  EXPECT_EQ(splitFields(",a"), (Lines{"", "a"}));
  EXPECT_EQ(splitFields(""), Lines{""});
  EXPECT_EQ(splitFields(","), (Lines{"", ""}));
}

TEST(Csv, SplitFieldsHasNoQuotingOrTrimming) {
  EXPECT_EQ(splitFields("\"a,b\", c "), (Lines{"\"a", "b\"", " c "}));
  EXPECT_EQ(splitFields("1,5;2", ';'), (Lines{"1,5", "2"}));
  EXPECT_EQ(splitFields("1 2\t3", ' '), (Lines{"1", "2\t3"}));
}

TEST(PoseQuaternion, RoundTripsAPose) {
  Pose X = Pose::Identity();
  X.linear() = lie::rotationFromRpy(0.3, -1.1, 2.5);
  X.translation() = Vec3(1.5, -0.25, 0.75);
  double p_m[3], q_wxyz[4];
  toPositionQuaternion(X, p_m, q_wxyz);
  EXPECT_EQ(Vec3(p_m[0], p_m[1], p_m[2]), X.translation());
  const Eigen::Quaterniond q(X.linear());
  EXPECT_EQ(q_wxyz[0], q.w());
  EXPECT_EQ(q_wxyz[1], q.x());
  EXPECT_EQ(q_wxyz[2], q.y());
  EXPECT_EQ(q_wxyz[3], q.z());
  const Pose back = poseFromPositionQuaternion(p_m, q_wxyz);
  EXPECT_TRUE(back.matrix().isApprox(X.matrix(), 1e-15));
  EXPECT_EQ(back.matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

TEST(PoseQuaternion, NormalisesAndChecksTheNorm) {
  const double p_m[3] = {0, 0, 0}, q_wxyz[4] = {2, 0, 0, 0};
  EXPECT_TRUE(poseFromPositionQuaternion(p_m, q_wxyz).linear().isApprox(Mat3::Identity(), 0.0));
  EXPECT_TRUE(isUnitQuaternion(Eigen::Quaterniond(1.0 + 0.9e-6, 0, 0, 0)));
  EXPECT_FALSE(isUnitQuaternion(Eigen::Quaterniond(1.0 + 1.1e-6, 0, 0, 0)));
  EXPECT_FALSE(isUnitQuaternion(Eigen::Quaterniond(NAN, 0, 0, 0)));
}

}  // namespace
}  // namespace stepcal

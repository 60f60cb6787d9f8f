// Comparison of the measurement rows of two campaigns.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "stepcal/common/campaign.hpp"

namespace stepcal::test {

/// True when a and b are the same double bit for bit (so -0 differs from 0, NaN can match).
inline bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// How expectSameRows compares the doubles of two rows.
enum class DoubleMatch {
  kEqual,     ///< ==: -0 matches 0
  kSameBits,  ///< bit for bit, as a round trip through files must keep them
};

/// Expects a and b to have the same rows, field by field.
/// Compares seq, pose_id, set, load_kg, q_rad, has_wrench, wrench_Sensor, p_TipInTracker_m,
/// has_orientation, q_TrackerTip (where has_orientation), temp_c and extra; stops after the
/// first row that differs, which it names.
inline void expectSameRows(const Campaign& a, const Campaign& b,
                           DoubleMatch match = DoubleMatch::kEqual) {
  const auto same = [match](double x, double y) {
    return match == DoubleMatch::kSameBits ? sameBits(x, y) : x == y;
  };
  const auto expectSameValues = [&](const auto& x, const auto& y, const char* field) {
    ASSERT_EQ(x.size(), y.size()) << field;
    for (Eigen::Index k = 0; k < x.size(); ++k) {
      EXPECT_TRUE(same(x[k], y[k])) << field << "[" << k << "]: " << ::testing::PrintToString(x[k])
                                    << " vs " << ::testing::PrintToString(y[k]);
    }
  };
  ASSERT_EQ(a.rows.size(), b.rows.size());
  const bool failed_before = ::testing::Test::HasFailure();
  for (size_t i = 0; i < a.rows.size(); ++i) {
    SCOPED_TRACE("row " + std::to_string(i));
    const Measurement& x = a.rows[i];
    const Measurement& y = b.rows[i];
    EXPECT_EQ(x.seq, y.seq);
    EXPECT_EQ(x.pose_id, y.pose_id);
    EXPECT_EQ(x.set, y.set);
    EXPECT_TRUE(same(x.load_kg, y.load_kg)) << "load_kg: " << x.load_kg << " vs " << y.load_kg;
    expectSameValues(x.q_rad, y.q_rad, "q_rad");
    EXPECT_EQ(x.has_wrench, y.has_wrench);
    expectSameValues(x.wrench_Sensor, y.wrench_Sensor, "wrench_Sensor");
    expectSameValues(x.p_TipInTracker_m, y.p_TipInTracker_m, "p_TipInTracker_m");
    EXPECT_EQ(x.has_orientation, y.has_orientation);
    if (x.has_orientation) {
      expectSameValues(x.q_TrackerTip.coeffs(), y.q_TrackerTip.coeffs(), "q_TrackerTip");
    }
    EXPECT_EQ(x.temp_c.has_value(), y.temp_c.has_value());
    if (x.temp_c && y.temp_c) {
      EXPECT_TRUE(same(*x.temp_c, *y.temp_c)) << "temp_c: " << *x.temp_c << " vs " << *y.temp_c;
    }
    EXPECT_EQ(x.extra, y.extra);
    if (!failed_before && ::testing::Test::HasFailure()) return;
  }
}

}  // namespace stepcal::test

// Unit conversions at the boundaries (files, messages, reports), in one place. Inside, everything
// is SI (metres, radians); millimetres and degrees exist only where text is read or written.
// Each constant says what it converts to and from: value_rad = value_deg * kRadPerDeg.
#pragma once

namespace stepcal {

/// π, as the double nearest it (the value of POSIX's M_PI, without depending on it).
inline constexpr double kPi = 3.14159265358979323846;

/// Radians per degree: value_rad = value_deg * kRadPerDeg (the double nearest π/180).
inline constexpr double kRadPerDeg = kPi / 180.0;
/// Degrees per radian: value_deg = value_rad * kDegPerRad (the double nearest 180/π).
inline constexpr double kDegPerRad = 180.0 / kPi;

/// Metres per millimetre: value_m = value_mm * kMPerMm.
inline constexpr double kMPerMm = 1e-3;
/// Millimetres per metre: value_mm = value_m * kMmPerM.
inline constexpr double kMmPerM = 1e3;

/// Radians per degree in extended precision, for the campaign files' exact degree text
/// (campaign.cpp rounds value_deg * kRadPerDegExtended to double once).
inline constexpr long double kRadPerDegExtended = 3.141592653589793238462643383279502884L / 180.0L;

/// A translation given in mm shorter than this (and not zero) looks like metres typed where mm
/// were expected: a robot's targets, frames and tools lie metres or centimetres apart.
inline constexpr double kLooksLikeMetresBelow_mm = 5.0;

/// Whether x y z (mm) looks like metres (kLooksLikeMetresBelow_mm): worth a warning, no more.
inline bool looksLikeMetres(double x_mm, double y_mm, double z_mm) {
  const double squared_mm2 = x_mm * x_mm + y_mm * y_mm + z_mm * z_mm;
  return squared_mm2 > 0.0 && squared_mm2 < kLooksLikeMetresBelow_mm * kLooksLikeMetresBelow_mm;
}

}  // namespace stepcal

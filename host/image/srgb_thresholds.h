// 8-bit sRGB encoding by comparison instead of by pow: the 255 linear values at which the encoded
// byte steps up. The tonemap kernel finds a pixel's byte with eight comparisons against this
// table; on PoCL's CPU devices that replaced three pow calls per pixel, which had made stage 8
// cost as much as a G-buffer pass (docs/measurements.md, "Pipeline stages on PoCL").
#pragma once

#include <array>

namespace px {

// thresholds[k] for k = 1..255 is the smallest float c with round(255 * srgb(c)) >= k, where
// srgb is the exact sRGB transfer curve (IEC 61966-2-1) evaluated in double precision; so the
// byte of c is the number of thresholds <= c. thresholds[0] = 0 (every c >= 0 reaches byte 0).
std::array<float, 256> srgb8_thresholds();

}  // namespace px

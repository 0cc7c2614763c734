// CAMBI (host/image/cambi.*) on images whose banding we know: a smooth gradient has none, a
// gradient quantised into bands one display level apart has some, more with wider bands, and
// noise dithering before the quantisation hides it again. Also: input checks, the linear-RGB
// entry point agrees with the luma one, and a flat image scores 0. CambiReference: exact values
// derived by hand for steps, staircases, scales, pooling and the mask (derivation below).
#include "image/cambi.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace px {
namespace {

constexpr int kW = 256, kH = 64;
constexpr float kBase = 0.08f;  // dark-ish: where a one-level step of an 8-bit display is visible

// Horizontal ramp of display-encoded luma rising one 8-bit level every `band` pixels.
std::vector<float> banded_ramp(int band) {
  std::vector<float> l(kW * kH);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) l[y * kW + x] = kBase + static_cast<float>(x / band) / 255.0f;
  return l;
}

// The same ramp before quantisation: continuous values with the same slope.
std::vector<float> smooth_ramp(int band) {
  std::vector<float> l(kW * kH);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) l[y * kW + x] = kBase + (x + 0.5f) / band / 255.0f;
  return l;
}

double score(const std::vector<float>& l, int bits = 8) {
  CambiOptions o;
  o.source_bits = bits;
  return cambi_luma(l, kW, kH, o).score;
}

TEST(Cambi, FlatImageScoresZero) { EXPECT_EQ(score(std::vector<float>(kW * kH, 0.3f)), 0.0); }

TEST(Cambi, SmoothGradientScoresAboutZero) {
  // Shown at 10 bits, a gradient rising one 8-bit level per 4 pixels steps one 10-bit code per
  // pixel: no flat runs, nothing reads as banding. Shown at 8 bits, the same gradient is bands
  // 4 pixels wide, one visible level apart.
  const double smooth = score(smooth_ramp(4), 10);
  const double banded = score(banded_ramp(4), 8);
  std::printf("[cambi] smooth ramp (10 bit) %.4f, the same ramp in 8 bit (4-px bands) %.4f\n", smooth, banded);
  EXPECT_LT(smooth, 0.01);
  EXPECT_GT(banded, 0.1);
}

TEST(Cambi, ScoreGrowsWithBandWidth) {
  double previous = -1.0;
  for (int band : {2, 4, 8, 16, 32}) {
    const double s = score(banded_ramp(band));
    std::printf("[cambi] band width %2d px: %.4f\n", band, s);
    EXPECT_GT(s, previous) << "band width " << band;
    previous = s;
  }
}

TEST(Cambi, NoiseDitheringLowersTheScore) {
  // Dithering: noise of +-1 level added before the 8-bit quantisation of the same ramp breaks
  // the flat runs the bands are made of.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> noise(-1.0f / 255.0f, 1.0f / 255.0f);
  auto l = smooth_ramp(16);
  const double banded = score(l);
  for (auto& v : l) v += noise(rng);
  const double dithered = score(l);
  std::printf("[cambi] 16-px bands %.4f, dithered %.4f\n", banded, dithered);
  EXPECT_GT(banded, 0.05);
  EXPECT_LT(dithered, 0.5 * banded);
}

TEST(Cambi, InvisibleStepsInBrightRegionsDoNotCount) {
  // The same one-level bands near white: a step of 4 codes at ~90% of peak is below the
  // visibility threshold, so the score is far lower than in the dark.
  auto l = banded_ramp(16);
  for (auto& v : l) v += 0.8f;
  const double bright = score(l), dark = score(banded_ramp(16));
  std::printf("[cambi] 16-px bands dark %.4f, bright %.4f\n", dark, bright);
  EXPECT_LT(bright, 0.1 * dark);
}

TEST(Cambi, RgbEntryPointMatchesLuma) {
  // A grey linear image whose sRGB encoding is the banded ramp gives the same score.
  const auto l = banded_ramp(16);
  ImageRGB img;
  img.width = kW;
  img.height = kH;
  img.rgb.resize(3 * l.size());
  for (std::size_t i = 0; i < l.size(); ++i) {
    const float e = l[i];
    const float lin = e <= 0.04045f ? e / 12.92f : std::pow((e + 0.055f) / 1.055f, 2.4f);
    img.rgb[3 * i] = img.rgb[3 * i + 1] = img.rgb[3 * i + 2] = lin;
  }
  EXPECT_NEAR(cambi(img).score, score(l), 1e-3);
}

// ---------------------------------------------------------------------------------------------
// Reference values derived by hand from the algorithm's definition (cambi.h), on synthetic
// images small enough to follow every step. All use 10-bit input (a luma of c / 1023 is code c
// exactly), a 9-pixel contrast window (r = 4), a 3-pixel flatness window and, unless said,
// one scale and topk = 1 (the score is the plain mean of c over all pixels).
//
// The step: columns x < s carry code A, columns x >= s code A + k, every row the same.
//  - Mask: only column s - 1 is not flat (its right neighbour differs); every 3x3 window (also
//    clipped at the borders) holds at most one non-flat column, so more than half of it is flat
//    and every pixel is kept.
//  - Contrast: all rows are alike, so clipping the window at the top or bottom scales both
//    histogram counts alike and p(L), p(L+k) are column fractions. A pixel sees the step only
//    within r columns of it: with j = 1..r columns of the other code in its 2r + 1 = 9 columns,
//    p0 = (9 - j) / 9, p1 = j / 9 and p0 + p1 = 1, so c = k * j * (9 - j) / 81 (when a step of
//    k codes at the darker side A is visible, and k <= 4). Each row has these r values on each
//    side of the step, and 0 elsewhere (one code only in the window):
//      row sum = 2k * sum_{j=1..4} j (9 - j) / 81 = 2k * (8 + 14 + 18 + 20) / 81 = 120 k / 81,
//    and the mean over a row of W pixels is 120 k / (81 W).
//  - Visibility (luminance(c) = (c / 1023)^2.4 + 1e-3, Weber contrast > 0.019): a one-code step
//    is visible from A = 44 (contrast 0.01909) to A = 101 (0.019005), not at 43 (0.01884) or 102
//    (0.018908); a four-code step from A = 12 to A = 504 (0.019012; at 505 0.018975). Computed
//    in double precision as cambi.cpp does; every margin is above 4e-6, far beyond rounding.
constexpr int kSW = 64, kSH = 16, kStepAt = 32;
constexpr double kStepMean = 120.0 / (81.0 * kSW);  // one visible one-code step, mean over the image

// Columns x in [edges[i], edges[i + 1]) carry codes[i] (edges[0] = 0, implied end kSW).
std::vector<float> columns_of_codes(const std::vector<int>& edges, const std::vector<int>& codes) {
  std::vector<float> l(kSW * kSH);
  for (int x = 0; x < kSW; ++x) {
    std::size_t band = 0;
    while (band + 1 < edges.size() && x >= edges[band + 1]) ++band;
    for (int y = 0; y < kSH; ++y) l[y * kSW + x] = codes[band] / 1023.0f;
  }
  return l;
}

std::vector<float> step(int a, int b) { return columns_of_codes({0, kStepAt}, {a, b}); }

CambiResult exact(const std::vector<float>& l, int scales = 1, double topk = 1.0, int bits = 10) {
  CambiOptions o;
  o.source_bits = bits;
  o.scales = scales;
  o.window = 9;
  o.mask_window = 3;
  o.topk = topk;
  return cambi_luma(l, kSW, kSH, o);
}

TEST(CambiReference, OneCodeStepMatchesTheDerivedMean) {
  EXPECT_NEAR(exact(step(60, 61)).score, kStepMean, 1e-12);  // 0.0231481...
  EXPECT_NEAR(exact(step(61, 60)).score, kStepMean, 1e-12) << "a step down counts as a step up";
}

TEST(CambiReference, StepHeightWeightsTheValueUpToFourCodes) {
  // c = k * p0 p1 / (p0 + p1): k = 2, 3, 4 scale the one-code value; a step of 5 codes is an
  // edge, not a band (k only goes to 4), and scores 0.
  for (int k : {2, 3, 4}) EXPECT_NEAR(exact(step(60, 60 + k)).score, k * kStepMean, 1e-12) << "k = " << k;
  EXPECT_EQ(exact(step(60, 65)).score, 0.0);
}

TEST(CambiReference, VisibilityIsJudgedAtTheDarkerSideOfTheStep) {
  // At both ends of the one-code visibility range: 44 and 101 are visible, 43 and 102 are not.
  EXPECT_NEAR(exact(step(44, 45)).score, kStepMean, 1e-12);
  EXPECT_EQ(exact(step(43, 44)).score, 0.0);
  EXPECT_NEAR(exact(step(101, 102)).score, kStepMean, 1e-12);
  EXPECT_NEAR(exact(step(102, 101)).score, kStepMean, 1e-12) << "darker side 101, whichever side it is on";
  EXPECT_EQ(exact(step(102, 103)).score, 0.0);
  // Four codes: visible up to 505, not from 506.
  EXPECT_NEAR(exact(step(505, 509)).score, 4 * kStepMean, 1e-12);
  EXPECT_EQ(exact(step(506, 510)).score, 0.0);
}

TEST(CambiReference, EightBitLevelsAreFourCodes) {
  // 8-bit input: level v becomes code 4v, so one level from 20/255 to 21/255 is a step of four
  // codes at 80 (visible): 4 times the one-code mean.
  std::vector<float> l(kSW * kSH);
  for (int y = 0; y < kSH; ++y)
    for (int x = 0; x < kSW; ++x) l[y * kSW + x] = (x < kStepAt ? 20 : 21) / 255.0f;
  EXPECT_NEAR(exact(l, 1, 1.0, 8).score, 4 * kStepMean, 1e-12);
}

TEST(CambiReference, StaircaseSumsItsSteps) {
  // Bands 8 = 2r columns wide, codes 50..57 (each one-code step visible: 44 <= A <= 101): no
  // pixel is within r columns of two steps (that needs bands narrower than 2r), and the first
  // and last steps (x = 8, 56) are r + 1 columns from the borders, so no window a step reaches
  // is clipped sideways. Each of the 7 steps adds its own mean: 7 * 120 / (81 * 64) = 0.16204.
  std::vector<int> edges, codes;
  for (int i = 0; i < 8; ++i) edges.push_back(8 * i), codes.push_back(50 + i);
  EXPECT_NEAR(exact(columns_of_codes(edges, codes)).score, 7 * kStepMean, 1e-12);
}

TEST(CambiReference, TopkPoolsTheLargestValues) {
  // topk = 1/32 of 64 x 16 pixels = 32 values: the 2 per row at j = r = 4 on either side of the
  // step, the largest, c = 4 * 5 / 81. (1/32 and 32 are exact in binary: ceil() sees 32.)
  EXPECT_NEAR(exact(step(60, 61), 1, 1.0 / 32).score, 20.0 / 81.0, 1e-12);
}

TEST(CambiReference, CoarserScalesSeeTheSameStepOnFewerPixels) {
  // Halving: 2x2 means of an even-aligned step keep the two codes and the step (at 16, then 8),
  // the mask stays full, and the window stays 9 pixels: the same row sums over W / 2 and W / 4
  // columns, so per scale 1, 2 and 4 times the full-scale mean (at W / 4 = 16 the step is still
  // r columns or more from both borders), and the score is their mean, 7/3 of it.
  const CambiResult r = exact(step(60, 61), 3);
  ASSERT_EQ(r.per_scale.size(), 3u);
  EXPECT_NEAR(r.per_scale[0], kStepMean, 1e-12);
  EXPECT_NEAR(r.per_scale[1], 2 * kStepMean, 1e-12);
  EXPECT_NEAR(r.per_scale[2], 4 * kStepMean, 1e-12);
  EXPECT_NEAR(r.score, 7.0 / 3.0 * kStepMean, 1e-12);
}

TEST(CambiReference, NoFlatPixelsMaskEverythingOut) {
  // A one-pixel checkerboard of two visible codes: no pixel has equal right and lower
  // neighbours but the bottom-right corner, so no 3x3 window is mostly flat, every pixel is
  // masked out, and the score is 0 although the two codes fill every window about half and
  // half (unmasked, each pixel would have c = 40 * 41 / 81^2 = 0.25 in a full window).
  std::vector<float> l(kSW * kSH);
  for (int y = 0; y < kSH; ++y)
    for (int x = 0; x < kSW; ++x) l[y * kSW + x] = ((x + y) % 2 ? 61 : 60) / 1023.0f;
  EXPECT_EQ(exact(l).score, 0.0);
}

TEST(Cambi, RejectsBadInput) {
  EXPECT_THROW(cambi_luma(std::vector<float>(10), 4, 4), std::invalid_argument);
  CambiOptions o;
  o.topk = 0.0;
  EXPECT_THROW(cambi_luma(std::vector<float>(16), 4, 4, o), std::invalid_argument);
}

}  // namespace
}  // namespace px

// CAMBI (host/image/cambi.*) on images whose banding we know: a smooth gradient has none, a
// gradient quantised into bands one display level apart has some, more with wider bands, and
// noise dithering before the quantisation hides it again. Also: input checks, the linear-RGB
// entry point agrees with the luma one, and a flat image scores 0.
#include "image/cambi.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

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

TEST(Cambi, FlatImageScoresZero) {
  EXPECT_EQ(score(std::vector<float>(kW * kH, 0.3f)), 0.0);
}

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

TEST(Cambi, RejectsBadInput) {
  EXPECT_THROW(cambi_luma(std::vector<float>(10), 4, 4), std::invalid_argument);
  CambiOptions o;
  o.topk = 0.0;
  EXPECT_THROW(cambi_luma(std::vector<float>(16), 4, 4, o), std::invalid_argument);
}

}  // namespace
}  // namespace px

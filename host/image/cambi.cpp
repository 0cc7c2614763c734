#include "image/cambi.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <stdexcept>

namespace px {
namespace {

constexpr int kCodes = 1024;  // CAMBI works in 10-bit codes whatever the source depth
constexpr int kMaxStep = 4;   // contrast steps 1..4 codes: larger steps are edges, not bands

struct Plane {
  int width = 0, height = 0;
  std::vector<std::uint16_t> code;
  std::vector<std::uint8_t> mask;
};

int odd_at_least(double v, int floor_value) {
  int n = std::max(floor_value, static_cast<int>(std::lround(v)));
  return n | 1;
}

// Display luminance of a 10-bit code, relative to peak: gamma 2.4 with a black level of 1/1000
// of peak, so that steps near black have a finite (large) Weber contrast.
double luminance(int code) { return std::pow(code / 1023.0, 2.4) + 1e-3; }

// visible[k][v]: a step of k codes up from v has a Weber contrast above the threshold.
std::array<std::vector<std::uint8_t>, kMaxStep + 1> visibility(double threshold) {
  std::array<std::vector<std::uint8_t>, kMaxStep + 1> vis;
  for (int k = 1; k <= kMaxStep; ++k) {
    vis[k].assign(kCodes, 0);
    for (int v = 0; v + k < kCodes; ++v) {
      const double l = luminance(v);
      vis[k][v] = (luminance(v + k) - l) > threshold * l;
    }
  }
  return vis;
}

// A pixel is flat when its right and lower neighbours carry the same code (a missing neighbour
// at the border counts as equal). The mask keeps pixels whose window is mostly flat: banding is
// only seen in smooth regions; in textured or noisy ones the same steps are masked.
std::vector<std::uint8_t> flat_mask(const Plane& p, int window) {
  const int w = p.width, h = p.height, r = window / 2;
  std::vector<int> integral(static_cast<std::size_t>(w + 1) * (h + 1), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const auto c = p.code[y * w + x];
      const bool flat = (x + 1 >= w || p.code[y * w + x + 1] == c) && (y + 1 >= h || p.code[(y + 1) * w + x] == c);
      integral[(y + 1) * (w + 1) + x + 1] =
          flat + integral[y * (w + 1) + x + 1] + integral[(y + 1) * (w + 1) + x] - integral[y * (w + 1) + x];
    }
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int x0 = std::max(0, x - r), x1 = std::min(w, x + r + 1), y0 = std::max(0, y - r),
                y1 = std::min(h, y + r + 1);
      const int flat = integral[y1 * (w + 1) + x1] - integral[y0 * (w + 1) + x1] - integral[y1 * (w + 1) + x0] +
                       integral[y0 * (w + 1) + x0];
      mask[y * w + x] = 2 * flat > (x1 - x0) * (y1 - y0);
    }
  return mask;
}

// Halves the plane: codes by 2x2 mean (rounded), the mask kept where at least half of the four
// fine pixels were kept (a band edge at the coarse scale stays a flat-region pixel).
Plane downsample(const Plane& p) {
  Plane q;
  q.width = p.width / 2;
  q.height = p.height / 2;
  q.code.resize(static_cast<std::size_t>(q.width) * q.height);
  q.mask.resize(q.code.size());
  for (int y = 0; y < q.height; ++y)
    for (int x = 0; x < q.width; ++x) {
      int sum = 0, kept = 0;
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const std::size_t i = static_cast<std::size_t>(2 * y + dy) * p.width + 2 * x + dx;
          sum += p.code[i];
          kept += p.mask[i];
        }
      q.code[y * q.width + x] = static_cast<std::uint16_t>((sum + 2) / 4);
      q.mask[y * q.width + x] = kept >= 2;
    }
  return q;
}

// Per-pixel contrast-banding values of one scale, pooled: the mean of the top `topk` fraction.
double pooled_banding(const Plane& p, int window, double topk,
                      const std::array<std::vector<std::uint8_t>, kMaxStep + 1>& visible) {
  const int w = p.width, h = p.height, r = window / 2;
  std::vector<double> c(static_cast<std::size_t>(w) * h, 0.0);
  std::vector<int> hist(kCodes, 0);
  // Sliding window along each row: a column of masked pixels leaves on the left and one enters
  // on the right, so the histogram costs O(window) per pixel instead of O(window^2).
  auto column = [&](int x, int y0, int y1, int delta) {
    if (x < 0 || x >= w) return;
    for (int y = y0; y < y1; ++y)
      if (p.mask[y * w + x]) hist[p.code[y * w + x]] += delta;
  };
  for (int y = 0; y < h; ++y) {
    const int y0 = std::max(0, y - r), y1 = std::min(h, y + r + 1);
    std::fill(hist.begin(), hist.end(), 0);
    for (int x = 0; x < r; ++x) column(x, y0, y1, +1);
    for (int x = 0; x < w; ++x) {
      column(x - r - 1, y0, y1, -1);
      column(x + r, y0, y1, +1);
      if (!p.mask[y * w + x]) continue;
      const double area = double(std::min(w, x + r + 1) - std::max(0, x - r)) * (y1 - y0);
      const int v = p.code[y * w + x];
      const double p0 = hist[v] / area;
      double best = 0.0;
      for (int k = 1; k <= kMaxStep; ++k)
        for (int u : {v + k, v - k}) {
          if (u < 0 || u >= kCodes) continue;
          if (!visible[k][std::min(u, v)]) continue;  // judged at the darker side of the step
          const double p1 = hist[u] / area;
          if (p1 <= 0.0) continue;
          best = std::max(best, k * p0 * p1 / (p0 + p1));
        }
      c[y * w + x] = best;
    }
  }
  if (c.empty()) return 0.0;
  const std::size_t n = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(topk * c.size())));
  std::nth_element(c.begin(), c.begin() + (n - 1), c.end(), std::greater<double>());
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) sum += c[i];
  return sum / n;
}

float srgb_encode(float linear) {
  const float v = std::clamp(linear, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

CambiResult cambi_luma(const std::vector<float>& luma, int width, int height, const CambiOptions& options) {
  if (width <= 0 || height <= 0 || luma.size() != static_cast<std::size_t>(width) * height)
    throw std::invalid_argument("cambi: luma size does not match width x height");
  if (options.source_bits < 1 || options.source_bits > 10) throw std::invalid_argument("cambi: source_bits in 1..10");
  if (options.scales < 1) throw std::invalid_argument("cambi: scales >= 1");
  if (!(options.topk > 0.0 && options.topk <= 1.0)) throw std::invalid_argument("cambi: topk in (0, 1]");

  // libvmaf's windows are 65 (contrast) and 7 (mask) pixels at 3840x2160; scaled to the image,
  // with floors so that our small evaluation images still see a neighbourhood.
  const double size_scale = (width + height) / (3840.0 + 2160.0);
  const int window = options.window > 0 ? options.window | 1 : odd_at_least(65.0 * size_scale, 9);
  const int mask_window = options.mask_window > 0 ? options.mask_window | 1 : odd_at_least(7.0 * size_scale, 5);
  const auto visible = visibility(options.tvi_threshold);

  Plane plane;
  plane.width = width;
  plane.height = height;
  plane.code.resize(luma.size());
  const int levels = (1 << options.source_bits) - 1;
  const int to10 = 1 << (10 - options.source_bits);
  for (std::size_t i = 0; i < luma.size(); ++i) {
    const float v = std::isfinite(luma[i]) ? std::clamp(luma[i], 0.0f, 1.0f) : 0.0f;
    plane.code[i] = static_cast<std::uint16_t>(std::lround(v * levels) * to10);
  }
  plane.mask = flat_mask(plane, mask_window);

  CambiResult result;
  for (int s = 0; s < options.scales; ++s) {
    if (s > 0) {
      if (plane.width < 4 || plane.height < 4) break;  // nothing left to see banding in
      plane = downsample(plane);
    }
    result.per_scale.push_back(pooled_banding(plane, window, options.topk, visible));
  }
  double sum = 0.0;
  for (double v : result.per_scale) sum += v;
  result.score = sum / result.per_scale.size();
  return result;
}

CambiResult cambi(const ImageRGB& image, const CambiOptions& options) {
  std::vector<float> luma(static_cast<std::size_t>(image.width) * image.height);
  for (std::size_t i = 0; i < luma.size(); ++i) {
    const float* p = &image.rgb[3 * i];
    luma[i] = 0.2126f * srgb_encode(p[0]) + 0.7152f * srgb_encode(p[1]) + 0.0722f * srgb_encode(p[2]);
  }
  return cambi_luma(luma, image.width, image.height, options);
}

}  // namespace px

// CAMBI, the contrast-aware multi-scale banding index (Tandon et al., PCS 2021; the banding
// metric of libvmaf), implemented from the paper's description for host-side evaluation: 0
// means no visible banding, larger means more. libvmaf's CAMBI cannot be called on an image in
// memory from Debian bookworm's packages, so this is our own implementation of the same steps:
//
//   1. display-encode (sRGB OETF, clamp), BT.709 luma, quantise to the source bit depth and
//      express it in 10-bit codes (an 8-bit value v becomes 4v, as libvmaf does);
//   2. spatial mask: a pixel counts only if most pixels of a small window around it have a
//      zero derivative (flat regions; texture and noise hide banding);
//   3. at each of `scales` scales (the image averaged down by 2 each time, the mask subsampled):
//      for every masked pixel of code L, over the masked pixels of a window around it,
//      c = max over k of  w_k * p(L) * p(L±k) / (p(L) + p(L±k))   (k = 1..4 codes)
//      where p are fractions of the window and w_k = k if a step of k codes at L is visible
//      (luminance Weber contrast above a threshold, gamma-2.4 display), else 0;
//   4. per scale, the mean of the top `topk` fraction of c over all pixels; CAMBI is the mean
//      over scales.
//
// Simplifications against libvmaf (document them beside any figure): no anti-dithering
// pre-filter, full-range luma, a pure gamma-2.4 display with a fixed black level for the
// visibility test instead of BT.1886 at a given peak, windows scaled to our small images with
// a floor, and the plain mean over scales. Scores are therefore on our own scale (at most 1:
// w_k <= 4 times at most 1/4), not libvmaf's 0-24; compare them with each other only.
#pragma once

#include "image/image_io.h"

#include <vector>

namespace px {

struct CambiOptions {
  int source_bits = 8;           // bit depth the image is shown at (8: our PNGs; 10: finer)
  int scales = 5;                // 1 = full resolution only
  int window = 0;                // odd side of the contrast window at full scale; 0 = from the size
  int mask_window = 0;           // odd side of the flatness window; 0 = from the size
  double topk = 0.2;             // fraction of the largest per-pixel values pooled per scale
  double tvi_threshold = 0.019;  // Weber contrast a step needs to be visible
};

struct CambiResult {
  double score = 0.0;
  std::vector<double> per_scale;  // pooled value of each scale, finest first
};

// `luma` is display-encoded luma in [0, 1], rows top to bottom (width * height values).
CambiResult cambi_luma(const std::vector<float>& luma, int width, int height, const CambiOptions& options = {});

// Linear RGB radiance, clamped and display-encoded as a display would show it.
CambiResult cambi(const ImageRGB& image, const CambiOptions& options = {});

}  // namespace px

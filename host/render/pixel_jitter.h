// Where in each pixel a frame's G-buffer ray and first path-traced sample go
// (CameraParams::jitter). A fixed position (the centre) makes every frame sample the same point
// of each pixel: temporal accumulation then converges to the value at that point, not to the
// pixel's mean, so edges stay jagged however many frames accumulate, and a pixel whose centre
// sees an emitter counts its light in full even where the emitter covers part of it. Moving the
// position every frame along the Halton (2, 3) sequence spreads the frames' points evenly over
// the pixel (any 2^k x 3^j consecutive frames hit every cell of a 2^k x 3^j grid once), so the
// accumulated value is the pixel's mean. The sequence has no period: frame f uses index f + 1
// (index 0 would be the corner (0, 0)).
#pragma once

#include <array>

namespace px {

enum class PixelJitter {
  Halton,  // Halton (2, 3) per frame (default)
  Centre,  // always (0.5, 0.5): every frame samples the pixel centre first
};

// The radical inverse of `index` in `base` (>= 2): its digits mirrored about the point, in [0, 1).
float radical_inverse(unsigned base, unsigned index);

// The frame's position (jx, jy) in [0, 1)^2 inside each pixel.
std::array<float, 2> pixel_jitter(PixelJitter mode, unsigned frame);

}  // namespace px

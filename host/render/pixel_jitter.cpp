#include "render/pixel_jitter.h"

#include <stdexcept>

namespace px {

float radical_inverse(unsigned base, unsigned index) {
  if (base < 2) throw std::invalid_argument("radical_inverse: base must be at least 2");
  // Digits accumulate as an integer over base^digits and divide once at the end (in double, so
  // that 32-bit indices keep every digit); the result is rounded down to the float below 1.
  double inv_base = 1.0 / base, scale = 1.0, value = 0.0;
  for (unsigned n = index; n > 0; n /= base) {
    scale *= inv_base;
    value += static_cast<double>(n % base) * scale;
  }
  const float v = static_cast<float>(value);
  return v < 1.0f ? v : 0x1.fffffep-1f;
}

std::array<float, 2> pixel_jitter(PixelJitter mode, unsigned frame) {
  if (mode == PixelJitter::Centre) return {0.5f, 0.5f};
  // Index frame + 1 (the sequence's 0 is the corner); past 2^32 - 1 frames it wraps.
  const unsigned index = frame + 1u;
  return {radical_inverse(2, index), radical_inverse(3, index)};
}

}  // namespace px

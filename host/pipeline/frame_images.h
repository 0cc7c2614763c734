// What the stages hand each other on one device: both eyes' images, full frame, each device
// writing only its own rows so that a pixel's index (and a row's byte offset) is the same on
// every device. Stage-private buffers (SVGF's state, staging for transfers) live in their units.
#pragma once

#include "cl/device_set.h"
#include "shared/types.h"

#include <array>

namespace px {

struct FrameImages {
  std::array<cl::Buffer, 2> radiance;  // float4: path traced / reprojected / denoised radiance
  std::array<cl::Buffer, 2> albedo;    // float4: mean primary albedo of the samples behind
                                       // `radiance` (SVGF demodulates by it)
  std::array<cl::Buffer, 2> gbuffer;   // GBufferTexel: this frame's primary hits
  cl::Buffer right_hits;               // Hit: the right eye's G-buffer rays' hits, where hole
                                       // filling starts its first samples (the G-buffer's rays)
  std::array<cl::Buffer, 2> rgba;      // uchar4: tonemapped
  cl::Buffer holes;                    // uint pixel indices reprojection could not fill (worst
                                       // case every pixel), appended in scanline order per group
  // Counters (uint), zeroed at the start of every frame and read after it.
  cl::Buffer hole_count;        // entries in `holes`
  cl::Buffer nonfinite_paths;   // paths dropped because their radiance was NaN / infinite
  cl::Buffer nonfinite_pixels;  // tonemapped pixels whose radiance was not finite

  // Full-frame buffers of a width x height image in `context`.
  static FrameImages allocate(const cl::Context& context, unsigned width, unsigned height);
  void zero_counters(const cl::CommandQueue& queue) const;
};

}  // namespace px

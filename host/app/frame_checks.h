// The checks every command makes before it writes or renders a frame: `render`'s frame loop,
// `preview` and `reference` all refuse a NaN camera and a non-finite image in the same words.
// They sit on their own so that each command shares one definition rather than a copy: a
// failure that reads differently per command is harder to recognise.
#pragma once

#include "image/image_io.h"
#include "scene/scene.h"

#include <array>
#include <string>

namespace px {

// Throws std::runtime_error when a pixel of either eye has a NaN or infinite channel. An image
// is either finite or the run fails: a NaN made before the path loop (camera, primary hit) is
// not caught by the kernels' per-path guard and would otherwise be written as a silently wrong
// image. `what` names the frame in the message ("frame 3", "preview").
void require_finite(const std::array<ImageRGB, 2>& eyes, const std::string& what);

// The camera at `time_s`, checked before rendering with it. Every key of a camera path is
// valid on load, but interpolating between two keys can still make position meet target (keys
// that swap them) or the view parallel to up: a NaN camera, whose rays miss everything, gave a
// silently black frame with exit 0. Throws std::runtime_error naming `what` and the time.
void check_camera(const Scene& scene, float time_s, const std::string& what);

}  // namespace px

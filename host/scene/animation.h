// Keyframe animation as glTF 2.0 defines it: tracks of times and values sampled with STEP,
// LINEAR (spherical for rotations) or CUBICSPLINE (Hermite) interpolation, channels that drive a
// node's translation, rotation or scale, and clips of channels that play together.
//
// One clock: a frame f is at time f / fps seconds, the same in `render`, `reference --frame`,
// `view` and on every MPI rank. A clip loops over its own length: at time t it is sampled at
// t mod duration (duration = its last key time over all its tracks), so frame 100 of a 1-second
// clip at 30 fps shows the pose at 10/30 s. Before a track's first key it holds the first value,
// after its last key the last (a clip whose tracks end at different times).
#pragma once

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include <string>
#include <vector>

namespace px {

enum class Interpolation { Step, Linear, CubicSpline };

// Values are (x, y, z, 0) for translations and scales and (x, y, z, w) quaternions for
// rotations. CUBICSPLINE keys hold three values each, in glTF's order: in-tangent, value,
// out-tangent (values.size() == 3 * times.size()); the others one per key.
struct KeyframeTrack {
  std::vector<double> times;  // seconds, strictly increasing
  std::vector<glm::dvec4> values;
  Interpolation interpolation = Interpolation::Linear;
};

// The track at time `t`. Rotations (rotation = true) are interpolated along the shorter arc
// (LINEAR: slerp) and returned normalised; every interpolation returns a key's value exactly at
// that key's time.
glm::dvec4 sample_track(const KeyframeTrack& track, double t, bool rotation);

// Spherical linear interpolation of unit quaternions along the shorter arc (q and -q are the
// same rotation); u = 0 gives a, u = 1 gives b (or -b).
glm::dquat slerp_shorter(const glm::dquat& a, const glm::dquat& b, double u);

enum class TrsPath { Translation, Rotation, Scale };

struct AnimationChannel {
  int node = -1;  // the glTF node index it drives
  TrsPath path = TrsPath::Translation;
  KeyframeTrack track;
};

struct AnimationClip {
  std::string name;  // glTF's, or "animation N" when it has none
  std::vector<AnimationChannel> channels;
  double duration = 0.0;  // the last key time over all channels
};

// The time within `clip` at scene time `t` (t mod duration; 0 for a clip of zero length).
double clip_time(const AnimationClip& clip, double t);

// Which clips play, from --animation: "all" (the default), "none", a clip's name, or its index.
// Throws std::invalid_argument naming the clips there are when `choice` matches none of them.
std::vector<int> select_clips(const std::vector<AnimationClip>& clips, const std::string& choice);

}  // namespace px

#include "scene/animation.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace px {

glm::dquat slerp_shorter(const glm::dquat& a, const glm::dquat& b_in, double u) {
  glm::dquat b = b_in;
  double c = glm::dot(a, b);
  if (c < 0.0) {  // the other sign of b is the shorter way round
    b = -b;
    c = -c;
  }
  if (c > 1.0 - 1e-12) {
    // Nearly the same rotation: sin(theta) ~ 0, and the linear blend is exact to rounding.
    return glm::normalize(
        glm::dquat(a.w + u * (b.w - a.w), a.x + u * (b.x - a.x), a.y + u * (b.y - a.y), a.z + u * (b.z - a.z)));
  }
  const double theta = std::acos(std::min(1.0, c));
  const double s = std::sin(theta);
  const double wa = std::sin((1.0 - u) * theta) / s, wb = std::sin(u * theta) / s;
  return glm::dquat(wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y, wa * a.z + wb * b.z);
}

namespace {

glm::dquat as_quat(const glm::dvec4& v) { return glm::dquat(v.w, v.x, v.y, v.z); }
glm::dvec4 as_vec(const glm::dquat& q) { return glm::dvec4(q.x, q.y, q.z, q.w); }

glm::dvec4 normalised_rotation(glm::dvec4 v) {
  const double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? v / len : glm::dvec4(0.0, 0.0, 0.0, 1.0);
}

}  // namespace

glm::dvec4 sample_track(const KeyframeTrack& track, double t, bool rotation) {
  const std::size_t n = track.times.size();
  if (n == 0) return rotation ? glm::dvec4(0.0, 0.0, 0.0, 1.0) : glm::dvec4(0.0);
  const bool cubic = track.interpolation == Interpolation::CubicSpline;
  // The value (not a tangent) of key k.
  auto value = [&](std::size_t k) { return track.values[cubic ? 3 * k + 1 : k]; };
  auto finish = [&](glm::dvec4 v) { return rotation ? normalised_rotation(v) : v; };
  if (!(t > track.times.front())) return finish(value(0));
  if (t >= track.times.back()) return finish(value(n - 1));
  // The key interval [k, k + 1] holding t: times[k] <= t < times[k + 1].
  const std::size_t k =
      static_cast<std::size_t>(std::upper_bound(track.times.begin(), track.times.end(), t) - track.times.begin()) - 1;
  const double t0 = track.times[k], t1 = track.times[k + 1];
  const double td = t1 - t0;
  const double u = td > 0.0 ? (t - t0) / td : 0.0;
  switch (track.interpolation) {
    case Interpolation::Step: return finish(value(k));
    case Interpolation::Linear:
      if (rotation)
        return as_vec(
            slerp_shorter(as_quat(normalised_rotation(value(k))), as_quat(normalised_rotation(value(k + 1))), u));
      return value(k) + u * (value(k + 1) - value(k));
    case Interpolation::CubicSpline: {
      // Hermite basis (glTF 2.0, Appendix C): the out-tangent of key k and the in-tangent of
      // key k + 1 are scaled by the interval's length.
      const double u2 = u * u, u3 = u2 * u;
      const glm::dvec4 p0 = value(k), p1 = value(k + 1);
      const glm::dvec4 m0 = td * track.values[3 * k + 2], m1 = td * track.values[3 * (k + 1)];
      return finish((2.0 * u3 - 3.0 * u2 + 1.0) * p0 + (u3 - 2.0 * u2 + u) * m0 + (-2.0 * u3 + 3.0 * u2) * p1 +
                    (u3 - u2) * m1);
    }
  }
  return finish(value(k));
}

double clip_time(const AnimationClip& clip, double t) {
  if (!(clip.duration > 0.0) || !std::isfinite(t)) return 0.0;
  const double r = std::fmod(t, clip.duration);
  return r < 0.0 ? r + clip.duration : r;
}

std::vector<int> select_clips(const std::vector<AnimationClip>& clips, const std::string& choice) {
  std::vector<int> out;
  if (choice == "none") return out;
  if (choice.empty() || choice == "all") {
    for (std::size_t i = 0; i < clips.size(); ++i) out.push_back(static_cast<int>(i));
    return out;
  }
  for (std::size_t i = 0; i < clips.size(); ++i)
    if (clips[i].name == choice) return {static_cast<int>(i)};
  if (!choice.empty() && std::all_of(choice.begin(), choice.end(), [](char c) { return c >= '0' && c <= '9'; }) &&
      choice.size() < 10) {
    const unsigned long i = std::stoul(choice);
    if (i < clips.size()) return {static_cast<int>(i)};
  }
  std::string list;
  for (std::size_t i = 0; i < clips.size(); ++i)
    list += (i ? ", " : "") + std::to_string(i) + " '" + clips[i].name + "'";
  throw std::invalid_argument("--animation " + choice + ": the scene has no such clip (" +
                              (clips.empty() ? std::string("it has no animations") : "its clips: " + list) +
                              "; or all, none)");
}

}  // namespace px

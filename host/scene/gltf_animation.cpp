// A glTF scene that moves or is skinned: its skins and animation clips read into the rig
// (scene_rig.h), and its triangles posed at rest.
#include "scene/gltf_converter.h"

#include <cmath>

namespace px::gltf {

void Converter::skins() {
  for (std::size_t si = 0; si < model_.skins.size(); ++si) {
    const tinygltf::Skin& s = model_.skins[si];
    const std::string what = "skin " + std::to_string(si);
    RigSkin skin;
    for (int j : s.joints) {
      if (j < 0 || std::size_t(j) >= model_.nodes.size())
        read_.fail(what + " names joint node " + std::to_string(j) + ", which does not exist");
      skin.joints.push_back(j);
    }
    if (s.inverseBindMatrices >= 0) {
      skin.inverse_bind = read_.matrices(s.inverseBindMatrices, what + " inverseBindMatrices");
      if (skin.inverse_bind.size() < skin.joints.size())
        read_.fail(what + ": " + std::to_string(skin.inverse_bind.size()) + " inverse bind matrices for " +
                   std::to_string(skin.joints.size()) + " joints");
      skin.inverse_bind.resize(skin.joints.size());
    } else {
      skin.inverse_bind.assign(skin.joints.size(), glm::dmat4(1.0));
    }
    rig_->skins.push_back(std::move(skin));
  }
  // Every vertex's joints must name one of its skin's joints.
  for (const RigMeshInstance& inst : rig_->instances) {
    if (inst.skin < 0) continue;
    const std::size_t joints = rig_->skins[std::size_t(inst.skin)].joints.size();
    for (int p : inst.primitives)
      for (const glm::vec4& j : rig_->primitives[std::size_t(p)].joints)
        for (int k = 0; k < 4; ++k)
          if (!(j[k] >= 0.0f && std::size_t(j[k]) < joints))
            read_.fail("node " + std::to_string(inst.node) + ": a vertex names joint " + std::to_string(j[k]) +
                       " of skin " + std::to_string(inst.skin) + ", which has " + std::to_string(joints));
  }
}

void Converter::animations() {
  for (std::size_t ai = 0; ai < model_.animations.size(); ++ai) {
    const tinygltf::Animation& a = model_.animations[ai];
    const std::string what = "animation " + std::to_string(ai);
    AnimationClip clip;
    clip.name = a.name.empty() ? what : a.name;
    for (std::size_t ci = 0; ci < a.channels.size(); ++ci) {
      const tinygltf::AnimationChannel& c = a.channels[ci];
      const std::string where = what + " channel " + std::to_string(ci);
      if (c.target_node < 0) continue;  // glTF: a channel without a node is for an extension
      if (std::size_t(c.target_node) >= model_.nodes.size())
        read_.fail(where + " targets node " + std::to_string(c.target_node) + ", which does not exist");
      AnimationChannel ch;
      ch.node = c.target_node;
      if (c.target_path == "translation")
        ch.path = TrsPath::Translation;
      else if (c.target_path == "rotation")
        ch.path = TrsPath::Rotation;
      else if (c.target_path == "scale")
        ch.path = TrsPath::Scale;
      else {
        unsupported_.add(c.target_path == "weights" ? "morph target weights" : "animation path " + c.target_path, what);
        continue;
      }
      if (rig_->nodes[std::size_t(c.target_node)].has_matrix) {
        unsupported_.add("channels on nodes given by a matrix", where);
        continue;
      }
      if (c.sampler < 0 || std::size_t(c.sampler) >= a.samplers.size())
        read_.fail(where + " names sampler " + std::to_string(c.sampler) + ", which does not exist");
      const tinygltf::AnimationSampler& s = a.samplers[std::size_t(c.sampler)];
      KeyframeTrack& track = ch.track;
      if (s.interpolation.empty() || s.interpolation == "LINEAR")
        track.interpolation = Interpolation::Linear;
      else if (s.interpolation == "STEP")
        track.interpolation = Interpolation::Step;
      else if (s.interpolation == "CUBICSPLINE")
        track.interpolation = Interpolation::CubicSpline;
      else
        read_.fail(where + ": unknown interpolation '" + s.interpolation + "'");
      for (const glm::vec4& t : read_.floats(s.input, {TINYGLTF_TYPE_SCALAR}, where + " input", false)) {
        if (!std::isfinite(t.x) || (!track.times.empty() && !(t.x > track.times.back())))
          read_.fail(where + ": key times must be finite and strictly increasing");
        // The glTF specification requires key times >= 0: a clip starts at time 0 and loops
        // over [0, its last key], so an earlier key could never be reached as the file meant it.
        if (t.x < 0.0f) read_.fail(where + ": key time " + std::to_string(t.x) + " is negative (glTF needs >= 0)");
        track.times.push_back(t.x);
      }
      const bool rotation = ch.path == TrsPath::Rotation;
      for (const glm::vec4& v :
           read_.floats(s.output, {rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3}, where + " output", rotation)) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(v.w))
          read_.fail(where + ": output values must be finite");
        track.values.push_back(glm::dvec4(v));
      }
      const std::size_t per_key = track.interpolation == Interpolation::CubicSpline ? 3 : 1;
      if (track.times.empty() || track.values.size() != per_key * track.times.size())
        read_.fail(where + ": " + std::to_string(track.times.size()) + " key times for " +
                   std::to_string(track.values.size()) + " output values" +
                   (per_key == 3 ? " (CUBICSPLINE has three per key)" : ""));
      clip.duration = std::max(clip.duration, track.times.back());
      clip.channels.push_back(std::move(ch));
    }
    rig_->clips.push_back(std::move(clip));
  }
}

void Converter::pose_at_rest() {
  // A rigid mesh on a node that a clip moves is drawn as an instance: its node's matrix places
  // it every frame, and its triangles are neither posed nor refitted; so is a still mesh that
  // several nodes draw. Not for skins, emitters (the light table samples world triangles), a
  // node that mirrors at rest, or when the options ask for flat copies.
  const bool instancing = options_.instancing && !rig_->clips.empty();
  if (instancing) {
    std::vector<int> all(rig_->clips.size());
    for (std::size_t c = 0; c < all.size(); ++c) all[c] = int(c);
    const std::vector<char> moves = moving_nodes(*rig_, all);
    const std::vector<glm::dmat4> world = rig_world_matrices(*rig_, 0.0, {});
    std::map<std::vector<int>, int> uses;  // rigid mesh instances per mesh (its primitives)
    for (const RigMeshInstance& inst : rig_->instances)
      if (inst.skin < 0) ++uses[inst.primitives];
    for (RigMeshInstance& inst : rig_->instances) {
      // Still meshes that other nodes draw too are stored once as well, as in a static file.
      bool ok = inst.skin < 0 && (moves[std::size_t(inst.node)] || uses[inst.primitives] >= 2) &&
                glm::determinant(glm::dmat3(world[std::size_t(inst.node)])) > 0.0;
      for (int p : inst.primitives) ok &= !scene_.materials.at(rig_->primitives[std::size_t(p)].material).is_emissive();
      inst.instance = ok ? 0 : -1;  // numbered by settle_rig_instances
    }
  }
  settle_rig(*rig_, scene_.triangles, scene_.stats, colours_out());
  if (instancing) settle_rig_instances(*rig_, scene_.triangles, scene_.stats, colours_out(), scene_.instancing);
  if (!rig_->clips.empty()) scene_.rig = std::move(rig_);
  rig_.reset();
}

}  // namespace px::gltf

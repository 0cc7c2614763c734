// load_scene: the one entry point from user input (a scene JSON file, an OBJ, or a built-in
// name) to a Scene. The JSON format is documented in scenes/README.md; every check here has a
// line there.
#include "scene/builtin_scenes.h"
#include "scene/instancing.h"
#include "scene/scene_rig.h"
#include "scene/scene_loader.h"
#include "scene/sun_path.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <unordered_set>
#include <sstream>

namespace px {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

std::string builtin_list() {
  std::string list;
  for (const std::string& n : builtin_scene_names()) list += (list.empty() ? "" : ", ") + n;
  return list;
}

// Grows [lo, hi] by the scene as its clips pose it over their length (a scene that moves: its
// triangles hold the rest pose), at kFramingSamples instants of the longest clip.
constexpr int kFramingSamples = 16;
void add_animated_bounds(const Scene& scene, glm::vec3& lo, glm::vec3& hi) {
  if (!scene.rig || scene.rig->clips.empty()) return;
  const SceneRig& rig = *scene.rig;
  std::vector<int> clips(rig.clips.size());
  double longest = 0.0;
  for (std::size_t c = 0; c < clips.size(); ++c) {
    clips[c] = static_cast<int>(c);
    longest = std::max(longest, rig.clips[c].duration);
  }
  if (!(longest > 0.0)) return;
  const auto grow = [&](const glm::vec3& p) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  };
  std::vector<SceneTriangle> world;
  SceneInstancing instancing = scene.instancing;
  for (int k = 1; k <= kFramingSamples; ++k) {
    const std::vector<glm::dmat4> matrices = rig_world_matrices(rig, longest * k / kFramingSamples, clips);
    pose_rig(rig, matrices, world);
    for (const SceneTriangle& t : world)
      for (const glm::vec3& p : t.p) grow(p);
    if (instancing.empty()) continue;
    rig_instance_matrices(rig, matrices, instancing);
    for (const MeshInstance& inst : instancing.instances) {
      const InstancedMesh& m = instancing.meshes[inst.mesh];
      for (std::size_t i = m.first; i < m.first + m.count; ++i)
        for (const glm::vec3& p : scene.triangles[i].p) grow(glm::vec3(inst.object_to_world * glm::vec4(p, 1.0f)));
    }
  }
}

// A camera that sees the whole bounding sphere of the scene from the +z side (the side OBJ
// exporters conventionally face), up = +y; of a scene that moves, the sphere around everywhere
// its clips take it, so that nothing leaves the view as it plays.
Camera frame_bounds(const Scene& scene) {
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for_each_drawn_triangle(scene, [&](const glm::vec3* p, std::size_t) {
    for (int c = 0; c < 3; ++c) {
      lo = glm::min(lo, p[c]);
      hi = glm::max(hi, p[c]);
    }
  });
  add_animated_bounds(scene, lo, hi);
  Camera cam;
  cam.vfov_deg = 45.0f;
  const glm::vec3 center = 0.5f * (lo + hi);
  const float radius = std::max(0.5f * glm::length(hi - lo), 1e-6f * std::max(1.0f, glm::length(center)));
  const float distance = radius / std::sin(glm::radians(0.5f * cam.vfov_deg));
  cam.target = center;
  cam.position = center + glm::vec3(0.0f, 0.0f, 1.05f * distance);
  cam.up = glm::vec3(0.0f, 1.0f, 0.0f);
  return cam;
}

bool has_light(const Scene& scene) {
  if (scene.sun.enabled || scene.sky.enabled) return true;
  for (const PunctualLight& l : scene.punctual_lights)
    if (l.intensity.x > 0.0f || l.intensity.y > 0.0f || l.intensity.z > 0.0f) return true;
  return std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) { return m.is_emissive(); });
}

bool is_mesh_extension(const std::string& ext) { return ext == ".obj" || ext == ".gltf" || ext == ".glb"; }

// An OBJ or glTF (by extension), with a camera: a glTF's own, else framed on the geometry.
Scene load_mesh_framed(const std::string& path, const SceneLoadOptions& options) {
  const std::string ext = lower(fs::path(path).extension().string());
  bool has_camera = false;
  Scene scene = ext == ".obj" ? load_obj(path) : load_gltf(path, options, &has_camera);
  // Before framing: a camera framed on out-of-range geometry overflows, and the error would
  // then be about the camera, not the vertices.
  check_coordinate_range(scene, path, /*warn=*/false);  // load_scene warns, once
  if (!has_camera) scene.camera = frame_bounds(scene);
  return scene;
}

// What load_scene does about light, in one warning line when it changes or misses something.
void apply_sky_mode(Scene& scene, const std::string& source, SkyMode mode) {
  if (mode == SkyMode::kOn) {
    if (scene.sky.enabled) return;  // the scene's own sky stays
    scene.sky = default_sky();
    scene.stats.warnings.push_back(source + ": lit by the default sky (--sky on)");
    return;
  }
  if (has_light(scene)) return;
  if (mode == SkyMode::kOff) {
    scene.stats.warnings.push_back(source +
                                   ": no light source (no emissive material, sun or sky) and --sky off; "
                                   "the image will be black");
    return;
  }
  scene.sky = default_sky();
  scene.stats.warnings.push_back(source +
                                 ": no light source (no emissive material, sun or sky); lit by a default "
                                 "sky instead (--sky off keeps it unlit)");
}

// ---------------------------------------------------------------------------------------------
// Typed access to the JSON with errors that name the file and the key.

class SceneFileReader {
 public:
  explicit SceneFileReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw SceneError(file_ + ": '" + key + "': " + what);
  }

  void require_object(const json& v, const std::string& key) const {
    if (!v.is_object()) fail(key, std::string("must be an object, got ") + v.type_name());
  }

  // Unknown keys are refused: a typo would otherwise silently fall back to a default.
  void check_keys(const json& obj, const std::string& prefix, std::initializer_list<std::string_view> allowed) const {
    for (const auto& [key, value] : obj.items()) {
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
      std::string list;
      for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
      fail(prefix + key, "unknown key (allowed here: " + list + ")");
    }
  }

  float number(const json& v, const std::string& key) const {
    if (!v.is_number()) fail(key, std::string("must be a number, got ") + v.type_name());
    const double d = v.get<double>();
    if (!std::isfinite(d) || std::abs(d) > double(std::numeric_limits<float>::max()))
      fail(key, "must be a finite number");
    return float(d);
  }

  glm::vec3 vec3(const json& v, const std::string& key) const {
    if (!v.is_array() || v.size() != 3)
      fail(key, std::string("must be an array of 3 numbers, got ") +
                    (v.is_array() ? "an array of " + std::to_string(v.size()) : std::string(v.type_name())));
    return glm::vec3(number(v[0], key + "[0]"), number(v[1], key + "[1]"), number(v[2], key + "[2]"));
  }

  glm::vec3 non_negative_vec3(const json& v, const std::string& key) const {
    const glm::vec3 c = vec3(v, key);
    if (c.x < 0.0f || c.y < 0.0f || c.z < 0.0f) fail(key, "components must not be negative");
    return c;
  }

  std::string string(const json& v, const std::string& key) const {
    if (!v.is_string()) fail(key, std::string("must be a string, got ") + v.type_name());
    return v.get<std::string>();
  }

  bool boolean(const json& v, const std::string& key) const {
    if (!v.is_boolean()) fail(key, std::string("must be true or false, got ") + v.type_name());
    return v.get<bool>();
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// Checks made before the document is built, by a SAX pass that keeps no values:
//  - nesting depth is bounded: nlohmann's DOM parser is iterative, but copying or comparing a
//    value recurses, and a generator_params nested ~70,000 deep overflowed the stack there;
//  - duplicate keys are refused (nlohmann keeps the last one silently). One hash set per open
//    object keeps this linear; nlohmann's callback parser, used for it before, rescans the
//    enclosing array for discarded values after every object (quadratic: a 160k-key
//    camera_path took 17 s).
class ScanKeysAndDepth : public nlohmann::json_sax<json> {
 public:
  static constexpr std::size_t kMaxDepth = 128;

  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override {
    if (!open()) return false;
    if (objects_ == keys_.size()) keys_.emplace_back();
    keys_[objects_++].clear();
    return true;
  }
  bool key(string_t& k) override {
    if (!keys_[objects_ - 1].insert(k).second) {
      duplicate = k;
      return false;
    }
    return true;
  }
  bool end_object() override {
    --objects_;
    --depth_;
    return true;
  }
  bool start_array(std::size_t) override { return open(); }
  bool end_array() override {
    --depth_;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    syntax_error = true;
    return false;
  }

  std::string duplicate;
  bool too_deep = false, syntax_error = false;

 private:
  bool open() {
    if (++depth_ > kMaxDepth) too_deep = true;
    return !too_deep;
  }
  std::size_t depth_ = 0, objects_ = 0;
  std::vector<std::unordered_set<std::string>> keys_;  // reused across objects at a depth
};

json parse_json_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError("cannot open scene file '" + path + "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string text = std::move(ss).str();

  ScanKeysAndDepth scan;
  json::sax_parse(text, &scan, json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/true);
  if (scan.too_deep)
    throw SceneError(path + ": objects and arrays nested deeper than " + std::to_string(ScanKeysAndDepth::kMaxDepth) +
                     " levels (a scene file needs a handful)");
  if (!scan.duplicate.empty()) throw SceneError(path + ": '" + scan.duplicate + "': duplicate key");
  // A syntax error is reported by the DOM parse below, which says where.
  json doc;
  try {
    doc = json::parse(text, nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const json::exception& e) {
    // e.what() is "[json.exception.parse_error.101] parse error at line L, column C: ..."
    std::string what = e.what();
    if (const std::size_t close = what.find("] "); what.rfind("[json.", 0) == 0 && close != std::string::npos)
      what = what.substr(close + 2);
    throw SceneError(path + ": invalid JSON: " + what);
  }
  return doc;
}

// A scene file's "lights": point and spot lights added to those of the mesh (scene.h,
// PunctualLight).
void read_punctual_lights(const SceneFileReader& r, const json& list, Scene& scene) {
  if (!list.is_array()) r.fail("lights", std::string("must be an array, got ") + list.type_name());
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string key = "lights[" + std::to_string(i) + "]";
    const json& l = list[i];
    r.require_object(l, key);
    r.check_keys(l, key + ".",
                 {"type", "position", "intensity", "color", "direction", "inner_cone_deg", "outer_cone_deg"});
    for (const char* required : {"type", "position", "intensity"})
      if (!l.contains(required)) r.fail(key + "." + required, "missing");
    PunctualLight light;
    const std::string type = r.string(l["type"], key + ".type");
    if (type != "point" && type != "spot") r.fail(key + ".type", "must be \"point\" or \"spot\", got '" + type + "'");
    light.spot = type == "spot";
    light.position = r.vec3(l["position"], key + ".position");
    const json& intensity = l["intensity"];
    if (intensity.is_number()) {
      const float candela = r.number(intensity, key + ".intensity");
      if (candela < 0.0f) r.fail(key + ".intensity", "must not be negative");
      const glm::vec3 colour = l.contains("color") ? r.non_negative_vec3(l["color"], key + ".color") : glm::vec3(1.0f);
      light.intensity = candela * colour;
    } else {
      if (l.contains("color")) r.fail(key + ".color", "only allowed with a number intensity (an array is the colour)");
      light.intensity = r.non_negative_vec3(intensity, key + ".intensity");
    }
    if (!light.spot) {
      for (const char* spot_only : {"direction", "inner_cone_deg", "outer_cone_deg"})
        if (l.contains(spot_only)) r.fail(key + "." + spot_only, "only allowed for a spot light");
    } else {
      if (!l.contains("direction")) r.fail(key + ".direction", "missing (a spot light needs its axis)");
      const glm::vec3 d = r.vec3(l["direction"], key + ".direction");
      const float len = glm::length(d);
      if (!(len > 0.0f) || !std::isfinite(len)) r.fail(key + ".direction", "must be a non-zero vector");
      light.direction = d / len;
      float inner = 0.0f, outer = 45.0f;
      if (l.contains("outer_cone_deg")) outer = r.number(l["outer_cone_deg"], key + ".outer_cone_deg");
      if (l.contains("inner_cone_deg")) inner = r.number(l["inner_cone_deg"], key + ".inner_cone_deg");
      if (!(outer > 0.0f && outer <= 90.0f)) r.fail(key + ".outer_cone_deg", "must be within (0, 90] degrees");
      if (!(inner >= 0.0f && inner < outer))
        r.fail(key + ".inner_cone_deg", "must be within [0, outer_cone_deg) degrees");
      light.inner_cone_rad = glm::radians(inner);
      light.outer_cone_rad = glm::radians(outer);
    }
    scene.punctual_lights.push_back(light);
  }
}

Scene load_scene_file(const std::string& path, const SceneLoadOptions& options) {
  const json doc = parse_json_file(path);
  const SceneFileReader r(path);
  if (!doc.is_object()) throw SceneError(path + ": the scene file must hold a JSON object");
  r.check_keys(doc, "",
               {"name", "mesh", "generator", "generator_params", "meters_per_unit", "ipd_m", "camera", "camera_path",
                "sun", "sky", "two_sided_emitters", "lights"});

  // The base scene: a mesh or a generator, exactly one.
  const bool has_mesh = doc.contains("mesh"), has_generator = doc.contains("generator");
  if (has_mesh == has_generator)
    throw SceneError(path + ": needs exactly one of 'mesh' (an OBJ, glTF or GLB path) or 'generator' (" +
                     builtin_list() + ")");
  if (doc.contains("generator_params") && !has_generator)
    r.fail("generator_params", "only allowed together with 'generator'");
  Scene scene;
  if (has_mesh) {
    const std::string mesh = r.string(doc["mesh"], "mesh");
    if (mesh.empty()) r.fail("mesh", "must not be empty");
    const fs::path mesh_path = fs::path(path).parent_path() / mesh;
    if (!is_mesh_extension(lower(mesh_path.extension().string())))
      r.fail("mesh", "'" + mesh + "' is not an .obj, .gltf or .glb file");
    try {
      scene = load_mesh_framed(mesh_path.string(), options);
    } catch (const SceneError& e) {
      r.fail("mesh", e.what());
    }
  } else {
    const std::string generator = r.string(doc["generator"], "generator");
    const auto& names = builtin_scene_names();
    if (std::find(names.begin(), names.end(), generator) == names.end())
      r.fail("generator", "unknown generator '" + generator + "' (known: " + builtin_list() + ")");
    json params = json::object();
    if (doc.contains("generator_params")) {
      params = doc["generator_params"];
      r.require_object(params, "generator_params");
    }
    try {
      scene = make_builtin_scene(generator, params);
    } catch (const SceneError& e) {
      r.fail("generator_params", e.what());
    }
  }
  scene.name = doc.contains("name") ? r.string(doc["name"], "name") : fs::path(path).stem().string();
  // Emitters light their front face only (pbrt, Mitsuba and the references published with
  // scenes like the Cornell box agree); some assets were made for renderers that emit both ways.
  if (doc.contains("two_sided_emitters") && r.boolean(doc["two_sided_emitters"], "two_sided_emitters"))
    for (Material& m : scene.materials) m.two_sided = true;

  if (doc.contains("meters_per_unit")) {
    const float m = r.number(doc["meters_per_unit"], "meters_per_unit");
    if (!(m > 0.0f)) r.fail("meters_per_unit", "must be positive");
    scene.meters_per_unit = m;
  }
  if (doc.contains("ipd_m")) {
    const float ipd = r.number(doc["ipd_m"], "ipd_m");
    if (ipd < 0.0f || ipd > 1.0f) r.fail("ipd_m", "must be within [0, 1] metres");
    scene.ipd_m = ipd;
  }

  if (doc.contains("camera")) {
    const json& cam = doc["camera"];
    r.require_object(cam, "camera");
    r.check_keys(cam, "camera.", {"position", "target", "up", "vfov_deg"});
    if (cam.contains("position")) scene.camera.position = r.vec3(cam["position"], "camera.position");
    if (cam.contains("target")) scene.camera.target = r.vec3(cam["target"], "camera.target");
    if (cam.contains("up")) scene.camera.up = r.vec3(cam["up"], "camera.up");
    if (cam.contains("vfov_deg")) {
      const float fov = r.number(cam["vfov_deg"], "camera.vfov_deg");
      if (!(fov > 0.0f && fov < 180.0f)) r.fail("camera.vfov_deg", "must be within (0, 180) degrees");
      scene.camera.vfov_deg = fov;
    }
  }
  // Checked on the merged camera, whichever fields came from the generator.
  if (scene.camera.position == scene.camera.target)
    r.fail("camera.position", "equals camera.target (no view direction)");
  {
    const glm::vec3 forward = scene.camera.target - scene.camera.position;
    const glm::vec3 side = glm::cross(forward, scene.camera.up);
    if (!(glm::dot(side, side) > 0.0f)) r.fail("camera.up", "is zero or parallel to the view direction");
  }

  if (doc.contains("camera_path")) {
    const json& path_json = doc["camera_path"];
    if (!path_json.is_array()) r.fail("camera_path", std::string("must be an array, got ") + path_json.type_name());
    std::vector<CameraKey> keys;
    for (std::size_t i = 0; i < path_json.size(); ++i) {
      const std::string key = "camera_path[" + std::to_string(i) + "]";
      const json& k = path_json[i];
      r.require_object(k, key);
      r.check_keys(k, key + ".", {"time", "position", "target"});
      for (const char* required : {"time", "position", "target"})
        if (!k.contains(required)) r.fail(key + "." + required, "missing");
      CameraKey ck;
      ck.time = r.number(k["time"], key + ".time");
      ck.position = r.vec3(k["position"], key + ".position");
      ck.target = r.vec3(k["target"], key + ".target");
      if (ck.position == ck.target) r.fail(key + ".position", "equals the key's target");
      if (!keys.empty() && !(ck.time > keys.back().time))
        r.fail(key + ".time", "must be greater than the previous key's time");
      keys.push_back(ck);
    }
    scene.camera_path = std::move(keys);
  }

  if (doc.contains("sun")) {
    const json& sun = doc["sun"];
    r.require_object(sun, "sun");
    r.check_keys(sun, "sun.", {"enabled", "direction", "keys", "radiance", "angular_radius_deg"});
    scene.sun.enabled = sun.contains("enabled") ? r.boolean(sun["enabled"], "sun.enabled") : true;
    if (sun.contains("keys") && sun.contains("direction"))
      r.fail("sun.direction", "not allowed together with sun.keys (each key gives the direction at its time)");
    if (sun.contains("keys")) {
      // A sun that moves, keyed like the camera path (sun_path.h evaluates it, SceneAnimator
      // poses it every frame); until then the first key's direction.
      const json& keys_json = sun["keys"];
      if (!keys_json.is_array()) r.fail("sun.keys", std::string("must be an array, got ") + keys_json.type_name());
      std::vector<SunKey> keys;
      for (std::size_t i = 0; i < keys_json.size(); ++i) {
        const std::string key = "sun.keys[" + std::to_string(i) + "]";
        const json& k = keys_json[i];
        r.require_object(k, key);
        r.check_keys(k, key + ".", {"time", "direction"});
        for (const char* required : {"time", "direction"})
          if (!k.contains(required)) r.fail(key + "." + required, "missing");
        SunKey sk;
        sk.time = r.number(k["time"], key + ".time");
        sk.direction = r.vec3(k["direction"], key + ".direction");
        keys.push_back(sk);
      }
      std::string bad_key, what;
      if (!check_sun_keys(keys, "sun.keys", bad_key, what)) r.fail(bad_key, what);
      for (SunKey& k : keys) k.direction = glm::normalize(k.direction);
      scene.sun.direction = keys.front().direction;
      scene.sun_path = std::move(keys);
    }
    if (sun.contains("direction")) {
      const glm::vec3 d = r.vec3(sun["direction"], "sun.direction");
      const float len = glm::length(d);
      if (!(len > 0.0f) || !std::isfinite(len)) r.fail("sun.direction", "must be a non-zero vector");
      scene.sun.direction = d / len;
    }
    if (sun.contains("radiance")) scene.sun.radiance = r.non_negative_vec3(sun["radiance"], "sun.radiance");
    if (sun.contains("angular_radius_deg")) {
      const float a = r.number(sun["angular_radius_deg"], "sun.angular_radius_deg");
      if (!(a > 0.0f && a < 90.0f)) r.fail("sun.angular_radius_deg", "must be within (0, 90) degrees");
      scene.sun.angular_radius_deg = a;
    }
  }
  if (doc.contains("lights")) read_punctual_lights(r, doc["lights"], scene);
  if (doc.contains("sky")) {
    const json& sky = doc["sky"];
    r.require_object(sky, "sky");
    r.check_keys(sky, "sky.", {"enabled", "zenith", "horizon", "ground"});
    scene.sky.enabled = sky.contains("enabled") ? r.boolean(sky["enabled"], "sky.enabled") : true;
    if (sky.contains("zenith")) scene.sky.zenith = r.non_negative_vec3(sky["zenith"], "sky.zenith");
    if (sky.contains("horizon")) scene.sky.horizon = r.non_negative_vec3(sky["horizon"], "sky.horizon");
    if (sky.contains("ground")) scene.sky.ground = r.non_negative_vec3(sky["ground"], "sky.ground");
  }
  return scene;
}

bool is_plain_file(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

Scene load_scene_unchecked(const std::string& spec, const SceneLoadOptions& options);

}  // namespace

Sky default_sky() {
  Sky sky;
  sky.enabled = true;
  sky.zenith = {0.55f, 0.65f, 0.85f};
  sky.horizon = {0.95f, 0.95f, 0.95f};
  sky.ground = {0.3f, 0.28f, 0.26f};
  return sky;
}

void check_coordinate_range(Scene& scene, const std::string& source, bool warn) {
  char value[32];
  auto refuse = [&](const std::string& what, float v) {
    std::snprintf(value, sizeof value, "%g", double(v));
    char limit[32];
    std::snprintf(limit, sizeof limit, "%g", double(kMaxSceneCoordinate));
    throw SceneError(source + ": " + what + " has a coordinate of " + value + " units, beyond the +-" + limit +
                     " that 32-bit float ray tracing handles; scale the scene down or move it nearer the origin");
  };
  auto check = [&](const glm::vec3& p, const std::string& what) {
    for (int c = 0; c < 3; ++c)
      if (!(std::abs(p[c]) <= kMaxSceneCoordinate)) refuse(what, p[c]);
  };
  // Per vertex, the name is made only when it is needed (30M strings at 10M triangles had taken
  // a sixth of a warm start).
  auto check_vertex = [&](const glm::vec3& p, std::size_t triangle) {
    if (!(std::abs(p.x) <= kMaxSceneCoordinate && std::abs(p.y) <= kMaxSceneCoordinate &&
          std::abs(p.z) <= kMaxSceneCoordinate))
      check(p, "triangle " + std::to_string(triangle));
  };
  // Instances are checked where they place their meshes (a mesh's own coordinates may be small
  // and its instances far).
  // One pass for the bounds and whether every coordinate is in range (NaN is not); only when one
  // is not are the triangles searched again, to name the first such. Only the bounds' extent and
  // farthest coordinate are used below, which a zero bound's sign does not change.
  const DrawnBounds bounds = drawn_bounds(scene);
  const glm::vec3 lo = bounds.lo, hi = bounds.hi;
  float far = 0.0f;
  if (!bounds.in_range)
    for_each_drawn_triangle(scene, [&](const glm::vec3* ps, std::size_t i) {
      for (int c = 0; c < 3; ++c) check_vertex(ps[c], i);
    });
  // Every vertex is within [lo, hi], so the farthest coordinate is a corner's.
  if (bounds.any)
    far = std::max({std::abs(lo.x), std::abs(lo.y), std::abs(lo.z), std::abs(hi.x), std::abs(hi.y), std::abs(hi.z)});
  check(scene.camera.position, "the camera position");
  check(scene.camera.target, "the camera target");
  for (std::size_t i = 0; i < scene.camera_path.size(); ++i) {
    check(scene.camera_path[i].position, "camera_path[" + std::to_string(i) + "].position");
    check(scene.camera_path[i].target, "camera_path[" + std::to_string(i) + "].target");
  }
  // A float near `far` is resolved to about far * 2^-23, and ray origins are pushed off surfaces
  // by 256 such steps. Far enough out the image turns visibly noisy (docs/measurements.md,
  // coordinate range); warn from a distance of 1e5 extents on.
  const float extent = scene.triangles.empty() ? 0.0f : glm::length(hi - lo);
  if (warn && extent > 0.0f && far > 1e5f * extent) {
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "%s: the geometry lies up to %g units from the origin but spans only %g: at that distance "
                  "32-bit floats resolve about %g units, so surfaces may show holes or noise; recentre it",
                  source.c_str(), double(far), double(extent), double(far * std::numeric_limits<float>::epsilon()));
    scene.stats.warnings.push_back(buf);
  }
}

Scene load_scene(const std::string& spec, const SceneLoadOptions& options) {
  Scene scene = load_scene_unchecked(spec, options);
  check_coordinate_range(scene, spec);
  apply_sky_mode(scene, spec, options.sky);
  return scene;
}

namespace {

Scene load_scene_unchecked(const std::string& spec, const SceneLoadOptions& options) {
  const fs::path p(spec);
  const std::string ext = lower(p.extension().string());
  if (is_plain_file(p)) {
    if (ext == ".json") return load_scene_file(spec, options);
    if (is_mesh_extension(ext)) return load_mesh_framed(spec, options);
    throw SceneError("scene '" + spec +
                     "': unsupported file type (expected a .json scene file, an .obj, .gltf or .glb)");
  }
  const auto& names = builtin_scene_names();
  if (std::find(names.begin(), names.end(), spec) != names.end()) return make_builtin_scene(spec);
  std::error_code ec;
  if (fs::exists(p, ec)) throw SceneError("scene '" + spec + "': not a regular file");
  if (ext == ".json" || is_mesh_extension(ext)) throw SceneError("scene file '" + spec + "' not found");
  throw SceneError("unknown scene '" + spec + "': no such file, and not a built-in scene (" + builtin_list() + ")");
}

}  // namespace

}  // namespace px

// The Cornell box, written from the measurements Cornell University publishes ("Cornell Box
// Data", graphics.cornell.edu/online/box/data.html): millimetres, a room of about
// 556 x 548.8 x 559.2 with slightly non-square walls, a short and a tall block, and a
// 130 x 105 mm light under the ceiling. Reflectances and the light's emission are those of the
// widely used OBJ version (Kd white 0.725 0.71 0.68, red 0.63 0.065 0.05, green 0.14 0.45
// 0.091; Ke 17 12 4).
//
// Orientation: the data is right-handed with y up and the camera at z = -800 looking down +z.
// Looking down +z with y up, camera-right is -x, so the red wall (x ~ 556) is on the left of
// the image and the green wall (x = 0) on the right, as in the classic photograph.
#include "scene/builtin_scenes.h"
#include "scene/primitives.h"

namespace px {

namespace {

// The quad a b c d (published vertex order) seen from the point `toward`: the room's interior
// for walls, outside for blocks.
void append_quad_seen_from(std::vector<SceneTriangle>& tris, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d,
                           glm::vec3 toward, std::uint32_t material) {
  append_quad_facing(tris, a, b, c, d, toward - 0.25f * (a + b + c + d), material);
}

// A block: the published top face (four corners at height `h`) extruded down to the floor.
// Its sides face away from the block's axis. There is no bottom: it stands on the floor, where
// no ray can reach it.
void append_block(std::vector<SceneTriangle>& tris, const glm::vec3 (&top)[4], std::uint32_t material) {
  const glm::vec3 center = 0.25f * (top[0] + top[1] + top[2] + top[3]);
  const glm::vec3 above = center + glm::vec3(0.0f, 1000.0f, 0.0f);
  append_quad_seen_from(tris, top[0], top[1], top[2], top[3], above, material);
  for (int i = 0; i < 4; ++i) {
    const glm::vec3 a = top[i], b = top[(i + 1) % 4];
    const glm::vec3 a0(a.x, 0.0f, a.z), b0(b.x, 0.0f, b.z);
    // Seen from outside: the midpoint of the side pushed away from the block's vertical axis.
    const glm::vec3 mid = 0.5f * (a0 + b);
    const glm::vec3 away = mid + (mid - glm::vec3(center.x, mid.y, center.z));
    append_quad_seen_from(tris, a0, b0, b, a, away, material);
  }
}

}  // namespace

Scene make_cornell_scene(const nlohmann::json& params, bool glossy) {
  const char* generator = glossy ? "cornell-glossy" : "cornell";
  check_generator_params(generator, params, {});

  Scene scene;
  scene.name = generator;
  scene.meters_per_unit = 0.001f;  // millimetres
  enum : std::uint32_t { kWhite, kRed, kGreen, kLight, kTall, kMirror };
  scene.materials.push_back(diffuse_material("white", {0.725f, 0.71f, 0.68f}));
  scene.materials.push_back(diffuse_material("red", {0.63f, 0.065f, 0.05f}));
  scene.materials.push_back(diffuse_material("green", {0.14f, 0.45f, 0.091f}));
  Material light = diffuse_material("light", glm::vec3(0.78f));
  light.emission = glm::vec3(17.0f, 12.0f, 4.0f);
  scene.materials.push_back(light);
  std::uint32_t tall_material = kWhite;
  if (glossy) {
    Material tall;
    tall.name = "glossy";
    tall.diffuse = glm::vec3(0.1f);
    tall.specular = glm::vec3(0.8f);
    tall.roughness = 0.2f;  // GGX alpha
    scene.materials.push_back(tall);
    Material mirror;
    mirror.name = "mirror";
    mirror.diffuse = glm::vec3(0.0f);
    mirror.specular = glm::vec3(0.95f);
    mirror.roughness = 0.0f;
    mirror.mirror = true;
    scene.materials.push_back(mirror);
    tall_material = kTall;
  }

  auto& tris = scene.triangles;
  const glm::vec3 room_center(278.0f, 274.4f, 279.6f);
  // Floor, ceiling, back wall, right (green, x = 0) and left (red, x ~ 556) walls; the front
  // (z = 0) is open towards the camera.
  append_quad_seen_from(tris, {552.8f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 559.2f}, {549.6f, 0.0f, 559.2f},
                        room_center, kWhite);
  append_quad_seen_from(tris, {556.0f, 548.8f, 0.0f}, {556.0f, 548.8f, 559.2f}, {0.0f, 548.8f, 559.2f},
                        {0.0f, 548.8f, 0.0f}, room_center, kWhite);
  append_quad_seen_from(tris, {549.6f, 0.0f, 559.2f}, {0.0f, 0.0f, 559.2f}, {0.0f, 548.8f, 559.2f},
                        {556.0f, 548.8f, 559.2f}, room_center, kWhite);
  append_quad_seen_from(tris, {0.0f, 0.0f, 559.2f}, {0.0f, 0.0f, 0.0f}, {0.0f, 548.8f, 0.0f}, {0.0f, 548.8f, 559.2f},
                        room_center, kGreen);
  append_quad_seen_from(tris, {552.8f, 0.0f, 0.0f}, {549.6f, 0.0f, 559.2f}, {556.0f, 548.8f, 559.2f},
                        {556.0f, 548.8f, 0.0f}, room_center, kRed);

  // The light: published at the ceiling's height; lowered by 0.1 mm so it does not coincide
  // with the ceiling (coplanar surfaces make the nearest hit a coin toss). It emits downwards.
  const float light_y = 548.7f;
  append_quad_seen_from(tris, {343.0f, light_y, 227.0f}, {343.0f, light_y, 332.0f}, {213.0f, light_y, 332.0f},
                        {213.0f, light_y, 227.0f}, {278.0f, 0.0f, 279.5f}, kLight);

  const glm::vec3 short_block[4] = {
      {130.0f, 165.0f, 65.0f}, {82.0f, 165.0f, 225.0f}, {240.0f, 165.0f, 272.0f}, {290.0f, 165.0f, 114.0f}};
  const glm::vec3 tall_block[4] = {
      {423.0f, 330.0f, 247.0f}, {265.0f, 330.0f, 296.0f}, {314.0f, 330.0f, 456.0f}, {472.0f, 330.0f, 406.0f}};
  append_block(tris, short_block, kWhite);
  append_block(tris, tall_block, tall_material);

  if (glossy) {
    // In front of the tall block, clear of both blocks and the red wall; 1 mm above the floor
    // so it touches nothing.
    const float radius = 80.0f;
    append_icosphere(tris, {400.0f, radius + 1.0f, 130.0f}, radius, 4, kMirror);
  }

  // The published camera: 35 mm focal length on a 25 mm film -> vfov = 2 atan(12.5 / 35).
  scene.camera.position = {278.0f, 273.0f, -800.0f};
  scene.camera.target = {278.0f, 273.0f, 0.0f};
  scene.camera.up = {0.0f, 1.0f, 0.0f};
  scene.camera.vfov_deg = 39.3f;
  // A slow sideways dolly, 60 mm each way over 4 s and back, so a looped playback is seamless.
  const glm::vec3 target(278.0f, 273.0f, 0.0f);
  scene.camera_path = {
      {0.0f, {278.0f, 273.0f, -800.0f}, target},
      {2.0f, {338.0f, 273.0f, -800.0f}, target},
      {6.0f, {218.0f, 273.0f, -800.0f}, target},
      {8.0f, {278.0f, 273.0f, -800.0f}, target},
  };
  return scene;
}

}  // namespace px

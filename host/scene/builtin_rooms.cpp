// "rooms": a closed building of square rooms on a grid, each lit by many small ceiling lamps of
// different colours and powers, and nothing else (no sun, no sky). It is the many-lights case
// of issue 49: with 1,024 emitters, most of them behind walls for any shading point, picking a
// lamp by power alone wastes most shadow rays, which is what a light tree or ReSTIR improve on.
//
// Layout (metres, y up): `grid` x `grid` rooms on a 4 m pitch, 3 m high. Walls are 0.2 m thick
// solid boxes centred on the grid lines; every wall between two rooms has a doorway (1.2 x 2.2 m)
// in its middle, so neighbouring rooms see into each other; the outer walls have none. A
// pillar stands at every grid node, so wall pieces meet without overlapping (overlapping boxes
// would give coplanar faces of different colours). One floor quad and one ceiling quad span the
// building.
//
// Lamps: `lamps` x `lamps` per room on a jittered grid under the ceiling, 1 cm below it (coplanar
// faces make the nearest hit a coin toss), one-sided, facing down; each its own material. Sides
// vary 2x (area 4x) and radiance 6x (log-uniform), so lamp powers span about 24x; colours are
// warm, cool or neutral with a small random tint, scaled to the same luminance before the
// radiance factor. All drawn from `seed` (splitmix64: the same on every platform).
//
// Exposure: radiance relative to the renderer's exposure 1. With the default lamps the floor
// under them receives roughly 0.2 x kBaseRadiance of direct irradiance, about double with the
// bounces off the walls, so a floor of albedo 0.45 comes out near 0.5.
//
// Camera: in room (1, 1) (x, z in [4, 8] with the default pitch), eye height 1.6 m, looking
// through the doorway in the wall x = 8 into room (2, 1); the path walks half a metre towards
// the doorway and back over 8 s.
#include "scene/builtin_scenes.h"
#include "scene/primitives.h"

#include <algorithm>
#include <cmath>

namespace px {

namespace {

constexpr float kPitch = 4.0f;      // room size, wall centre to wall centre
constexpr float kHeight = 3.0f;     // floor to ceiling
constexpr float kWall = 0.2f;       // wall thickness
constexpr float kDoorWidth = 1.2f;  // doorway between neighbouring rooms
constexpr float kDoorHeight = 2.2f;
constexpr float kLampDrop = 0.01f;     // lamps hang this far under the ceiling
constexpr float kLampMargin = 0.25f;   // from the walls' faces to the outermost lamp cells
constexpr float kBaseRadiance = 9.0f;  // the dimmest lamp's radiance factor (see Exposure above)

// Surface materials; the lamps' own materials follow them.
enum : std::uint32_t { kFloor, kCeiling, kPlaster, kSage, kClay, kSlate };
constexpr std::uint32_t kWallMaterials[] = {kPlaster, kPlaster, kSage, kClay, kSlate};

float luminance(glm::vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// A lamp's colour of luminance 1: warm, cool or neutral white, tinted a little.
glm::vec3 lamp_colour(GeneratorRng& rng) {
  static const glm::vec3 kBases[] = {{1.0f, 0.72f, 0.45f}, {0.62f, 0.78f, 1.0f}, {1.0f, 0.97f, 0.92f}};
  const glm::vec3 base = kBases[rng.next() % 3];
  const glm::vec3 tint(rng.range(0.85f, 1.15f), rng.range(0.85f, 1.15f), rng.range(0.85f, 1.15f));
  const glm::vec3 c = base * tint;
  return c / luminance(c);
}

// A solid wall piece: the box over [a, b] along the wall's direction, kWall thick round the grid
// line at `at`, from height y0 to y1. `along_x`: the wall runs along x (a line z = at).
void append_wall_piece(std::vector<SceneTriangle>& tris, bool along_x, float at, float a, float b, float y0, float y1,
                       std::uint32_t material) {
  if (b <= a || y1 <= y0) return;
  const float h = 0.5f * kWall;
  if (along_x)
    append_box(tris, {a, y0, at - h}, {b, y1, at + h}, material);
  else
    append_box(tris, {at - h, y0, a}, {at + h, y1, b}, material);
}

// The wall on grid line `line` between nodes `cell` and `cell + 1`, with a doorway in its middle
// when it separates two rooms.
void append_wall(std::vector<SceneTriangle>& tris, bool along_x, int line, int cell, int grid, std::uint32_t material) {
  const float at = kPitch * float(line);
  const float a = kPitch * float(cell) + 0.5f * kWall, b = kPitch * float(cell + 1) - 0.5f * kWall;
  const bool inner = line > 0 && line < grid;
  if (!inner) {
    append_wall_piece(tris, along_x, at, a, b, 0.0f, kHeight, material);
    return;
  }
  const float mid = 0.5f * (a + b), d0 = mid - 0.5f * kDoorWidth, d1 = mid + 0.5f * kDoorWidth;
  append_wall_piece(tris, along_x, at, a, d0, 0.0f, kHeight, material);
  append_wall_piece(tris, along_x, at, d1, b, 0.0f, kHeight, material);
  append_wall_piece(tris, along_x, at, d0, d1, kDoorHeight, kHeight, material);  // lintel
}

}  // namespace

Scene make_rooms_scene(const nlohmann::json& params) {
  check_generator_params("rooms", params, {"grid", "lamps", "seed"});
  const int grid = int(std::lround(generator_number("rooms", params, "grid", 4.0, 1.0, 16.0)));
  const int lamps = int(std::lround(generator_number("rooms", params, "lamps", 8.0, 1.0, 16.0)));
  const std::uint64_t seed = std::uint64_t(generator_number("rooms", params, "seed", 1.0, 0.0, 4294967295.0));

  Scene scene;
  scene.name = "rooms";
  scene.meters_per_unit = 1.0f;
  scene.materials.push_back(diffuse_material("floor", {0.45f, 0.36f, 0.27f}));
  scene.materials.push_back(diffuse_material("ceiling", {0.8f, 0.8f, 0.78f}));
  scene.materials.push_back(diffuse_material("plaster", {0.75f, 0.72f, 0.66f}));
  scene.materials.push_back(diffuse_material("sage", {0.42f, 0.52f, 0.40f}));
  scene.materials.push_back(diffuse_material("clay", {0.62f, 0.40f, 0.30f}));
  scene.materials.push_back(diffuse_material("slate", {0.35f, 0.40f, 0.50f}));

  GeneratorRng rng(seed ^ 0x600d1a3bull);
  auto& tris = scene.triangles;
  const float size = kPitch * float(grid), h = 0.5f * kWall;

  // Floor and ceiling over the whole building, out to the outer walls' outer faces.
  append_quad_facing(tris, {-h, 0.0f, -h}, {size + h, 0.0f, -h}, {size + h, 0.0f, size + h}, {-h, 0.0f, size + h},
                     {0.0f, 1.0f, 0.0f}, kFloor);
  append_quad_facing(tris, {-h, kHeight, -h}, {size + h, kHeight, -h}, {size + h, kHeight, size + h},
                     {-h, kHeight, size + h}, {0.0f, -1.0f, 0.0f}, kCeiling);

  // Pillars at the grid nodes, then the walls between them.
  for (int i = 0; i <= grid; ++i)
    for (int j = 0; j <= grid; ++j) {
      const float x = kPitch * float(i), z = kPitch * float(j);
      append_box(tris, {x - h, 0.0f, z - h}, {x + h, kHeight, z + h}, kPlaster);
    }
  auto wall_material = [&] { return kWallMaterials[rng.next() % std::size(kWallMaterials)]; };
  for (int line = 0; line <= grid; ++line)
    for (int cell = 0; cell < grid; ++cell) {
      append_wall(tris, true, line, cell, grid, wall_material());
      append_wall(tris, false, line, cell, grid, wall_material());
    }

  // The lamps, room by room.
  const float span = kPitch - kWall - 2.0f * kLampMargin, cell = span / float(lamps);
  const float y = kHeight - kLampDrop;
  for (int rx = 0; rx < grid; ++rx)
    for (int rz = 0; rz < grid; ++rz)
      for (int lx = 0; lx < lamps; ++lx)
        for (int lz = 0; lz < lamps; ++lz) {
          const float x0 = kPitch * float(rx) + h + kLampMargin, z0 = kPitch * float(rz) + h + kLampMargin;
          const float half_side = 0.5f * std::min(rng.range(0.08f, 0.16f), 0.9f * cell);
          const float jitter = std::max(0.0f, 0.5f * cell - half_side);
          const float cx = x0 + cell * (float(lx) + 0.5f) + rng.range(-jitter, jitter);
          const float cz = z0 + cell * (float(lz) + 0.5f) + rng.range(-jitter, jitter);
          Material lamp = diffuse_material("lamp", glm::vec3(0.8f));
          lamp.emission = lamp_colour(rng) * (kBaseRadiance * std::exp(rng.range(0.0f, std::log(6.0f))));
          const auto material = std::uint32_t(scene.materials.size());
          scene.materials.push_back(lamp);
          append_quad_facing(tris, {cx - half_side, y, cz - half_side}, {cx + half_side, y, cz - half_side},
                             {cx + half_side, y, cz + half_side}, {cx - half_side, y, cz + half_side},
                             {0.0f, -1.0f, 0.0f}, material);
        }

  // In room (1, 1) (room (0, 0) in a one-room building), looking through the doorway of its +x
  // wall into the next room, a little off the doorway's axis so the side walls show.
  const float room = grid > 1 ? kPitch : 0.0f;
  const glm::vec3 eye(room + 0.6f, 1.6f, room + 1.3f);
  const glm::vec3 look(room + 2.0f * kPitch, 1.3f, room + 0.5f * kPitch + 0.6f);
  scene.camera.position = eye;
  scene.camera.target = look;
  scene.camera.up = {0.0f, 1.0f, 0.0f};
  scene.camera.vfov_deg = 60.0f;
  scene.camera_path = {
      {0.0f, eye, look},
      {4.0f, eye + glm::vec3(0.5f, 0.0f, 0.15f), look},
      {8.0f, eye, look},
  };
  return scene;
}

}  // namespace px

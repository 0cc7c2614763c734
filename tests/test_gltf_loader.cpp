// glTF 2.0 loading: every file here is written by the test (JSON with a data-URI or .bin
// buffer, and GLB), and checked against an independent expectation: the same mesh written as
// an OBJ with the node transform applied by hand, a texture's known texel colours, an emitter's
// radiance seen straight on, and refusals that name the file.
#include "bvh/bvh_builder.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"
#include "support/gltf_builder.h"
#include "support/test_support.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>

namespace px {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::base64;
using test::TempDir;

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "<no SceneError thrown>";
}

int count_warnings_containing(const Scene& s, const std::string& needle) {
  int n = 0;
  for (const std::string& w : s.stats.warnings) n += w.find(needle) != std::string::npos;
  return n;
}

// One triangle mesh as a glTF document with its binary buffer; the document's buffer[0]
// has no uri yet (each writer below sets it).
using Gltf = test::GltfBuilder;

// The document's one scene: one node drawing one mesh of primitive `prim` (buffer 0's uri and
// length are the writers' below).
void one_primitive_scene(Gltf& g, const json& prim) {
  g.doc["scene"] = 0;
  g.doc["scenes"] = json::array({{{"nodes", json::array({0})}}});
  g.doc["nodes"] = json::array({{{"mesh", 0}}});
  g.doc["meshes"] = json::array({{{"primitives", json::array({prim})}}});
  g.doc["buffers"] = json::array({{{"byteLength", 0}}});
}

// positions (xyz per vertex), optional normals and uvs, uint16 indices (empty = non-indexed).
Gltf make_mesh(const std::vector<float>& pos, const std::vector<std::uint16_t>& idx,
               const std::vector<float>& normals = {}, const std::vector<float>& uvs = {}) {
  Gltf g;
  json attributes = json::object();
  const std::size_t nv = pos.size() / 3;
  attributes["POSITION"] = g.floats(pos, "VEC3", nv);
  if (!normals.empty()) attributes["NORMAL"] = g.floats(normals, "VEC3", nv);
  if (!uvs.empty()) attributes["TEXCOORD_0"] = g.floats(uvs, "VEC2", nv);
  json prim = {{"attributes", attributes}};
  if (!idx.empty()) prim["indices"] = g.uint16s(idx, "SCALAR", idx.size());
  one_primitive_scene(g, prim);
  return g;
}

fs::path write_embedded(const TempDir& dir, const std::string& name, Gltf g) {
  g.doc["buffers"][0] = {{"byteLength", g.bin.size()},
                         {"uri", "data:application/octet-stream;base64," + base64(g.bin)}};
  return dir.write(name, g.doc.dump());
}

fs::path write_with_bin(const TempDir& dir, const std::string& name, Gltf g) {
  const std::string bin_name = fs::path(name).stem().string() + ".bin";
  dir.write(bin_name, g.bin);
  g.doc["buffers"][0] = {{"byteLength", g.bin.size()}, {"uri", bin_name}};
  return dir.write(name, g.doc.dump());
}

fs::path write_glb(const TempDir& dir, const std::string& name, Gltf g) {
  g.doc["buffers"][0] = {{"byteLength", g.bin.size()}};
  std::string js = g.doc.dump();
  while (js.size() % 4) js.push_back(' ');
  std::string bin = g.bin;
  while (bin.size() % 4) bin.push_back('\0');
  auto u32 = [](std::string& s, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) s.push_back(char((v >> (8 * i)) & 0xff));
  };
  std::string out;
  u32(out, 0x46546C67);
  u32(out, 2);
  u32(out, std::uint32_t(12 + 8 + js.size() + 8 + bin.size()));
  u32(out, std::uint32_t(js.size()));
  u32(out, 0x4E4F534A);
  out += js;
  u32(out, std::uint32_t(bin.size()));
  u32(out, 0x004E4942);
  out += bin;
  return dir.write(name, out);
}

// A quad (two indexed triangles) and a lone triangle sharing no vertices, in the z = 0 plane,
// normals +z, uvs in glTF's convention (v down the image).
const std::vector<float> kPos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 3, 0, 0, 2, 1, 0};
const std::vector<float> kNormals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
const std::vector<float> kUv = {0, 1, 1, 1, 1, 0, 0, 0, 0, 1, 1, 1, 0, 0};
const std::vector<std::uint16_t> kIdx = {0, 1, 2, 0, 2, 3, 4, 5, 6};

// The node transform used below, applied by hand: translation (1, 2, 3) on the parent; on the
// child a 90 degree rotation about +y, (x, y, z) -> (z, y, -x), after a uniform scale of 2.
glm::vec3 by_hand(float x, float y, float z) { return {1.0f + 2.0f * z, 2.0f + 2.0f * y, 3.0f - 2.0f * x}; }

Gltf transformed_mesh() {
  Gltf g = make_mesh(kPos, kIdx, kNormals, kUv);
  const double h = std::sqrt(0.5);
  g.doc["nodes"] = json::array({{{"translation", {1, 2, 3}}, {"children", {1}}},
                                {{"mesh", 0}, {"rotation", {0, h, 0, h}}, {"scale", {2, 2, 2}}}});
  return g;
}

// The OBJ twin: the same triangles with the transform applied, and the texture coordinates
// in OBJ's convention (v up).
fs::path write_obj_twin(const TempDir& dir) {
  std::string obj;
  for (std::size_t i = 0; i < kPos.size(); i += 3) {
    const glm::vec3 p = by_hand(kPos[i], kPos[i + 1], kPos[i + 2]);
    obj += "v " + std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + "\n";
  }
  for (std::size_t i = 0; i < kUv.size(); i += 2)
    obj += "vt " + std::to_string(kUv[i]) + " " + std::to_string(1.0f - kUv[i + 1]) + "\n";
  obj += "vn 1 0 0\n";  // +z rotated by 90 degrees about +y
  for (std::size_t i = 0; i < kIdx.size(); i += 3) {
    obj += "f";
    for (int c = 0; c < 3; ++c) {
      const std::string k = std::to_string(kIdx[i + std::size_t(c)] + 1);
      obj += " " + k + "/" + k + "/1";
    }
    obj += "\n";
  }
  return dir.write("twin.obj", obj);
}

void expect_same_triangles(const Scene& a, const Scene& b, const std::string& label) {
  ASSERT_EQ(a.triangles.size(), b.triangles.size()) << label;
  for (std::size_t i = 0; i < a.triangles.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const SceneTriangle &ta = a.triangles[i], &tb = b.triangles[i];
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(ta.p[c][k], tb.p[c][k], 1e-5f) << label << " triangle " << i << " corner " << c;
        EXPECT_NEAR(ta.n[c][k], tb.n[c][k], 1e-5f) << label << " triangle " << i << " corner " << c;
      }
      EXPECT_NEAR(ta.uv[c].x, tb.uv[c].x, 1e-5f) << label << " triangle " << i;
      EXPECT_NEAR(ta.uv[c].y, tb.uv[c].y, 1e-5f) << label << " triangle " << i;
    }
}

TEST(GltfLoader, EmbeddedBinAndGlbLoadTheTrianglesOfTheirObjTwin) {
  TempDir dir;
  const Scene obj = load_obj(write_obj_twin(dir).string());
  ASSERT_EQ(obj.triangles.size(), 3u);
  const fs::path files[] = {write_embedded(dir, "embedded.gltf", transformed_mesh()),
                            write_with_bin(dir, "external.gltf", transformed_mesh()),
                            write_glb(dir, "binary.glb", transformed_mesh())};
  for (const fs::path& f : files) {
    const Scene s = load_gltf(f.string());
    expect_same_triangles(s, obj, f.filename().string());
    // No material in the file: one default, as for an OBJ without MTL.
    ASSERT_EQ(s.materials.size(), 1u);
    EXPECT_TRUE(s.stats.warnings.empty()) << s.stats.warnings.front();
  }
}

TEST(GltfLoader, InterleavedFloatAttributesAndNormalizedIntegerUvsReadAsTheirValues) {
  // Positions and normals interleaved in one buffer view (byteStride 24), uvs as normalized
  // unsigned shorts: each corner must carry its vertex's values as glTF defines them (a uv's
  // v turned to the renderer's convention, 1 - v), whatever reader the loader uses for them.
  const std::vector<float> normals = {0.6f, 0.0f, 0.8f, 0.0f, 0.6f, 0.8f, 0.0f, 0.0f, 1.0f, -0.6f, 0.0f, 0.8f};
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const std::vector<std::uint16_t> uv16 = {0, 65535, 65535, 32768, 1000, 0, 12345, 54321};
  const std::vector<std::uint16_t> idx = {0, 1, 2, 0, 2, 3};
  Gltf g;
  std::string interleaved;
  for (std::size_t v = 0; v < 4; ++v) {
    interleaved.append(reinterpret_cast<const char*>(&pos[3 * v]), 12);
    interleaved.append(reinterpret_cast<const char*>(&normals[3 * v]), 12);
  }
  while (g.bin.size() % 4) g.bin.push_back('\0');
  const std::size_t offset = g.bin.size();
  g.bin += interleaved;
  const int view = g.add(
      "bufferViews", {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", interleaved.size()}, {"byteStride", 24}});
  const int position = g.add(
      "accessors", {{"bufferView", view}, {"byteOffset", 0}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}});
  const int normal = g.add(
      "accessors", {{"bufferView", view}, {"byteOffset", 12}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}});
  const int uv = g.uint16s(uv16, "VEC2", 4);
  g.doc["accessors"][uv]["normalized"] = true;
  json prim = {{"attributes", {{"POSITION", position}, {"NORMAL", normal}, {"TEXCOORD_0", uv}}},
               {"indices", g.uint16s(idx, "SCALAR", idx.size())}};
  one_primitive_scene(g, prim);
  TempDir dir;
  for (const fs::path& f : {write_embedded(dir, "interleaved.gltf", g), write_glb(dir, "interleaved.glb", g)}) {
    const Scene s = load_gltf(f.string());
    ASSERT_EQ(s.triangles.size(), 2u) << f;
    for (std::size_t t = 0; t < 2; ++t)
      for (int c = 0; c < 3; ++c) {
        const std::size_t v = idx[3 * t + std::size_t(c)];
        const SceneTriangle& tri = s.triangles[t];
        for (int k = 0; k < 3; ++k) {
          EXPECT_EQ(tri.p[c][k], pos[3 * v + std::size_t(k)]) << f << " triangle " << t << " corner " << c;
          EXPECT_NEAR(tri.n[c][k], normals[3 * v + std::size_t(k)], 1e-6f) << f << " triangle " << t;
        }
        EXPECT_FLOAT_EQ(tri.uv[c].x, uv16[2 * v] / 65535.0f) << f << " triangle " << t << " corner " << c;
        EXPECT_FLOAT_EQ(tri.uv[c].y, 1.0f - uv16[2 * v + 1] / 65535.0f) << f << " triangle " << t << " corner " << c;
      }
  }
}

TEST(GltfLoader, NonIndexedMatrixNodeAndMirroringKeepTheFrontFace) {
  TempDir dir;
  // Non-indexed: the same three triangles spelled out vertex by vertex.
  std::vector<float> pos;
  for (std::uint16_t i : kIdx) pos.insert(pos.end(), {kPos[3 * i], kPos[3 * i + 1], kPos[3 * i + 2]});
  Gltf g = make_mesh(pos, {});
  // A matrix mirroring x (column-major), which would turn the triangles' fronts to -z.
  g.doc["nodes"][0]["matrix"] = {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const Scene s = load_gltf(write_embedded(dir, "mirror.gltf", g).string());
  ASSERT_EQ(s.triangles.size(), 3u);
  for (std::size_t t = 0; t < 3; ++t) {
    EXPECT_GT(geometric_normal(s.triangles[t]).z, 0.99f) << "triangle " << t;
    for (int c = 0; c < 3; ++c) EXPECT_LE(s.triangles[t].p[c].x, 0.0f);
  }
}

TEST(GltfLoader, SceneFileAndLoadSceneAcceptGltfAndGlb) {
  TempDir dir;
  write_with_bin(dir, "m.gltf", transformed_mesh());
  write_glb(dir, "m.glb", transformed_mesh());
  for (const char* mesh : {"m.gltf", "m.glb"}) {
    const fs::path json_path =
        dir.write("s.json", std::string(R"({"mesh": ")") + mesh + R"(", "sky": {"zenith": [1, 1, 1]}})");
    const Scene s = load_scene(json_path.string());
    EXPECT_EQ(s.triangles.size(), 3u) << mesh;
    EXPECT_EQ(count_warnings_containing(s, "no light"), 0) << mesh;
    // Given directly: framed (no camera in the file), and lit by the default sky, said once.
    const Scene direct = load_scene((dir.path() / mesh).string());
    EXPECT_TRUE(direct.sky.enabled) << mesh;
    EXPECT_EQ(count_warnings_containing(direct, "default sky"), 1) << mesh;
    EXPECT_FALSE(load_scene((dir.path() / mesh).string(), {SkyMode::kOff}).sky.enabled) << mesh;
  }
  EXPECT_NE(error_of([&] { load_scene(dir.write("bad.json", R"({"mesh": "m.txt"})").string()); }).find("m.txt"),
            std::string::npos);
}

TEST(GltfLoader, PerspectiveCameraBecomesTheView) {
  TempDir dir;
  Gltf g = make_mesh(kPos, kIdx);
  // Camera at (0.5, 0.5, 4) looking down -z, 30 degrees vertical field of view.
  g.doc["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"yfov", M_PI / 6}, {"znear", 0.1}}}}});
  g.doc["nodes"].push_back({{"camera", 0}, {"translation", {0.5, 0.5, 4}}});
  g.doc["scenes"][0]["nodes"] = {0, 1};
  const Scene s = load_scene(write_embedded(dir, "cam.gltf", g).string());
  EXPECT_NEAR(s.camera.vfov_deg, 30.0f, 1e-4f);
  EXPECT_NEAR(glm::length(s.camera.position - glm::vec3(0.5f, 0.5f, 4.0f)), 0.0f, 1e-5f);
  const glm::vec3 dir_view = glm::normalize(s.camera.target - s.camera.position);
  EXPECT_NEAR(dir_view.z, -1.0f, 1e-5f);
  // A scene file's camera still wins over the glTF's.
  const Scene over = load_scene(
      dir.write("over.json", R"({"mesh": "cam.gltf", "camera": {"position": [9, 9, 9], "target": [0, 0, 0]}})")
          .string());
  EXPECT_EQ(over.camera.position, glm::vec3(9.0f));
}

// The texel a renderer lookup of `uv` reads (kernels/scene/scene_view.h: rows top to bottom,
// v up), nearest-neighbour.
glm::vec4 texel_at(const Texture& t, glm::vec2 uv) {
  const int x = std::clamp(int(std::floor(uv.x * float(t.width))), 0, t.width - 1);
  const int y = std::clamp(int(std::floor((1.0f - uv.y) * float(t.height))), 0, t.height - 1);
  const float* p = &t.rgba[4 * (std::size_t(y) * std::size_t(t.width) + std::size_t(x))];
  return {p[0], p[1], p[2], p[3]};
}

float srgb_decode(int v) {
  const double c = v / 255.0;
  return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

void write_png(const fs::path& path, int w, int h, int channels, const std::vector<unsigned char>& px) {
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out);
  ASSERT_TRUE(out->open(path.string(), OIIO::ImageSpec(w, h, channels, OIIO::TypeDesc::UINT8)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
  out->close();
}

TEST(GltfLoader, TexturedQuadShowsTheTextureColourWhereItsUvsPoint) {
  TempDir dir;
  // 2 x 2 texture, rows top to bottom: red, green / blue, white (sRGB values).
  write_png(dir.path() / "tex.png", 2, 2, 3, {200, 0, 0, 0, 150, 0, 0, 0, 100, 255, 255, 255});
  Gltf g = make_mesh(kPos, kIdx, kNormals, kUv);
  g.doc["images"] = json::array({{{"uri", "tex.png"}}});
  g.doc["textures"] = json::array({{{"source", 0}}});
  g.doc["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0.0}}}}});
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  const Scene s = load_gltf(write_embedded(dir, "tex.gltf", g).string());
  ASSERT_EQ(s.triangles.size(), 3u);
  const Material& m = s.materials[s.triangles[0].material];
  ASSERT_GE(m.diffuse_texture, 0);
  EXPECT_EQ(m.diffuse, glm::vec3(1.0f));  // base colour factor 1, not metallic
  const Texture& t = s.textures[std::size_t(m.diffuse_texture)];
  // Vertex 0 has glTF uv (0, 1): the image's bottom-left texel (blue); vertex 2 (1, 0) its
  // top-right (green). Sampled a little inside the quad from those corners.
  const SceneTriangle& tri = s.triangles[0];  // vertices 0, 1, 2
  const glm::vec2 near_v0 = 0.9f * tri.uv[0] + 0.05f * (tri.uv[1] + tri.uv[2]);
  const glm::vec2 near_v2 = 0.9f * tri.uv[2] + 0.05f * (tri.uv[0] + tri.uv[1]);
  const glm::vec4 blue = texel_at(t, near_v0), green = texel_at(t, near_v2);
  EXPECT_NEAR(blue.x, 0.0f, 1e-6f);
  EXPECT_NEAR(blue.z, srgb_decode(100), 1e-4f);
  EXPECT_NEAR(green.y, srgb_decode(150), 1e-4f);
  EXPECT_NEAR(green.x, 0.0f, 1e-6f);
  // And the top-left texel (red) is the image's first.
  EXPECT_NEAR(texel_at(t, {0.25f, 0.75f}).x, srgb_decode(200), 1e-4f);
}

TEST(GltfLoader, MetallicRoughnessEmissionAndAlphaMaskMapOntoTheMaterialModel) {
  TempDir dir;
  // 2 x 1 RGBA: left texel alpha 0 (cut out), right alpha 255.
  write_png(dir.path() / "leaf.png", 2, 1, 4, {10, 200, 10, 0, 10, 200, 10, 255});
  Gltf g = make_mesh(kPos, kIdx, {}, kUv);
  g.doc["images"] = json::array({{{"uri", "leaf.png"}}});
  g.doc["textures"] = json::array({{{"source", 0}}});
  g.doc["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  g.doc["materials"] = json::array({
      {{"name", "gold"},
       {"pbrMetallicRoughness",
        {{"baseColorFactor", {1.0, 0.8, 0.3, 1.0}}, {"metallicFactor", 1.0}, {"roughnessFactor", 0.5}}}},
      {{"name", "lamp"},
       {"emissiveFactor", {1.0, 0.5, 0.25}},
       {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 8.0}}}}}},
      {{"name", "leaf"},
       {"alphaMode", "MASK"},
       {"alphaCutoff", 0.3},
       {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}},
      {{"name", "faded"}, {"alphaMode", "MASK"}, {"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 0.2}}}}},
  });
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  const Scene s = load_gltf(write_embedded(dir, "mat.gltf", g).string());
  ASSERT_EQ(s.materials.size(), 4u);  // no default: every primitive names its material
  const Material &gold = s.materials[0], &lamp = s.materials[1], &leaf = s.materials[2], &faded = s.materials[3];
  EXPECT_EQ(gold.diffuse, glm::vec3(0.0f));  // a metal has no diffuse lobe
  EXPECT_NEAR(gold.specular.y, 0.8f, 1e-6f);
  EXPECT_NEAR(gold.roughness, 0.25f, 1e-6f);  // GGX alpha = roughness^2
  EXPECT_NEAR(lamp.emission.x, 8.0f, 1e-5f);
  EXPECT_NEAR(lamp.emission.z, 2.0f, 1e-5f);
  EXPECT_TRUE(lamp.is_emissive());
  ASSERT_GE(leaf.alpha_texture, 0);
  const Texture& mask = s.textures[std::size_t(leaf.alpha_texture)];
  EXPECT_LT(texel_at(mask, {0.25f, 0.5f}).w, 0.5f);  // alpha 0: cut out
  EXPECT_GE(texel_at(mask, {0.75f, 0.5f}).w, 0.5f);  // alpha 1: kept
  ASSERT_GE(faded.alpha_texture, 0);                 // 0.2 below the default cutoff 0.5
  EXPECT_LT(s.textures[std::size_t(faded.alpha_texture)].rgba[3], 0.5f);
  EXPECT_EQ(s.materials[0].alpha_texture, -1);  // OPAQUE
}

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

double mean_of_render(const Scene& scene) {
  const FlatBvh bvh = build_bvh(scene.triangles);
  DeviceScene device_scene(one_device(), scene, bvh);
  PathTracer tracer(one_device(), device_scene, scene);
  PathTracer::Options opt;
  opt.spp = 4;
  const auto eyes = tracer.render_stereo(0.0f, 0, 8, 8, opt);
  double sum = 0.0;
  for (float v : eyes[0].rgb) sum += v;
  return sum / double(eyes[0].rgb.size());
}

TEST(GltfLoader, EmissiveMeshLightsTheImageAndWithoutItTheImageIsBlack) {
  TempDir dir;
  // A large quad facing +z, filling a narrow camera's view from the file's own camera.
  Gltf g = make_mesh({-10, -10, 0, 10, -10, 0, 10, 10, 0, -10, 10, 0}, {0, 1, 2, 0, 2, 3});
  g.doc["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"yfov", 0.2}, {"znear", 0.1}}}}});
  g.doc["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  g.doc["scenes"][0]["nodes"] = {0, 1};
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  // Black base colour: what the camera sees is the emission alone, 0.5 x strength 4 = 2.
  g.doc["materials"] =
      json::array({{{"emissiveFactor", {0.5, 0.5, 0.5}},
                    {"pbrMetallicRoughness", {{"baseColorFactor", {0, 0, 0, 1}}, {"metallicFactor", 0.0}}},
                    {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 4.0}}}}}}});
  const Scene lit = load_scene(write_glb(dir, "lamp.glb", g).string(), {SkyMode::kOff});
  EXPECT_FALSE(lit.sky.enabled);
  EXPECT_NEAR(mean_of_render(lit), 2.0, 1e-3);

  g.doc["materials"][0].erase("emissiveFactor");
  const Scene dark = load_scene(write_glb(dir, "dark.glb", g).string(), {SkyMode::kOff});
  EXPECT_EQ(count_warnings_containing(dark, "will be black"), 1);
  EXPECT_EQ(mean_of_render(dark), 0.0);
  // By default a lightless file is lit by the sky instead (a black base colour still
  // reflects the 4% specular of a dielectric: not black).
  const Scene sky = load_scene((dir.path() / "dark.glb").string());
  EXPECT_TRUE(sky.sky.enabled);
  EXPECT_GT(mean_of_render(sky), 0.0);
}

// KHR_lights_punctual: the first directional light is the sun. Its illuminance E (lux) over
// the sun disk's solid angle is the disk's radiance, and a surface facing it receives E; turned
// 60 degrees away, E cos 60 (the 4% specular of the dielectric mapping bends the ratio by a few
// percent, within the bounds below).
TEST(GltfLoader, ADirectionalLightBecomesTheSunWithItsIlluminance) {
  TempDir dir;
  Gltf g = make_mesh({-10, -10, 0, 10, -10, 0, 10, 10, 0, -10, 10, 0}, {0, 1, 2, 0, 2, 3});
  g.doc["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"yfov", 0.2}, {"znear", 0.1}}}}});
  g.doc["materials"] =
      json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.5, 0.5, 1}}, {"metallicFactor", 0.0}}}}});
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  g.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  g.doc["extensions"] = {
      {"KHR_lights_punctual",
       {{"lights", json::array({{{"type", "directional"}, {"color", {1.0, 0.5, 0.25}}, {"intensity", 3.0}}})}}}};
  g.doc["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
  // The light shines along its node's -z: here straight onto the quad (which faces +z).
  g.doc["nodes"].push_back({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.doc["scenes"][0]["nodes"] = {0, 1, 2};
  const Scene head_on = load_scene(write_embedded(dir, "sun.gltf", g).string());
  ASSERT_TRUE(head_on.sun.enabled);
  EXPECT_FALSE(head_on.sky.enabled);  // lit: no default sky added
  EXPECT_EQ(count_warnings_containing(head_on, "KHR_lights_punctual"), 0);
  EXPECT_NEAR(head_on.sun.direction.z, 1.0f, 1e-6);  // towards the light
  const double omega = 2.0 * M_PI * (1.0 - std::cos(head_on.sun.angular_radius_deg * M_PI / 180.0));
  EXPECT_NEAR(head_on.sun.radiance.x * omega, 3.0, 1e-3);
  EXPECT_NEAR(head_on.sun.radiance.y * omega, 1.5, 1e-3);
  // Turned 60 degrees about x.
  const double s = std::sin(M_PI / 6), c = std::cos(M_PI / 6);
  g.doc["nodes"][2]["rotation"] = {s, 0.0, 0.0, c};
  const Scene slanted = load_scene(write_embedded(dir, "slanted.gltf", g).string());
  EXPECT_NEAR(slanted.sun.direction.z, 0.5f, 1e-5);
  const double ratio = mean_of_render(slanted) / mean_of_render(head_on);
  EXPECT_GT(ratio, 0.45);
  EXPECT_LT(ratio, 0.55);
  // A diffuse 0.5 surface facing E = 3 (red channel) shows 0.5 x 3 / pi = 0.477, give or take
  // the dielectric's 4% specular (which takes its share from the diffuse lobe and adds its own
  // reflection): within 10%. The channels are in the light colour's ratio 1 : 0.5 : 0.25.
  const double red = mean_of_render(head_on) / (1.0 + 0.5 + 0.25) * 3.0;
  EXPECT_GT(red, 0.477 * 0.90);
  EXPECT_LT(red, 0.477 * 1.10);
}

// COLOR_0 multiplies the diffuse colour: a quad whose vertices are all (1, 0.5, 0.25) renders
// as the same quad with that colour folded into its base colour instead (a second code path:
// the material), channel by channel; and a quad whose corners differ renders in between.
TEST(GltfLoader, VertexColoursMultiplyTheDiffuseColour) {
  TempDir dir;
  auto quad = [](bool coloured, std::vector<double> base) {
    Gltf g = make_mesh({-10, -10, 0, 10, -10, 0, 10, 10, 0, -10, 10, 0}, {0, 1, 2, 0, 2, 3});
    g.doc["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"yfov", 0.2}, {"znear", 0.1}}}}});
    g.doc["nodes"].push_back({{"camera", 0}, {"translation", {0, 0, 5}}});
    g.doc["scenes"][0]["nodes"] = {0, 1};
    g.doc["materials"] =
        json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", base}, {"metallicFactor", 0.0}}}}});
    g.doc["meshes"][0]["primitives"][0]["material"] = 0;
    if (coloured) {
      const std::vector<float> rgb = {1, 0.5f, 0.25f, 1, 0.5f, 0.25f, 1, 0.5f, 0.25f, 1, 0.5f, 0.25f};
      g.doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = g.floats(rgb, "VEC3", 4);
    }
    return g;
  };
  auto channel_means = [](const Scene& scene) {
    const FlatBvh bvh = build_bvh(scene.triangles);
    DeviceScene device_scene(one_device(), scene, bvh);
    EXPECT_EQ((device_scene.scene_features() & PX_FEATURE_VERTEX_COLOURS) != 0, !scene.vertex_colours.empty());
    PathTracer tracer(one_device(), device_scene, scene);
    PathTracer::Options opt;
    opt.spp = 4;
    const auto eyes = tracer.render_stereo(0.0f, 0, 8, 8, opt);
    glm::dvec3 sum(0.0);
    for (std::size_t i = 0; i < eyes[0].rgb.size(); i += 3)
      sum += glm::dvec3(eyes[0].rgb[i], eyes[0].rgb[i + 1], eyes[0].rgb[i + 2]);
    return sum / double(eyes[0].rgb.size() / 3);
  };
  const Scene coloured = load_scene(write_embedded(dir, "tinted.gltf", quad(true, {0.8, 0.8, 0.8, 1})).string());
  ASSERT_EQ(coloured.vertex_colours.size(), coloured.triangles.size());
  for (const auto& w : coloured.stats.warnings) EXPECT_EQ(w.find("colour"), std::string::npos) << w;
  const Scene folded = load_scene(write_embedded(dir, "folded.gltf", quad(false, {0.8, 0.4, 0.2, 1})).string());
  EXPECT_TRUE(folded.vertex_colours.empty());
  const glm::dvec3 a = channel_means(coloured), b = channel_means(folded);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-4 * b[c]) << "channel " << c;
  EXPECT_GT(a.x, 1.5 * a.y);  // the colours show
  EXPECT_GT(a.y, 1.5 * a.z);
}

// KHR_lights_punctual point and spot lights: placed at their node's world origin (through its
// parent), a spot shining along the node's -z; candela x colour as the intensity; the cones as given.
TEST(GltfLoader, PointAndSpotLightsTakeTheirNodesPlacement) {
  TempDir dir;
  Gltf g = make_mesh({-10, -10, 0, 10, -10, 0, 10, 10, 0, -10, 10, 0}, {0, 1, 2, 0, 2, 3});
  g.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  g.doc["extensions"] = {{"KHR_lights_punctual",
                          {{"lights", json::array({{{"type", "point"}, {"color", {1.0, 0.5, 0.25}}, {"intensity", 8.0}},
                                                   {{"type", "spot"},
                                                    {"intensity", 2.0},
                                                    {"spot", {{"innerConeAngle", 0.2}, {"outerConeAngle", 0.5}}}}})}}}};
  // Node 1 (a parent moved by (1, 2, 3)) holds node 2, the point light at (0, 0, 4) in its frame;
  // node 3, the spot at (0, 5, 0), turned -90 degrees about x: its -z becomes world -y.
  const double h = std::sqrt(0.5);
  g.doc["nodes"].push_back({{"translation", {1, 2, 3}}, {"children", {2}}});
  g.doc["nodes"].push_back({{"translation", {0, 0, 4}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.doc["nodes"].push_back({{"translation", {0, 5, 0}},
                            {"rotation", {-h, 0.0, 0.0, h}},
                            {"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}});
  g.doc["scenes"][0]["nodes"] = {0, 1, 3};
  const Scene s = load_scene(write_embedded(dir, "lamps.gltf", g).string(), {SkyMode::kOff});
  ASSERT_EQ(s.punctual_lights.size(), 2u);
  EXPECT_FALSE(s.sky.enabled);  // lit: no default sky
  EXPECT_EQ(count_warnings_containing(s, "KHR_lights_punctual"), 0);
  const PunctualLight& point = s.punctual_lights[0];
  EXPECT_FALSE(point.spot);
  EXPECT_NEAR(glm::length(point.position - glm::vec3(1, 2, 7)), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(point.intensity - glm::vec3(8, 4, 2)), 0.0f, 1e-5f);
  const PunctualLight& spot = s.punctual_lights[1];
  EXPECT_TRUE(spot.spot);
  EXPECT_NEAR(glm::length(spot.position - glm::vec3(0, 5, 0)), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::length(spot.direction - glm::vec3(0, -1, 0)), 0.0f, 1e-5f);
  EXPECT_NEAR(spot.inner_cone_rad, 0.2f, 1e-6f);
  EXPECT_NEAR(spot.outer_cone_rad, 0.5f, 1e-6f);
  EXPECT_NEAR(spot.intensity.x, 2.0f, 1e-6f);
}

TEST(GltfLoader, UnsupportedFeaturesAreNamedInOneWarningLine) {
  TempDir dir;
  Gltf g = make_mesh(kPos, kIdx, {}, kUv);
  json lines = g.doc["meshes"][0]["primitives"][0];
  lines["mode"] = 1;  // LINES
  g.doc["meshes"][0]["primitives"].push_back(lines);
  g.doc["images"] = json::array({{{"uri", "missing.png"}}});
  g.doc["samplers"] = json::array({{{"wrapS", 33071}}});
  g.doc["textures"] = json::array({{{"source", 0}, {"sampler", 0}}});
  g.doc["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_sheen"};
  g.doc["extensions"] = {
      {"KHR_lights_punctual", {{"lights", json::array({{{"type", "point"}, {"intensity", 5.0}, {"range", 3.0}}})}}}};
  g.doc["nodes"].push_back({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.doc["scenes"][0]["nodes"] = {0, 1};
  g.doc["materials"] = json::array({{{"alphaMode", "BLEND"},
                                     {"occlusionTexture", {{"index", 0}}},
                                     {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}}});
  g.doc["meshes"][0]["primitives"][0]["material"] = 0;
  const Scene s = load_gltf(write_embedded(dir, "odd.gltf", g).string());
  EXPECT_EQ(s.triangles.size(), 3u);
  EXPECT_EQ(count_warnings_containing(s, "ignored glTF features"), 1);
  for (const char* feature :
       {"line primitives", "alphaMode BLEND", "KHR_materials_sheen", "light range", "wrap modes", "occlusionTexture"})
    EXPECT_EQ(count_warnings_containing(s, feature), 1) << feature;
  EXPECT_EQ(count_warnings_containing(s, "missing.png"), 1);
  // An embedded image that is no image loses its texture, with a warning; the file loads.
  g.doc["images"][0] = {{"uri", "data:image/png;base64," + base64("not a png at all")}};
  const Scene junk = load_gltf(write_embedded(dir, "junk_image.gltf", g).string());
  EXPECT_EQ(junk.triangles.size(), 3u);
  EXPECT_EQ(count_warnings_containing(junk, "cannot decode image 0"), 1);
  EXPECT_EQ(junk.materials[0].diffuse_texture, -1);
}

TEST(GltfLoader, BadInputsAreRefusedWithAMessageNamingTheFile) {
  TempDir dir;
  auto expect_refused = [&](const std::string& name, const Gltf& g, const std::string& needle) {
    const fs::path p = write_embedded(dir, name, g);
    const std::string msg = error_of([&] { load_scene(p.string()); });
    EXPECT_NE(msg.find(name), std::string::npos) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << name << ": " << msg;
  };
  {
    Gltf g = make_mesh(kPos, {0, 1, 7});
    expect_refused("index.gltf", g, "out of range");
  }
  {
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["accessors"][0]["count"] = 10;
    expect_refused("count.gltf", g, "reach past the end");
  }
  {
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["bufferViews"][0]["byteLength"] = 100000;
    expect_refused("view.gltf", g, "past the end of buffer");
  }
  {
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 42;
    expect_refused("accessor.gltf", g, "accessor 42");
  }
  {
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["nodes"][0]["children"] = {0};
    expect_refused("cycle.gltf", g, "reached twice");
  }
  {
    // A chain of 1000 nodes: refused before it could exhaust the stack.
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["nodes"] = json::array();
    for (int i = 0; i < 1000; ++i)
      g.doc["nodes"].push_back(i + 1 < 1000 ? json{{"children", {i + 1}}} : json{{"mesh", 0}});
    expect_refused("chain.gltf", g, "deeper than");
  }
  {
    Gltf g = make_mesh(kPos, kIdx);
    g.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    expect_refused("draco.gltf", g, "KHR_draco_mesh_compression");
  }
  {
    // Every position NaN: no triangle is left.
    const float nan = std::nanf("");
    Gltf g = make_mesh(std::vector<float>(kPos.size(), nan), kIdx);
    expect_refused("nan.gltf", g, "no triangles");
  }
  {
    // One NaN vertex: its two triangles are dropped and counted; the third stays.
    std::vector<float> pos = kPos;
    pos[0] = std::numeric_limits<float>::infinity();
    const Scene s = load_gltf(write_embedded(dir, "inf.gltf", make_mesh(pos, kIdx)).string());
    EXPECT_EQ(s.triangles.size(), 1u);
    EXPECT_EQ(s.stats.dropped_nonfinite, 2u);
  }
  // Missing .bin buffer, garbage, truncated GLB, missing file.
  {
    const fs::path p = write_with_bin(dir, "nobin.gltf", make_mesh(kPos, kIdx));
    fs::remove(dir.path() / "nobin.bin");
    const std::string msg = error_of([&] { load_scene(p.string()); });
    EXPECT_NE(msg.find("nobin.gltf"), std::string::npos) << msg;
    EXPECT_NE(msg.find("nobin.bin"), std::string::npos) << msg;
  }
  const std::string garbage = error_of([&] { load_scene(dir.write("junk.gltf", "{\"asset\": [").string()); });
  EXPECT_NE(garbage.find("junk.gltf"), std::string::npos) << garbage;
  const fs::path glb = write_glb(dir, "cut.glb", make_mesh(kPos, kIdx));
  std::string bytes;
  {
    std::ifstream in(glb, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  for (std::size_t keep : {std::size_t(10), std::size_t(24), bytes.size() - 8}) {
    const fs::path cut = dir.write("cut" + std::to_string(keep) + ".glb", bytes.substr(0, keep));
    const std::string msg = error_of([&] { load_scene(cut.string()); });
    EXPECT_NE(msg.find(cut.filename().string()), std::string::npos) << keep << ": " << msg;
  }
  EXPECT_NE(error_of([&] { load_scene((dir.path() / "none.glb").string()); }).find("none.glb"), std::string::npos);
  // Nesting deep enough to overflow a recursive parser is refused before parsing.
  const std::string deep =
      "{\"asset\": {\"version\": \"2.0\"}, \"extras\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
  EXPECT_NE(error_of([&] { load_scene(dir.write("deep.gltf", deep).string()); }).find("nested deeper"),
            std::string::npos);
}

}  // namespace
}  // namespace px

// Kernels compiled for the scene's features (render/kernel_features.h): which features a scene
// gets, and that the scene's kernels render every image bit for bit as the general kernels do
// (every feature compiled in) on the built-in scenes, a synthetic scene with every feature, and
// the shared real scenes. A feature missing from the derivation (one the scene uses) makes the
// images differ: a build without GGX renders cornell-glossy's glossy box as diffuse. And that a
// quick build (cl/kernel_build.h: the optimiser off) renders every image bit for bit as the
// optimised build does.
#include "app/scene_setup.h"
#include "bvh/scene_bvhs.h"
#include "bvh/wide_bvh.h"
#include "pipeline/stereo_pipeline.h"
#include "render/device_scene.h"
#include "render/kernel_features.h"
#include "render/path_tracer.h"
#include "render/preview_renderer.h"
#include "scene/primitives.h"
#include "support/test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

namespace px {
namespace {

GpuMaterial plain_material() {
  GpuMaterial m{};
  m.diffuse[0] = m.diffuse[1] = m.diffuse[2] = 0.5f;
  m.roughness = 0.3f;
  m.diffuse_texture = m.alpha_texture = m.specular_texture = m.normal_texture = -1;
  return m;
}

std::uint32_t features_of(const GpuMaterial& m, std::uint32_t tri_flags = 0, FrameParams lights = {}) {
  return kernel_features({m}, {tri_flags}, lights);
}

TEST(KernelFeatures, EachFeatureComesFromTheDataItsKernelBranchTests) {
  EXPECT_EQ(features_of(plain_material()), 0u) << "a grey Lambert material under no light needs nothing";
  GpuMaterial m = plain_material();
  m.diffuse_texture = 0;
  EXPECT_EQ(features_of(m), PX_FEATURE_TEXTURES);
  m = plain_material();
  m.specular_texture = 2;
  EXPECT_EQ(features_of(m), PX_FEATURE_TEXTURES);
  m = plain_material();
  m.normal_texture = 1;
  EXPECT_EQ(features_of(m), PX_FEATURE_NORMAL_MAP);
  EXPECT_EQ(features_of(plain_material(), PX_TRI_ALPHA_TESTED), PX_FEATURE_ALPHA_TEST);
  // A specular colour: GGX with alpha > 0, a mirror with the flag or alpha 0 (px_make_bsdf).
  m = plain_material();
  m.specular[1] = 0.2f;
  EXPECT_EQ(features_of(m), PX_FEATURE_GGX);
  m.roughness = 0.0f;
  EXPECT_EQ(features_of(m), PX_FEATURE_MIRROR);
  m.roughness = 0.3f;
  m.flags = PX_MAT_MIRROR;
  EXPECT_EQ(features_of(m), PX_FEATURE_MIRROR);
  // Glass: its specular colour is no lobe of its own.
  m.flags = PX_MAT_DIELECTRIC;
  EXPECT_EQ(features_of(m), PX_FEATURE_DIELECTRIC);
  m = plain_material();
  m.flags = PX_MAT_EMISSIVE | PX_MAT_TWO_SIDED_EMITTER;
  EXPECT_EQ(features_of(m), PX_FEATURE_EMISSIVE | PX_FEATURE_TWO_SIDED);
  // Lights as fill_light_params writes them.
  FrameParams lights{};
  lights.light_count = 3;
  lights.p_triangles = 1.0f;
  EXPECT_EQ(features_of(plain_material(), 0, lights), PX_FEATURE_EMISSIVE);
  lights = {};
  lights.p_sun = 0.5f;
  EXPECT_EQ(features_of(plain_material(), 0, lights), PX_FEATURE_SUN);
  lights = {};
  lights.sky_horizon[2] = 0.1f;  // a sky's colour is read on every miss, sampled or not
  EXPECT_EQ(features_of(plain_material(), 0, lights), PX_FEATURE_SKY);
  EXPECT_EQ(kernel_feature_list(PX_FEATURES_ALL).size(), kernel_feature_names().size());
}

TEST(KernelFeatures, TheCornellBoxNeedsOnlyEmissiveTriangles) {
  const LoadedScene cornell = load_and_build("cornell", true);
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, cornell.scene, cornell.bvh);
  EXPECT_EQ(ds.scene_features(), PX_FEATURE_EMISSIVE) << describe_kernel_features(ds.scene_features());
  EXPECT_EQ(ds.kernel_features(), PX_FEATURE_EMISSIVE);
  EXPECT_NE(ds.kernel_options().find("-DPX_FEATURES=0x040"), std::string::npos) << ds.kernel_options();
  ds.set_kernel_choice(KernelChoice::General);
  EXPECT_EQ(ds.kernel_features(), PX_FEATURES_ALL);
}

// Every feature in one small scene: a textured floor with cut-outs and a normal map, a glass
// sphere, a mirror box, a glossy box with a specular texture, a two-sided emitter, sun and sky.
LoadedScene every_feature_scene() {
  Scene s;
  s.name = "every feature";
  Texture checker;  // RGBA: a checker of two colours, every fourth texel cut out (alpha 0)
  checker.width = checker.height = 8;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      const bool dark = ((x / 2) + (y / 2)) % 2 == 0;
      checker.rgba.insert(checker.rgba.end(),
                          {dark ? 0.2f : 0.9f, 0.6f, dark ? 0.8f : 0.3f, (x + y) % 4 == 0 ? 0.0f : 1.0f});
    }
  Texture normals;  // tilted tangent-space normals
  normals.width = normals.height = 4;
  for (int i = 0; i < 16; ++i)
    normals.rgba.insert(normals.rgba.end(), {0.5f + 0.1f * (i % 4), 0.5f - 0.05f * (i / 4), 0.9f, 1.0f});
  s.textures = {checker, normals};
  Material floor;
  floor.diffuse = {0.8f, 0.8f, 0.8f};
  floor.diffuse_texture = 0;
  floor.alpha_texture = 0;
  floor.normal_texture = 1;
  Material glass;
  glass.dielectric = true;
  glass.ior = 1.5f;
  Material mirror;
  mirror.specular = {0.9f, 0.9f, 0.9f};
  mirror.mirror = true;
  Material glossy;
  glossy.diffuse = {0.3f, 0.4f, 0.6f};
  glossy.specular = {0.5f, 0.5f, 0.5f};
  glossy.roughness = 0.15f;
  glossy.specular_texture = 0;
  Material lamp;
  lamp.diffuse = {0.0f, 0.0f, 0.0f};
  lamp.emission = {4.0f, 3.5f, 3.0f};
  lamp.two_sided = true;
  s.materials = {floor, glass, mirror, glossy, lamp};
  PunctualLight bulb;  // a point light and a spot light (PX_FEATURE_PUNCTUAL)
  bulb.position = {1.5f, 1.5f, 1.0f};
  bulb.intensity = {2.0f, 1.5f, 1.0f};
  PunctualLight spot = bulb;
  spot.spot = true;
  spot.position = {-1.0f, 2.0f, 0.5f};
  spot.direction = glm::normalize(glm::vec3(0.3f, -1.0f, 0.0f));
  spot.inner_cone_rad = 0.3f;
  spot.outer_cone_rad = 0.6f;
  s.punctual_lights = {bulb, spot};
  append_quad(s.triangles, {-3, -1, -3}, {-3, -1, 3}, {3, -1, 3}, {3, -1, -3}, 0,
              {glm::vec2(0, 0), glm::vec2(0, 3), glm::vec2(3, 3), glm::vec2(3, 0)});
  append_icosphere(s.triangles, {-0.9f, -0.2f, 0.0f}, 0.7f, 2, 1);
  append_box(s.triangles, {0.3f, -1.0f, -1.2f}, {1.2f, 0.2f, -0.4f}, 2);
  append_quad(s.triangles, {-1.0f, 1.6f, -1.0f}, {1.0f, 1.6f, -1.0f}, {1.0f, 1.6f, 1.0f}, {-1.0f, 1.6f, 1.0f}, 4);
  // Instances: a glossy box stored once in its own space, drawn twice (PX_FEATURE_INSTANCES).
  s.instancing.world_triangles = s.triangles.size();
  s.instancing.meshes.push_back({s.triangles.size(), 0});
  append_box(s.triangles, {-0.45f, -0.35f, -0.4f}, {0.45f, 0.35f, 0.4f}, 3);
  s.instancing.meshes[0].count = s.triangles.size() - s.instancing.meshes[0].first;
  s.instancing.instances.push_back({0, glm::translate(glm::mat4(1.0f), glm::vec3(0.85f, -0.65f, 0.7f))});
  s.instancing.instances.push_back(
      {0, glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(-1.8f, -0.7f, 1.2f)), 0.6f,
                                 glm::vec3(0.0f, 1.0f, 0.0f)),
                     glm::vec3(0.5f, 0.4f, 0.6f))});
  s.sun.enabled = true;
  s.sun.direction = glm::normalize(glm::vec3(0.4f, 1.0f, 0.3f));
  s.sun.radiance = {30.0f, 28.0f, 25.0f};
  s.sky.enabled = true;
  s.sky.zenith = {0.3f, 0.5f, 1.0f};
  s.sky.horizon = {0.8f, 0.85f, 0.9f};
  s.sky.ground = {0.2f, 0.2f, 0.2f};
  s.camera.position = {0.0f, 0.8f, 4.5f};
  s.camera.target = {0.0f, -0.3f, 0.0f};
  s.camera.vfov_deg = 50.0f;
  s.camera_path = {{0.0f, {0.0f, 0.8f, 4.5f}, {0.0f, -0.3f, 0.0f}}, {1.0f, {0.6f, 1.0f, 4.0f}, {0.1f, -0.3f, 0.0f}}};
  // Vertex colours: a different tint at each corner of every triangle.
  s.vertex_colours.resize(s.triangles.size());
  for (std::size_t t = 0; t < s.triangles.size(); ++t)
    for (int c = 0; c < 3; ++c)
      s.vertex_colours[t][std::size_t(c)] = glm::vec3(0.4f + 0.2f * float((t + c) % 4), 0.9f - 0.1f * float(c), 0.7f);
  return LoadedScene{s, build_world_bvh(s), {}};
}

bool same_bits(const ImageRGB& a, const ImageRGB& b) {
  return a.rgb.size() == b.rgb.size() && std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

struct Images {
  std::vector<std::array<ImageRGB, 2>> frames;  // pipeline frames 0 and 1 (denoised)
  std::array<ImageRGB, 2> reference, preview;
};

// The proposed pipeline on 2 devices over 2 frames (denoised), a jittered reference pass and
// the preview, with the given kernels.
// `hand_over`: the device scene takes the triangles of a copy of the scene (SceneOnDevices' way:
// leaf triangles as BvhLeafRef records in the wide layouts), which the renderers then get.
// `layout`: the set's BVH node layout (nullopt: its device type's default). `build`: optimised
// or quick kernels.
Images render_with(const LoadedScene& loaded, KernelChoice kernels, PathTraceKernel path_kernel, unsigned w, unsigned h,
                   bool hand_over = false, std::optional<BvhLayout> layout = std::nullopt,
                   KernelBuild build = KernelBuild::Optimized) {
  DeviceOptions options{2, DeviceMode::Auto, "", std::nullopt};
  options.bvh_layout = layout;
  options.kernel_build = build;
  DeviceSet set = DeviceSet::create(options);
  EXPECT_EQ(set.kernel_build().quick, build == KernelBuild::Quick);
  Scene copy = loaded.scene;
  DeviceScene ds =
      hand_over ? DeviceScene(set, copy, loaded.bvh, {}, {}, [&copy] { return std::exchange(copy.triangles, {}); })
                : DeviceScene(set, loaded.scene, loaded.bvh);
  EXPECT_EQ(ds.leaf_refs(),
            hand_over && set.bvh_layout() != BvhLayout::Binary && set.bvh_layout() != BvhLayout::Compressed8);
  const Scene& scene = hand_over ? copy : loaded.scene;
  ds.set_kernel_choice(kernels);
  StereoPipeline::Options opt;
  opt.pipeline = PipelineKind::Proposed;
  opt.trace.spp = 2;
  opt.trace.bounces = 4;
  opt.path_kernel = path_kernel;
  StereoPipeline p(set, ds, scene, w, h, opt);
  Images out;
  for (unsigned f = 0; f < 2; ++f) {
    p.render(f, 0.3f * f);
    out.frames.push_back(p.radiance());
  }
  PathTracer tracer(set, ds, scene);
  PathTracer::Options ref;
  ref.spp = 2;
  ref.bounces = 4;
  ref.first_sample_on_gbuffer_ray = false;
  out.reference = tracer.render_stereo(0.0f, 0, w, h, ref);
  out.preview = PreviewRenderer(set, ds).render(scene, 0.0f, w, h);
  return out;
}

// Every image of `a` (pipeline frames, reference, preview) is the same image of `b` to the bit.
void expect_same_bits(const Images& a, const Images& b, const std::string& what = "") {
  for (std::size_t f = 0; f < a.frames.size(); ++f)
    for (int e = 0; e < 2; ++e)
      EXPECT_TRUE(same_bits(a.frames[f][e], b.frames[f][e])) << what << "frame " << f << ", eye " << e;
  for (int e = 0; e < 2; ++e) {
    EXPECT_TRUE(same_bits(a.reference[e], b.reference[e])) << what << "reference, eye " << e;
    EXPECT_TRUE(same_bits(a.preview[e], b.preview[e])) << what << "preview, eye " << e;
  }
}

void expect_same_images(const LoadedScene& loaded, PathTraceKernel path_kernel = PathTraceKernel::Megakernel,
                        unsigned w = 40, unsigned h = 28) {
  const auto scene = render_with(loaded, KernelChoice::Scene, path_kernel, w, h);
  const auto general = render_with(loaded, KernelChoice::General, path_kernel, w, h);
  expect_same_bits(scene, general, loaded.scene.name + ": ");
}

TEST(KernelFeatures, SceneKernelsGiveTheGeneralKernelsImagesOnTheBuiltInScenes) {
  for (const char* name : {"cornell", "cornell-glossy", "atrium"}) {
    const LoadedScene loaded = load_and_build(name, true);
    SCOPED_TRACE(name);
    expect_same_images(loaded);
  }
}

TEST(KernelFeatures, SceneKernelsGiveTheGeneralKernelsImagesWithEveryFeature) {
  const LoadedScene loaded = every_feature_scene();
  {
    DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
    DeviceScene ds(set, loaded.scene, loaded.bvh);
    EXPECT_EQ(ds.scene_features(), PX_FEATURES_ALL) << describe_kernel_features(ds.scene_features());
  }
  expect_same_images(loaded);
  expect_same_images(loaded, PathTraceKernel::Wavefront);
  // The same scene without its sun, sky and emitter's second face: fewer features, same bits.
  LoadedScene fewer = loaded;
  fewer.scene.sun.enabled = false;
  fewer.scene.sky.enabled = false;
  fewer.scene.materials[4].two_sided = false;
  fewer.scene.punctual_lights.clear();
  expect_same_images(fewer);
}

TEST(KernelFeatures, SceneKernelsGiveTheGeneralKernelsImagesOnTheSharedScenes) {
  const auto shared = test::shared_dir();
  if (shared.empty()) GTEST_SKIP() << "../shared is absent on this machine";
  const auto real = shared / "scenes" / "real";
  for (const auto& file :
       {real / "bunny" / "bunny.json", real / "spot" / "spot-front.json", real / "cornell-mapping" / "scene.json"}) {
    if (!std::filesystem::exists(file)) {
      ADD_FAILURE() << file << " is missing from ../shared";
      continue;
    }
    const LoadedScene loaded = load_and_build(file.string(), true);
    SCOPED_TRACE(file.string());
    expect_same_images(loaded);
  }
}

// Leaf triangles as BvhLeafRef records (the vertices read from the leaf blocks, in the surface
// hit and in the one-by-one test of alpha-tested leaves and edge hits) render every image bit for
// bit as full leaf triangles do, in both wide layouts: the built-in scenes and the every-feature
// scene without its instances (a scene with instances keeps full leaf triangles).
TEST(KernelFeatures, LeafRefsRenderTheImagesOfFullLeafTriangles) {
  LoadedScene every = every_feature_scene();
  every.scene.instancing = {};
  every.bvh = build_world_bvh(every.scene);
  std::vector<LoadedScene> scenes;
  scenes.push_back(std::move(every));
  for (const char* name : {"cornell", "atrium"}) scenes.push_back(load_and_build(name, true));
  for (const BvhLayout layout : {BvhLayout::Wide8, BvhLayout::Wide4}) {
    for (const LoadedScene& loaded : scenes) {
      SCOPED_TRACE(loaded.scene.name + std::string(", ") + to_string(layout));
      FlatBvh tree = loaded.bvh;
      ensure_layout(tree, layout);
      LoadedScene in_layout{loaded.scene, tree, {}};
      const auto full = render_with(in_layout, KernelChoice::Scene, PathTraceKernel::Megakernel, 40, 28, false, layout);
      const auto refs = render_with(in_layout, KernelChoice::Scene, PathTraceKernel::Megakernel, 40, 28, true, layout);
      expect_same_bits(full, refs);
    }
  }
}

// The compiler's optimiser may not change a floating-point result without fast-math options, so
// a quick build (optimisation off) computes what the optimised build does: every pipeline stage,
// the reference pass and the preview, on the built-in scenes and with every feature, both path
// tracers. What would break it: a kernel reading memory it never wrote or overflowing a shift
// (undefined behaviour the two levels resolve differently), a fast-math option, or a compiler
// that contracts a*b+c at one level and not the other.
TEST(KernelFeatures, AQuickBuildRendersTheOptimisedBuildsImages) {
  std::vector<LoadedScene> scenes;
  scenes.push_back(every_feature_scene());
  for (const char* name : {"cornell", "atrium"}) scenes.push_back(load_and_build(name, true));
  for (const LoadedScene& loaded : scenes) {
    for (const PathTraceKernel path_kernel : {PathTraceKernel::Megakernel, PathTraceKernel::Wavefront}) {
      if (path_kernel == PathTraceKernel::Wavefront && loaded.scene.name != "every feature") continue;
      SCOPED_TRACE(loaded.scene.name + (path_kernel == PathTraceKernel::Wavefront ? ", wavefront" : ""));
      const auto optimised =
          render_with(loaded, KernelChoice::Scene, path_kernel, 40, 28, false, std::nullopt, KernelBuild::Optimized);
      const auto quick =
          render_with(loaded, KernelChoice::Scene, path_kernel, 40, 28, false, std::nullopt, KernelBuild::Quick);
      expect_same_bits(optimised, quick);
    }
  }
}

}  // namespace
}  // namespace px

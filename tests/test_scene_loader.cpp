// OBJ loading (corpus of historically troublesome files, repairs, refusals, MTL mapping,
// textures) and scene files (JSON format, overrides, error messages).
#include "scene/primitives.h"
#include "scene/scene_file_bytes.h"
#include "scene/scene_loader.h"
#include "support/test_support.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <unistd.h>

namespace px {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

fs::path corpus_dir() {
  const fs::path shared = test::shared_dir();
  return shared.empty() ? fs::path() : shared / "corpus" / "obj-edge-cases";
}

#define REQUIRE_CORPUS()                \
  const fs::path corpus = corpus_dir(); \
  if (corpus.empty()) GTEST_SKIP() << "../shared is absent on this machine"

// What every loaded scene must satisfy, whatever the input was.
void expect_valid_scene(const Scene& scene, const std::string& label) {
  ASSERT_FALSE(scene.triangles.empty()) << label;
  ASSERT_FALSE(scene.materials.empty()) << label;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const SceneTriangle& t = scene.triangles[i];
    ASSERT_TRUE(has_finite_positions(t)) << label << " triangle " << i;
    ASSERT_FALSE(is_degenerate(t)) << label << " triangle " << i;
    ASSERT_GT(glm::length(geometric_normal(t)), 0.5f) << label << " triangle " << i;
    ASSERT_LT(t.material, scene.materials.size()) << label << " triangle " << i;
    for (int c = 0; c < 3; ++c) {
      ASSERT_NEAR(glm::length(t.n[c]), 1.0f, 1e-4f) << label << " triangle " << i;
      ASSERT_TRUE(std::isfinite(t.uv[c].x) && std::isfinite(t.uv[c].y)) << label;
    }
  }
  for (const Material& m : scene.materials) {
    EXPECT_TRUE(m.diffuse_texture < int(scene.textures.size())) << label;
    EXPECT_TRUE(m.alpha_texture < int(scene.textures.size())) << label;
  }
}

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "<no SceneError thrown>";
}

bool any_warning_contains(const Scene& s, const std::string& needle) {
  for (const std::string& w : s.stats.warnings)
    if (w.find(needle) != std::string::npos) return true;
  return false;
}

// ---------------------------------------------------------------------------------------------
// Corpus

TEST(ObjCorpus, EveryFileLoadsOrFailsCleanly) {
  REQUIRE_CORPUS();
  int loaded = 0, refused = 0;
  // Every file, not only *.obj: an MTL, a licence or an empty file given as an OBJ must be
  // refused cleanly too.
  for (const auto& entry : fs::directory_iterator(corpus)) {
    const std::string path = entry.path().string();
    const std::string name = entry.path().filename().string();
    try {
      const Scene scene = load_obj(path);
      expect_valid_scene(scene, name);
      ++loaded;
    } catch (const SceneError& e) {
      const std::string msg = e.what();
      EXPECT_FALSE(msg.empty()) << name;
      EXPECT_NE(msg.find(name), std::string::npos) << "message does not name the file: " << msg;
      ++refused;
    }
  }
  EXPECT_GE(loaded, 30);
  EXPECT_GE(refused, 5);
}

TEST(ObjCorpus, NanCoordinatesAreDroppedAndCounted) {
  REQUIRE_CORPUS();
  const Scene s = load_obj((corpus / "test-nan.obj").string());
  // The first face (a quad over four NaN/Inf vertices, "1.#IND" included) is the only bad one.
  EXPECT_EQ(s.stats.dropped_nonfinite, 2u);
  EXPECT_TRUE(any_warning_contains(s, "NaN")) << "no warning about the NaN vertices";
  EXPECT_TRUE(any_warning_contains(s, "line 12")) << "warning should name the first bad line";
  expect_valid_scene(s, "test-nan.obj");
  EXPECT_GT(s.triangles.size(), 20u);
}

TEST(ObjCorpus, InvalidIndicesAreRefusedWithTheirLine) {
  REQUIRE_CORPUS();
  struct Case {
    const char* file;
    const char* expected;
  };
  for (const Case& c : {Case{"invalid-relative-vertex-index.obj", "invalid-relative-vertex-index.obj:1:"},
                        Case{"invalid-relative-texture-index.obj", "invalid-relative-texture-index.obj:2:"},
                        Case{"issue-140-zero-face-idx.obj", "issue-140-zero-face-idx.obj:16:"}}) {
    const std::string msg = error_of([&] { load_obj((corpus / c.file).string()); });
    EXPECT_NE(msg.find(c.expected), std::string::npos) << msg;
  }
  EXPECT_NE(error_of([&] { load_obj((corpus / "issue-140-zero-face-idx.obj").string()); }).find("index 0"),
            std::string::npos);
}

TEST(ObjCorpus, FilesWithoutTrianglesAreRefused) {
  REQUIRE_CORPUS();
  for (const char* file : {"points-prim.obj", "line-prim.obj", "issue46.obj", "invalid-face-definition.obj"}) {
    const std::string msg = error_of([&] { load_obj((corpus / file).string()); });
    EXPECT_NE(msg.find("no triangles"), std::string::npos) << file << ": " << msg;
    EXPECT_NE(msg.find(file), std::string::npos) << msg;
  }
  EXPECT_NE(error_of([&] { load_obj((corpus / "points-prim.obj").string()); }).find("lines/points"), std::string::npos);
}

TEST(ObjCorpus, MissingMaterialLibraryGivesDefaultMaterial) {
  REQUIRE_CORPUS();
  const Scene s = load_obj((corpus / "missing_material_file.obj").string());
  expect_valid_scene(s, "missing_material_file.obj");
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.materials[0].name, "default");
  EXPECT_TRUE(any_warning_contains(s, "not found"));
}

TEST(ObjCorpus, MaterialsAreAssignedPerFace) {
  REQUIRE_CORPUS();
  const Scene s = load_obj((corpus / "cornell_box.obj").string());
  expect_valid_scene(s, "cornell_box.obj");
  std::set<std::string> used;
  for (const SceneTriangle& t : s.triangles) used.insert(s.materials[t.material].name);
  EXPECT_TRUE(used.count("red") && used.count("green") && used.count("white") && used.count("light"));
  for (const Material& m : s.materials)
    if (m.name == "red") {
      EXPECT_EQ(m.diffuse, glm::vec3(1.0f, 0.0f, 0.0f));
    }
}

TEST(ObjCorpus, MissingTextureIsAWarning) {
  REQUIRE_CORPUS();
  const Scene s = load_obj((corpus / "texture-filename-with-whitespace.obj").string());
  expect_valid_scene(s, "texture-filename-with-whitespace.obj");
  EXPECT_TRUE(any_warning_contains(s, "texture 01.png"));
  EXPECT_TRUE(s.textures.empty());
}

TEST(ObjCorpus, UndefinedNormalsFallBackToGeometricNormals) {
  REQUIRE_CORPUS();
  const Scene s = load_obj((corpus / "catmark_torus_creases0.obj").string());
  expect_valid_scene(s, "catmark_torus_creases0.obj");
  EXPECT_TRUE(any_warning_contains(s, "normal"));
  for (const SceneTriangle& t : s.triangles) EXPECT_EQ(t.n[0], geometric_normal(t));
}

TEST(ObjCorpus, CornellBoxOriginalHasItsLight) {
  const fs::path shared = test::shared_dir();
  if (shared.empty()) GTEST_SKIP() << "../shared is absent on this machine";
  // Its mtllib line says "scenes/CornellBox-Original.mtl" for a file that sits beside the OBJ.
  const fs::path obj = shared / "scenes" / "cornell-box-original" / "CornellBox-Original.obj";
  const Scene s = load_scene(obj.string());
  expect_valid_scene(s, "CornellBox-Original.obj");
  const Material* light = nullptr;
  for (const Material& m : s.materials)
    if (m.name == "light") light = &m;
  ASSERT_NE(light, nullptr);
  EXPECT_EQ(light->emission, glm::vec3(17.0f, 12.0f, 4.0f));
  std::size_t emissive = 0;
  for (const SceneTriangle& t : s.triangles) emissive += s.materials[t.material].is_emissive();
  EXPECT_GT(emissive, 0u);
  // Framed camera: looks at the bounds' centre from outside them.
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const SceneTriangle& t : s.triangles)
    for (const glm::vec3& p : t.p) lo = glm::min(lo, p), hi = glm::max(hi, p);
  EXPECT_LT(glm::distance(s.camera.target, 0.5f * (lo + hi)), 1e-4f);
  EXPECT_GT(s.camera.position.z, hi.z);
}

// ---------------------------------------------------------------------------------------------
// Hand-written OBJ files: repairs, refusals, triangulation, MTL mapping, textures

TEST(ObjLoader, MissingFileNamesTheFile) {
  const std::string msg = error_of([] { load_obj("/nonexistent/dir/missing-mesh.obj"); });
  EXPECT_NE(msg.find("missing-mesh.obj"), std::string::npos) << msg;
  TempDir dir;
  const std::string msg2 = error_of([&] { load_obj(dir.path().string()); });
  EXPECT_NE(msg2.find(dir.path().string()), std::string::npos) << msg2;
}

TEST(ObjLoader, DropsNonFiniteAndDegenerateTriangles) {
  TempDir dir;
  const fs::path obj = dir.write("m.obj",
                                 "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                 "v nan 0 0\nv 1e999 0 0\n"
                                 "v 2 0 0\nv 3 0 0\n"
                                 "f 1 2 3\n"    // fine
                                 "f 1 2 4\n"    // NaN
                                 "f 5 2 3\n"    // overflow -> Inf
                                 "f 1 6 7\n"    // collinear
                                 "f 1 1 2\n");  // repeated vertex
  const Scene s = load_obj(obj.string());
  EXPECT_EQ(s.triangles.size(), 1u);
  EXPECT_EQ(s.stats.dropped_nonfinite, 2u);
  EXPECT_EQ(s.stats.dropped_degenerate, 2u);
  expect_valid_scene(s, "m.obj");
}

TEST(ObjLoader, RefusesOutOfRangeVertexIndexWithLine) {
  TempDir dir;
  const fs::path obj = dir.write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n# c\nf 1 2 9\n");
  const std::string msg = error_of([&] { load_obj(obj.string()); });
  EXPECT_NE(msg.find("bad.obj:6:"), std::string::npos) << msg;
  const fs::path junk = dir.write("junk.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x3\n");
  EXPECT_NE(error_of([&] { load_obj(junk.string()); }).find("junk.obj:4:"), std::string::npos);
}

TEST(ObjLoader, LineEndingsDoNotMatter) {
  TempDir dir;
  const std::string lf = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
  std::string crlf, cr;
  for (char c : lf) {
    crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
    cr += c == '\n' ? '\r' : c;
  }
  const Scene a = load_obj(dir.write("lf.obj", lf).string());
  const Scene b = load_obj(dir.write("crlf.obj", crlf).string());
  const Scene c = load_obj(dir.write("cr.obj", cr).string());
  ASSERT_EQ(a.triangles.size(), 2u);
  ASSERT_EQ(b.triangles.size(), 2u);
  ASSERT_EQ(c.triangles.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i)
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.triangles[i].p[k], b.triangles[i].p[k]);
      EXPECT_EQ(a.triangles[i].p[k], c.triangles[i].p[k]);
    }
}

TEST(ObjLoader, NonConvexPolygonIsTriangulatedExactly) {
  // An L-shaped hexagon (area 3) and a concave star-like octagon in the z = 1 plane; the
  // triangles must tile them: same total area, all facing the polygon's way.
  TempDir dir;
  const fs::path obj = dir.write("poly.obj",
                                 "v 0 0 1\nv 2 0 1\nv 2 1 1\nv 1 1 1\nv 1 2 1\nv 0 2 1\n"
                                 "f 1 2 3 4 5 6\n"
                                 "v 0 0 5\nv 4 0 5\nv 4 4 5\nv 3 1 5\nv 2 4 5\nv 1 1 5\nv 0 4 5\nv 0.5 2 5\n"
                                 "f 7 8 9 10 11 12 13 14\n");
  const Scene s = load_obj(obj.string());
  double area_l = 0.0, area_star = 0.0;
  for (const SceneTriangle& t : s.triangles) {
    EXPECT_GT(geometric_normal(t).z, 0.999f);
    (t.p[0].z < 2.0f ? area_l : area_star) += triangle_area(t);
  }
  EXPECT_EQ(s.triangles.size(), 4u + 6u);
  EXPECT_NEAR(area_l, 3.0, 1e-6);
  // Shoelace area of the octagon.
  const double xs[] = {0, 4, 4, 3, 2, 1, 0, 0.5}, ys[] = {0, 0, 4, 1, 4, 1, 4, 2};
  double shoelace = 0.0;
  for (int i = 0; i < 8; ++i) shoelace += xs[i] * ys[(i + 1) % 8] - xs[(i + 1) % 8] * ys[i];
  EXPECT_NEAR(area_star, 0.5 * std::abs(shoelace), 1e-6);
}

TEST(ObjLoader, MapsMtlParameters) {
  TempDir dir;
  dir.write("sub/m.mtl",
            "newmtl glossy\nKd 0.5 0.25 0.125\nKs 0.04 0.04 0.04\nNs 98\n"
            "newmtl mirror_ns\nKs 0.9 0.9 0.9\nNs 1000\n"
            "newmtl mirror_illum\nKs 0.8 0.8 0.8\nNs 10\nillum 5\n"
            "newmtl lamp\nKd 0.5 0.5 0.5\nKe 3 2 1\n"
            "newmtl too_bright\nKd 2 -1 0.5\n");
  // The mtllib path names a subfolder; materials are used by name.
  const fs::path obj = dir.write("m.obj",
                                 "mtllib sub/m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                 "usemtl glossy\nf 1 2 3\nusemtl mirror_ns\nf 1 2 3\n"
                                 "usemtl mirror_illum\nf 1 2 3\nusemtl lamp\nf 1 2 3\n"
                                 "usemtl too_bright\nf 1 2 3\nusemtl nonexistent\nf 1 2 3\n");
  const Scene s = load_obj(obj.string());
  ASSERT_EQ(s.triangles.size(), 6u);
  auto mat = [&](int i) { return s.materials[s.triangles[i].material]; };
  EXPECT_EQ(mat(0).name, "glossy");
  EXPECT_EQ(mat(0).diffuse, glm::vec3(0.5f, 0.25f, 0.125f));
  EXPECT_NEAR(mat(0).roughness, std::sqrt(2.0f / 100.0f), 1e-6f);
  EXPECT_FALSE(mat(0).mirror);
  EXPECT_TRUE(mat(1).mirror);
  EXPECT_EQ(mat(1).roughness, 0.0f);
  EXPECT_TRUE(mat(2).mirror);
  EXPECT_EQ(mat(3).emission, glm::vec3(3.0f, 2.0f, 1.0f));
  EXPECT_TRUE(mat(3).is_emissive());
  EXPECT_EQ(mat(4).diffuse, glm::vec3(1.0f, 0.0f, 0.5f));  // clamped to [0, 1]
  EXPECT_EQ(mat(5).name, "default");
  EXPECT_TRUE(any_warning_contains(s, "nonexistent"));
}

void write_png(const fs::path& path, int w, int h, int channels, const std::vector<unsigned char>& data) {
  fs::create_directories(path.parent_path());
  auto out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out) << OIIO::geterror();
  OIIO::ImageSpec spec(w, h, channels, OIIO::TypeDesc::UINT8);
  ASSERT_TRUE(out->open(path.string(), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, data.data()));
  out->close();
}

TEST(ObjLoader, LoadsTexturesLinearised) {
  TempDir dir;
  // 2x1 RGBA: an opaque sRGB mid-grey and a transparent white; a 1-channel alpha mask.
  write_png(dir.path() / "tex" / "albedo.png", 2, 1, 4, {128, 128, 128, 255, 255, 255, 255, 0});
  write_png(dir.path() / "tex" / "mask.png", 2, 1, 1, {255, 64});
  dir.write("m.mtl",
            "newmtl leaf\nKd 1 1 1\nmap_Kd tex/albedo.png\nmap_d tex/mask.png\n"
            "newmtl broken\nmap_Kd tex/missing.png\n");
  const fs::path obj = dir.write("m.obj",
                                 "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                 "usemtl leaf\nf 1/1 2/2 3/3\nusemtl broken\nf 1/1 2/2 3/3\n");
  const Scene s = load_obj(obj.string());
  ASSERT_EQ(s.textures.size(), 2u);
  const Material& leaf = s.materials[s.triangles[0].material];
  ASSERT_GE(leaf.diffuse_texture, 0);
  ASSERT_GE(leaf.alpha_texture, 0);
  const Texture& albedo = s.textures[leaf.diffuse_texture];
  const Texture& mask = s.textures[leaf.alpha_texture];
  ASSERT_EQ(albedo.width, 2);
  ASSERT_EQ(albedo.height, 1);
  ASSERT_EQ(albedo.rgba.size(), 8u);
  // sRGB 128/255 = 0.50196 -> linear 0.21586; alpha stays linear.
  EXPECT_NEAR(albedo.rgba[0], 0.21586f, 1e-4f);
  EXPECT_NEAR(albedo.rgba[3], 1.0f, 1e-6f);
  EXPECT_NEAR(albedo.rgba[4], 1.0f, 1e-6f);
  EXPECT_NEAR(albedo.rgba[7], 0.0f, 1e-6f);
  // The mask's single channel is its alpha, linear.
  EXPECT_NEAR(mask.rgba[3], 1.0f, 1e-6f);
  EXPECT_NEAR(mask.rgba[7], 64.0f / 255.0f, 1e-4f);
  EXPECT_EQ(s.triangles[0].uv[1], glm::vec2(1.0f, 0.0f));
  const Material& broken = s.materials[s.triangles[1].material];
  EXPECT_EQ(broken.diffuse_texture, -1);
  EXPECT_TRUE(any_warning_contains(s, "missing.png"));
}

TEST(ObjLoader, MapKdWithoutKdIsTheTexturesOwnColour) {
  // OBJ viewers show a map_Kd's own colour; only an explicit Kd scales it (it used to be taken
  // as 0: a black wall). Same rule for map_Ks and Ks.
  TempDir dir;
  write_png(dir.path() / "wall.png", 1, 1, 3, {255, 128, 0});
  dir.write("m.mtl",
            "newmtl bare\nmap_Kd wall.png\n"
            "newmtl scaled\nKd 0.5 0.25 1\nmap_Kd wall.png\n"
            "newmtl plain\nKd 0.3 0.3 0.3\n"
            "newmtl spec_bare\nKd 0.5 0.5 0.5\nmap_Ks wall.png\nNs 20\n"
            "newmtl spec_scaled\nKs 0.2 0.2 0.2\nmap_Ks wall.png\n"
            "newmtl missing\nmap_Kd nowhere.png\n");
  const fs::path obj = dir.write("m.obj",
                                 "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                 "usemtl bare\nf 1/1 2/2 3/3\nusemtl scaled\nf 1/1 2/2 3/3\n"
                                 "usemtl plain\nf 1/1 2/2 3/3\nusemtl spec_bare\nf 1/1 2/2 3/3\n"
                                 "usemtl spec_scaled\nf 1/1 2/2 3/3\nusemtl missing\nf 1/1 2/2 3/3\n");
  const Scene s = load_obj(obj.string());
  auto mat = [&](int i) { return s.materials[s.triangles[i].material]; };
  // The albedo the renderer uses is Kd x texel.
  auto albedo = [&](const Material& m) {
    glm::vec3 a = m.diffuse;
    if (m.diffuse_texture >= 0) {
      const auto& t = s.textures[m.diffuse_texture].rgba;
      a *= glm::vec3(t[0], t[1], t[2]);
    }
    return a;
  };
  const glm::vec3 texel(1.0f, 0.21586f, 0.0f);  // sRGB (255, 128, 0), linear
  ASSERT_GE(mat(0).diffuse_texture, 0);
  EXPECT_EQ(mat(0).diffuse, glm::vec3(1.0f));
  EXPECT_NEAR(glm::length(albedo(mat(0)) - texel), 0.0f, 1e-4f);
  EXPECT_NEAR(glm::length(albedo(mat(1)) - texel * glm::vec3(0.5f, 0.25f, 1.0f)), 0.0f, 1e-4f);
  EXPECT_EQ(mat(2).diffuse, glm::vec3(0.3f));
  EXPECT_EQ(mat(2).diffuse_texture, -1);
  ASSERT_GE(mat(3).specular_texture, 0);
  EXPECT_EQ(mat(3).specular, glm::vec3(1.0f));
  EXPECT_EQ(mat(4).specular, glm::vec3(0.2f));
  EXPECT_GE(mat(4).specular_texture, 0);
  // An unreadable map: warned, and a neutral grey rather than black or white.
  EXPECT_EQ(mat(5).diffuse_texture, -1);
  EXPECT_EQ(mat(5).diffuse, Material{}.diffuse);
  EXPECT_TRUE(any_warning_contains(s, "nowhere.png"));
}

TEST(ObjLoader, GlassIsADielectric) {
  TempDir dir;
  dir.write("m.mtl",
            "newmtl water\nKd 0.1 0.1 0.1\nKs 1 1 1\nNi 1.33\nillum 7\n"
            "newmtl dissolved\nKd 0.5 0.5 0.5\nd 0.4\n"
            "newmtl filter\nKs 0.04 0.04 0.04\nNs 200\nNi 1.6\nTf 0.95 0.9 0.85\n"  // cornell-mapping's sphere
            "newmtl glass4\nillum 4\n"
            "newmtl opaque_tf\nKd 0.5 0.5 0.5\nTf 1 1 1\nNi 1.5\nd 1\nillum 2\n"
            "newmtl fresnel_mirror\nKs 0.9 0.9 0.9\nillum 5\n"
            "newmtl tr_as_d\nKd 0.5 0.5 0.5\nTr 1\n");
  const fs::path obj = dir.write("m.obj",
                                 "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                 "usemtl water\nf 1 2 3\nusemtl dissolved\nf 1 2 3\nusemtl filter\nf 1 2 3\n"
                                 "usemtl glass4\nf 1 2 3\nusemtl opaque_tf\nf 1 2 3\nusemtl fresnel_mirror\nf 1 2 3\n"
                                 "usemtl tr_as_d\nf 1 2 3\n");
  const Scene s = load_obj(obj.string());
  auto mat = [&](int i) { return s.materials[s.triangles[i].material]; };
  EXPECT_TRUE(mat(0).dielectric);
  EXPECT_FLOAT_EQ(mat(0).ior, 1.33f);
  EXPECT_EQ(mat(0).transmission, glm::vec3(1.0f));
  EXPECT_FALSE(mat(0).mirror);
  EXPECT_TRUE(mat(1).dielectric);
  EXPECT_FLOAT_EQ(mat(1).ior, 1.5f);  // no Ni: common glass
  EXPECT_TRUE(mat(2).dielectric);
  EXPECT_FLOAT_EQ(mat(2).ior, 1.6f);
  EXPECT_EQ(mat(2).transmission, glm::vec3(0.95f, 0.9f, 0.85f));
  EXPECT_TRUE(mat(3).dielectric);
  EXPECT_FALSE(mat(4).dielectric) << "Tf 1 1 1 with d 1 is what exporters write on opaque materials";
  EXPECT_FALSE(mat(5).dielectric);
  EXPECT_TRUE(mat(5).mirror);
  // "Tr 1" is d = 0 (invisible) by the letter, opaque by some exporters' meaning: opaque, said.
  EXPECT_FALSE(mat(6).dielectric);
  EXPECT_TRUE(any_warning_contains(s, "fully transparent d 0 / Tr 1 (rendered opaque) (tr_as_d)"));
}

TEST(ObjLoader, NormalMapsAndIgnoredFeaturesAreNamedInOneLine) {
  TempDir dir;
  // A tangent-space normal map (bluish, not grey), and a grey height map.
  write_png(dir.path() / "n.png", 2, 1, 3, {128, 128, 255, 200, 128, 230});
  write_png(dir.path() / "h.png", 2, 1, 1, {10, 240});
  dir.write("m.mtl",
            "newmtl norm_map\nKd 1 1 1\nnorm n.png\n"
            "newmtl bump_normal\nKd 1 1 1\nbump -bm 0.5 n.png\n"
            "newmtl bump_height\nKd 1 1 1\nmap_Bump h.png\nmap_Ns rough.png\n"
            "newmtl lamp\nKe 1 1 1\nPe 10\nKa 0.1 0.1 0.1\n");
  const fs::path obj = dir.write("m.obj",
                                 "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                 "usemtl norm_map\nf 1 2 3\nusemtl bump_normal\nf 1 2 3\n"
                                 "usemtl bump_height\nf 1 2 3\nusemtl lamp\nf 1 2 3\n");
  const Scene s = load_obj(obj.string());
  auto mat = [&](int i) { return s.materials[s.triangles[i].material]; };
  ASSERT_GE(mat(0).normal_texture, 0);
  // Normals are numbers, not colours: no sRGB decoding (128 / 255, not 0.2159).
  const Texture& n = s.textures[mat(0).normal_texture];
  EXPECT_NEAR(n.rgba[0], 128.0f / 255.0f, 1e-5f);
  EXPECT_NEAR(n.rgba[2], 1.0f, 1e-5f);
  EXPECT_FLOAT_EQ(mat(0).normal_scale, 1.0f);
  ASSERT_GE(mat(1).normal_texture, 0);
  EXPECT_FLOAT_EQ(mat(1).normal_scale, 0.5f);
  EXPECT_EQ(mat(2).normal_texture, -1) << "a height map is not a normal map";
  // Exactly one line for the library, naming every ignored feature and where it is.
  std::vector<std::string> lines;
  for (const auto& w : s.stats.warnings)
    if (w.find("m.mtl") != std::string::npos && w.find("ignored") != std::string::npos) lines.push_back(w);
  ASSERT_EQ(lines.size(), 1u);
  for (const char* what : {"bump height map (bump_height)", "map_Ns (bump_height)", "Pe (lamp)"})
    EXPECT_NE(lines[0].find(what), std::string::npos) << what << " missing from: " << lines[0];
  EXPECT_EQ(lines[0].find("Ka"), std::string::npos) << "ambient means nothing to a path tracer";
  EXPECT_EQ(lines[0].find("norm_map"), std::string::npos) << "norm_map is fully modelled";
}

TEST(ObjLoader, CornellMappingBackWallHasItsTexturesAndTheSphereIsGlass) {
  const fs::path shared = test::shared_dir();
  const fs::path file = shared / "scenes" / "real" / "cornell-mapping" / "CornellBox-Mapping.obj";
  if (shared.empty() || !fs::exists(file)) GTEST_SKIP() << "../shared/scenes/real is absent on this machine";
  const Scene s = load_obj(file.string());
  const Material* wall = nullptr;
  const Material* sphere = nullptr;
  for (const auto& m : s.materials) {
    if (m.name == "backWall") wall = &m;
    if (m.name == "rightSphere") sphere = &m;
  }
  ASSERT_TRUE(wall && sphere);
  EXPECT_EQ(wall->diffuse, glm::vec3(1.0f));
  EXPECT_GE(wall->diffuse_texture, 0);
  EXPECT_GE(wall->specular_texture, 0);
  EXPECT_GE(wall->normal_texture, 0) << "its bump is a normal map";
  EXPECT_TRUE(sphere->dielectric);
  EXPECT_FLOAT_EQ(sphere->ior, 1.6f);
}

// ---------------------------------------------------------------------------------------------
// Scene files

TEST(SceneFile, AMappedSceneFileHoldsTheFilesBytesUntilReleased) {
  TempDir dir;
  std::string bytes(300001, '\0');  // more than a page, not a whole number of them
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = char((i * 131 + 7) & 0xff);
  const fs::path path = dir.write("bytes.glb", bytes);
  MappedSceneFile file(path.string(), "glTF");
  EXPECT_TRUE(file.mapped());
  ASSERT_EQ(file.size(), bytes.size());
  EXPECT_EQ(std::memcmp(file.data(), bytes.data(), bytes.size()), 0);
  file.release();
  EXPECT_EQ(file.data(), nullptr);
  EXPECT_EQ(file.size(), 0u);
  // An empty file cannot be mapped: it is read, as empty.
  const MappedSceneFile empty(dir.write("empty.glb", "").string(), "glTF");
  EXPECT_FALSE(empty.mapped());
  EXPECT_EQ(empty.size(), 0u);
  // The errors of a read, naming the file; an empty glTF is refused, not a crash.
  const std::string missing = error_of([&] { MappedSceneFile((dir.path() / "none.glb").string(), "glTF"); });
  EXPECT_NE(missing.find("none.glb"), std::string::npos) << missing;
  EXPECT_NE(missing.find("no such file"), std::string::npos) << missing;
  const std::string folder = error_of([&] { MappedSceneFile(dir.path().string(), "glTF"); });
  EXPECT_NE(folder.find("not a regular file"), std::string::npos) << folder;
  const std::string refused = error_of([&] { load_scene((dir.path() / "empty.glb").string()); });
  EXPECT_NE(refused.find("empty.glb"), std::string::npos) << refused;
}

TEST(SceneFile, ProjectScenesLoad) {
  for (const char* name : {"cornell.json", "cornell-glossy.json"}) {
    const Scene s = load_scene((test::source_dir() / "scenes" / name).string());
    expect_valid_scene(s, name);
    EXPECT_FLOAT_EQ(s.meters_per_unit, 0.001f);
    EXPECT_FALSE(s.camera_path.empty());
  }
  const Scene atrium = load_scene((test::source_dir() / "scenes" / "atrium.json").string());
  EXPECT_GE(atrium.triangles.size(), 500000u);
  EXPECT_TRUE(atrium.sun.enabled);
  EXPECT_TRUE(atrium.sky.enabled);
  EXPECT_NEAR(glm::length(atrium.sun.direction), 1.0f, 1e-5f);
}

TEST(SceneFile, FieldsOverrideGeneratorDefaults) {
  TempDir dir;
  const fs::path json = dir.write("s.json", R"({
    // comments are allowed
    "generator": "cornell",
    "name": "custom",
    "ipd_m": 0.07,
    "camera": {"position": [278, 273, -600], "vfov_deg": 50},
    "camera_path": [],
    "sky": {"zenith": [0.1, 0.2, 0.3]}
  })");
  const Scene s = load_scene(json.string());
  const Scene base = make_builtin_scene("cornell");
  EXPECT_EQ(s.name, "custom");
  EXPECT_FLOAT_EQ(s.ipd_m, 0.07f);
  EXPECT_FLOAT_EQ(s.ipd_units(), 70.0f);
  EXPECT_EQ(s.camera.position, glm::vec3(278, 273, -600));
  EXPECT_EQ(s.camera.target, base.camera.target);  // not given: kept
  EXPECT_FLOAT_EQ(s.camera.vfov_deg, 50.0f);
  EXPECT_TRUE(s.camera_path.empty());
  EXPECT_TRUE(s.sky.enabled);
  EXPECT_EQ(s.sky.zenith, glm::vec3(0.1f, 0.2f, 0.3f));
  EXPECT_FALSE(s.sun.enabled);
  EXPECT_EQ(s.triangles.size(), base.triangles.size());
}

TEST(SceneFile, MeshIsRelativeToTheJson) {
  TempDir dir;
  dir.write("meshes/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path json = dir.write("scene/s.json", R"({"mesh": "../meshes/tri.obj",
      "camera_path": [{"time": 0, "position": [0, 0, 3], "target": [0, 0, 0]},
                      {"time": 2.5, "position": [1, 0, 3], "target": [0, 0, 0]}]})");
  const Scene s = load_scene(json.string());
  EXPECT_EQ(s.triangles.size(), 1u);
  EXPECT_EQ(s.name, "s");
  ASSERT_EQ(s.camera_path.size(), 2u);
  EXPECT_FLOAT_EQ(s.camera_path[1].time, 2.5f);
}

struct BadJson {
  const char* label;
  const char* text;
  const char* expected;  // must appear in the message
};

TEST(SceneFile, ErrorsNameTheFileAndKey) {
  TempDir dir;
  const BadJson cases[] = {
      {"unknown key", R"({"generator": "cornell", "camrea": {}})", "'camrea'"},
      {"unknown nested key", R"({"generator": "cornell", "camera": {"fov": 40}})", "camera.fov"},
      {"bad type", R"({"generator": "cornell", "ipd_m": "wide"})", "'ipd_m'"},
      {"bad vector", R"({"generator": "cornell", "camera": {"position": [1, 2]}})", "camera.position"},
      {"vector element", R"({"generator": "cornell", "camera": {"target": [1, "x", 2]}})", "camera.target[1]"},
      {"NaN literal", R"({"generator": "cornell", "ipd_m": NaN})", "line 1"},
      {"overflow", R"({"generator": "cornell", "ipd_m": 1e999})", "1e999"},
      {"too large for float", R"({"generator": "cornell", "ipd_m": 1e300})", "ipd_m"},
      {"syntax", "{\"generator\": \"cornell\",\n \"ipd_m\": 0.06,,\n}", "line 2"},
      {"vfov", R"({"generator": "cornell", "camera": {"vfov_deg": 190}})", "camera.vfov_deg"},
      {"vfov zero", R"({"generator": "cornell", "camera": {"vfov_deg": 0}})", "camera.vfov_deg"},
      {"eye at target", R"({"generator": "cornell", "camera": {"position": [278, 273, 0]}})", "camera.position"},
      {"up parallel", R"({"generator": "cornell", "camera": {"up": [0, 0, 1]}})", "camera.up"},
      {"scale", R"({"generator": "cornell", "meters_per_unit": 0})", "meters_per_unit"},
      {"negative scale", R"({"generator": "cornell", "meters_per_unit": -1})", "meters_per_unit"},
      {"missing mesh", R"({"mesh": "nowhere/gone.obj"})", "gone.obj"},
      {"both", R"({"mesh": "a.obj", "generator": "cornell"})", "exactly one"},
      {"neither", R"({"name": "x"})", "exactly one"},
      {"unknown generator", R"({"generator": "sponza"})", "sponza"},
      {"unknown param", R"({"generator": "atrium", "generator_params": {"detial": 0.1}})", "detial"},
      {"param range", R"({"generator": "atrium", "generator_params": {"detail": -1}})", "detail"},
      {"params without generator", R"({"mesh": "a.obj", "generator_params": {}})", "generator_params"},
      {"path time", R"({"generator": "cornell", "camera_path": [
          {"time": 1, "position": [0, 0, 0], "target": [0, 0, 1]},
          {"time": 1, "position": [0, 0, 0], "target": [0, 0, 1]}]})",
       "camera_path[1].time"},
      {"path key missing", R"({"generator": "cornell", "camera_path": [{"time": 0, "position": [0, 0, 0]}]})",
       "camera_path[0].target"},
      {"sun zero", R"({"generator": "cornell", "sun": {"direction": [0, 0, 0]}})", "sun.direction"},
      // A sun with keys over time (sun_path.h): each bad key is named.
      {"sun keys not array", R"({"generator": "cornell", "sun": {"keys": {"time": 0}}})", "'sun.keys'"},
      {"sun keys empty", R"({"generator": "cornell", "sun": {"keys": []}})", "'sun.keys'"},
      {"sun keys and direction", R"({"generator": "cornell", "sun": {"direction": [0, 1, 0],
          "keys": [{"time": 0, "direction": [0, 1, 0]}]}})",
       "'sun.direction'"},
      {"sun key time missing", R"({"generator": "cornell", "sun": {"keys": [{"direction": [0, 1, 0]}]}})",
       "'sun.keys[0].time'"},
      {"sun key unknown field", R"({"generator": "cornell", "sun": {"keys": [{"time": 0, "dir": [0, 1, 0]}]}})",
       "sun.keys[0].dir"},
      {"sun key negative time", R"({"generator": "cornell", "sun": {"keys": [{"time": -1, "direction": [0, 1, 0]}]}})",
       "'sun.keys[0].time'"},
      {"sun key time order", R"({"generator": "cornell", "sun": {"keys": [{"time": 0, "direction": [0, 1, 0]},
          {"time": 2, "direction": [1, 1, 0]}, {"time": 2, "direction": [1, 0, 0]}]}})",
       "'sun.keys[2].time'"},
      {"sun key zero direction", R"({"generator": "cornell", "sun": {"keys": [{"time": 0, "direction": [0, 1, 0]},
          {"time": 1, "direction": [0, 0, 0]}]}})",
       "'sun.keys[1].direction'"},
      {"sun key bad direction",
       R"({"generator": "cornell", "sun": {"keys": [{"time": 0, "direction": [0, "up", 0]}]}})",
       "sun.keys[0].direction[1]"},
      {"sun keys opposite", R"({"generator": "cornell", "sun": {"keys": [{"time": 0, "direction": [1, 0, 0]},
          {"time": 1, "direction": [-2, 0, 0]}]}})",
       "'sun.keys[1].direction'"},
      {"sky negative", R"({"generator": "cornell", "sky": {"zenith": [0, -1, 0]}})", "sky.zenith"},
      {"duplicate", R"({"generator": "cornell", "ipd_m": 0.06, "ipd_m": 0.07})", "ipd_m"},
      {"not an object", R"([1, 2, 3])", "object"},
  };
  int index = 0;
  for (const BadJson& c : cases) {
    const std::string file = "case" + std::to_string(index++) + ".json";
    const fs::path path = dir.write(file, c.text);
    const std::string msg = error_of([&] { load_scene(path.string()); });
    EXPECT_NE(msg.find(file), std::string::npos) << c.label << ": " << msg;
    EXPECT_NE(msg.find(c.expected), std::string::npos) << c.label << ": " << msg;
  }
}

TEST(SceneFile, SpecResolution) {
  EXPECT_EQ(load_scene("cornell").triangles.size(), make_builtin_scene("cornell").triangles.size());
  const std::string unknown = error_of([] { load_scene("no-such-scene"); });
  for (const std::string& name : builtin_scene_names()) EXPECT_NE(unknown.find(name), std::string::npos) << unknown;
  EXPECT_NE(error_of([] { load_scene("/nowhere/x.json"); }).find("/nowhere/x.json"), std::string::npos);
  TempDir dir;
  const fs::path txt = dir.write("mesh.txt", "v 0 0 0\n");
  EXPECT_NE(error_of([&] { load_scene(txt.string()); }).find("mesh.txt"), std::string::npos);
  // An OBJ given directly is framed and has no lights: it gets the default sky (and says so),
  // unless asked not to (then it says the image will be black).
  const fs::path obj = dir.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const Scene s = load_scene(obj.string());
  EXPECT_FALSE(s.sun.enabled);
  EXPECT_TRUE(s.sky.enabled);
  EXPECT_EQ(s.sky.zenith, default_sky().zenith);
  EXPECT_GT(s.camera.position.z, 0.0f);
  EXPECT_TRUE(any_warning_contains(s, "no light"));
  EXPECT_TRUE(any_warning_contains(s, "default sky"));
  const Scene unlit = load_scene(obj.string(), {SkyMode::kOff});
  EXPECT_FALSE(unlit.sky.enabled);
  EXPECT_TRUE(any_warning_contains(unlit, "will be black"));
  // The same mesh with a sky from a scene file is lit: no warning, and its own sky is kept.
  const fs::path json = dir.write("lit.json", R"({"mesh": "tri.obj", "sky": {"zenith": [1, 1, 1]}})");
  EXPECT_FALSE(any_warning_contains(load_scene(json.string()), "no light"));
  EXPECT_EQ(load_scene(json.string(), {SkyMode::kOn}).sky.zenith, glm::vec3(1.0f));
  // --sky on adds the default sky beside a scene's emitters.
  const Scene cornell = load_scene("cornell", {SkyMode::kOn});
  EXPECT_TRUE(cornell.sky.enabled);
  EXPECT_FALSE(load_scene("cornell").sky.enabled);
}

// Hostile nesting is refused with a message, not a stack overflow (70,000 levels crashed the
// copy of generator_params); the limit is far above what a scene needs.
TEST(SceneFile, DeepNestingIsAClearError) {
  TempDir dir;
  const int depth = 70000;
  std::string deep = R"({"generator": "cornell", "generator_params": )";
  for (int i = 0; i < depth; ++i) deep += "{\"a\": ";
  deep += "1";
  deep.append(depth, '}');
  deep += "}";
  const fs::path p = dir.write("deep.json", deep);
  const std::string msg = error_of([&] { load_scene(p.string()); });
  EXPECT_NE(msg.find("deep.json"), std::string::npos) << msg;
  EXPECT_NE(msg.find("nested deeper"), std::string::npos) << msg;
  // Arrays count as well.
  const fs::path arrays = dir.write(
      "arrays.json", R"({"generator": "cornell", "name": )" + std::string(depth, '[') + std::string(depth, ']') + "}");
  EXPECT_NE(error_of([&] { load_scene(arrays.string()); }).find("nested deeper"), std::string::npos);
  // Ordinary nesting still loads.
  EXPECT_NO_THROW(
      load_scene(dir.write("ok.json", R"({"generator": "atrium", "generator_params": {"detail": 0.2}})").string()));
}

// Duplicate keys are found in every object (not only the first level) and in long camera paths;
// the check is a hash set per object (the previous callback parser was quadratic in the length
// of the camera_path array: 17 s for 160k keys). No time is asserted; the size shows it runs.
TEST(SceneFile, DuplicateKeysAnywhereAndLongCameraPaths) {
  TempDir dir;
  std::string path = R"({"generator": "cornell", "camera_path": [)";
  const int keys = 20000;
  for (int i = 0; i < keys; ++i) {
    path += i ? ",{\"time\": " : "{\"time\": ";
    path += std::to_string(i);
    path += R"(, "position": [0, 0, 5], "target": [0, 0, 0]})";
  }
  const fs::path ok = dir.write("long.json", path + "]}");
  EXPECT_EQ(load_scene(ok.string()).camera_path.size(), std::size_t(keys));
  const fs::path dup =
      dir.write("dup.json", path + R"(, {"time": 1e6, "position": [0, 0, 5], "target": [0, 0, 0], "time": 2e6}]})");
  const std::string msg = error_of([&] { load_scene(dup.string()); });
  EXPECT_NE(msg.find("dup.json"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'time': duplicate key"), std::string::npos) << msg;
  // The same key in sibling objects is not a duplicate.
  EXPECT_NO_THROW(load_scene(dir.write("siblings.json", R"({"generator": "cornell", "camera": {"up": [0, 1, 0]},
      "sky": {"zenith": [0, 1, 0]}})")
                                 .string()));
}

// Coordinates beyond what float ray tracing resolves are refused on load (they gave an all-NaN
// image with exit 0); geometry far from the origin relative to its size is a warning.
TEST(SceneFile, OutOfRangeCoordinatesAreRefused) {
  TempDir dir;
  const fs::path huge = dir.write("huge.obj", "v -1e19 0 0\nv 1e19 0 0\nv 0 1e19 0\nf 1 2 3\n");
  std::string msg = error_of([&] { load_scene(huge.string()); });
  EXPECT_NE(msg.find("huge.obj"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1e+19"), std::string::npos) << msg;
  msg = error_of([&] {
    load_scene(dir.write("cam.json", R"({"generator": "cornell", "camera": {"position": [1e20, 0, 0]}})").string());
  });
  EXPECT_NE(msg.find("camera position"), std::string::npos) << msg;
  msg = error_of([&] {
    load_scene(dir.write("path.json", R"({"generator": "cornell", "camera_path": [
        {"time": 0, "position": [0, 0, 5], "target": [0, 0, 0]},
        {"time": 1, "position": [0, 0, 5], "target": [0, 3e11, 0]}]})")
                   .string());
  });
  EXPECT_NE(msg.find("camera_path[1].target"), std::string::npos) << msg;
  // Large but in range: loads; a small model far out: loads with a warning.
  EXPECT_NO_THROW(load_scene(dir.write("big.obj", "v -1e9 0 0\nv 1e9 0 0\nv 0 1e9 0\nf 1 2 3\n").string()));
  const Scene far =
      load_scene(dir.write("far.obj", "v 1e6 1e6 1e6\nv 1000001 1e6 1e6\nv 1e6 1000001 1e6\nf 1 2 3\n").string());
  EXPECT_TRUE(any_warning_contains(far, "recentre")) << "far from the origin";
  EXPECT_FALSE(any_warning_contains(load_scene("cornell"), "recentre"));
}

}  // namespace
}  // namespace px

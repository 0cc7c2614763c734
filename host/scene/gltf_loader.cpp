// glTF 2.0 loading (.gltf with external or data-URI buffers, and binary .glb): tinygltf (the
// Debian shared library) parses the file, OpenImageIO decodes its images; this file validates
// and converts.
//
// tinygltf trusts the file's numbers: an accessor or buffer view reaching past its buffer, an
// index beyond the vertex count, a node hierarchy with a cycle, or JSON nested deep enough to
// overflow its recursive value conversion would read out of bounds or crash. So:
//   - before tinygltf sees the file, a pre-scan bounds the JSON nesting depth and checks that
//     every buffer view lies inside its buffer's declared byteLength (image decoding reads
//     through buffer views without checking);
//   - every accessor read here is checked against the bytes actually loaded, every index
//     against the vertex count, and the node walk refuses nodes reached twice.
//
// Material mapping onto the renderer's model (scene.h):
//   baseColorFactor (+ baseColorTexture)  -> diffuse (+ diffuse_texture), scaled by 1 - metallic
//   metallicFactor                        -> specular = mix(0.04, base colour, metallic)
//                                            (a mostly metallic material's specular is also
//                                            tinted by the base colour texture)
//   roughnessFactor                       -> GGX alpha = roughness^2 (0 = perfect mirror)
//   alphaMode MASK + alphaCutoff          -> an alpha cut-out texture (the OBJ map_d path)
//   emissiveFactor x KHR_materials_emissive_strength -> emission (an emissive texture, which
//                                            the renderer cannot vary across a surface, is
//                                            averaged to one colour)
//   normalTexture                         -> normal_texture, normal_scale
//   KHR_materials_transmission >= 0.5     -> smooth dielectric, index from KHR_materials_ior
//   doubleSided                           -> emitters light both faces
//   COLOR_0 (vertex colours)              -> Scene::vertex_colours, multiplying the diffuse colour
//   KHR_lights_punctual directional       -> the sun (the first one; point and spot lights are named)
// Everything else the file asks for is named in one warning line.
//
// Motion: a file with animations keeps its node hierarchy, meshes, skins and clips in
// Scene::rig (scene_rig.h), which poses the scene at any time; translation, rotation and scale
// channels play with STEP, LINEAR and CUBICSPLINE interpolation, and skins (JOINTS_0 and
// WEIGHTS_0, inverse bind matrices) are evaluated on the host. A file without animations is
// posed once here (skins included, at their rest pose) and keeps no rig. Morph targets are named
// in the warning line.
//
// Instances: in a static file, a mesh that several nodes draw is stored once in its own space,
// with one matrix per node (Scene::instancing), and traversed through a two-level BVH; in a file
// that moves, so is each rigid mesh on a node that a clip moves (its matrix changes, its
// triangles do not). SceneLoadOptions::instancing = false draws copies instead.
#include "scene/gltf_converter.h"
#include "scene/gltf_reader.h"
#include "scene/scene_file_bytes.h"
#include "scene/scene_loader.h"

#include <tiny_gltf.h>

#include <filesystem>
#include <string>

namespace px {

namespace fs = std::filesystem;
using gltf::check_gltf_file_size;
using gltf::Converter;
using gltf::ImageLoadLog;
using gltf::kGlbJsonChunk;
using gltf::kGlbMagic;
using gltf::load_image_lenient;
using gltf::one_line;
using gltf::prescan_json;
using gltf::read_u32;

Scene load_gltf(const std::string& path, const SceneLoadOptions& options, bool* has_camera) {
  if (has_camera) *has_camera = false;
  // A file too large for tinygltf is refused before it is mapped (and read in whole).
  if (std::error_code ec; fs::is_regular_file(path, ec)) {
    const std::uintmax_t size = fs::file_size(path, ec);
    if (!ec) check_gltf_file_size(path, static_cast<std::size_t>(size));
  }
  // Mapped, not read: tinygltf copies the buffers it needs out of the file's bytes, which are
  // parsed where they lie in the page cache (scene_file_bytes.h).
  MappedSceneFile file(path, "glTF");
  check_gltf_file_size(path, file.size());
  const unsigned char* bytes = file.data();
  const bool binary = file.size() >= 4 && read_u32(bytes, 0) == kGlbMagic;
  std::string json_text;
  if (binary) {
    if (file.size() < 20) throw SceneError(path + ": truncated GLB file (" + std::to_string(file.size()) + " bytes)");
    const std::uint32_t chunk_length = read_u32(bytes, 12), chunk_type = read_u32(bytes, 16);
    if (chunk_type != kGlbJsonChunk) throw SceneError(path + ": invalid GLB: the first chunk is not JSON");
    if (chunk_length > file.size() - 20)
      throw SceneError(path + ": invalid GLB: the JSON chunk reaches past the end of the file");
    json_text.assign(reinterpret_cast<const char*>(bytes) + 20, chunk_length);
  } else {
    json_text.assign(reinterpret_cast<const char*>(bytes), file.size());
  }
  prescan_json(json_text, path);

  tinygltf::TinyGLTF loader;
  ImageLoadLog images;
  loader.SetImageLoader(&load_image_lenient, &images);
  tinygltf::Model model;
  std::string err, warn;
  const std::string base_dir = fs::absolute(fs::path(path)).parent_path().string();
  const bool ok =
      binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes, unsigned(file.size()), base_dir)
             : loader.LoadASCIIFromString(&model, &err, &warn, json_text.c_str(), unsigned(json_text.size()), base_dir);
  // The model holds copies of the buffers: the file's bytes go before the triangles are made.
  file.release();
  std::string().swap(json_text);
  if (!ok) {
    const std::string why = one_line(err);
    throw SceneError(path + ": cannot load glTF: " + (why.empty() ? "unknown error" : why));
  }

  Scene scene;
  scene.name = fs::path(path).stem().string();
  // Required extensions change what the data means; without them the scene would be wrong.
  for (const std::string& e : model.extensionsRequired)
    if (!Converter::handled_extension(e))
      throw SceneError(path + ": requires glTF extension " + e + ", which parallax does not support");
  // tinygltf's warnings that matter (missing image files) are reported per material below.
  Converter convert(model, path, options, scene);
  convert.failed_images_ = images.failed;
  convert.release_buffers_ = [&model] {
    for (tinygltf::Buffer& b : model.buffers) std::vector<unsigned char>().swap(b.data);
  };
  convert.materials();
  convert.geometry(has_camera);
  convert.finish();

  if (scene.stats.dropped_degenerate > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_degenerate) +
                                   " degenerate (zero-area) triangles");
  if (scene.stats.dropped_nonfinite > 0)
    scene.stats.warnings.push_back(path + ": dropped " + std::to_string(scene.stats.dropped_nonfinite) +
                                   " triangles with non-finite coordinates");
  if (scene.triangles.empty())
    throw SceneError(path +
                     ": no triangles (the default scene has no triangle meshes, or all were "
                     "degenerate or non-finite)");
  if (scene.materials.empty()) {
    Material grey;
    grey.name = "default";
    grey.diffuse = glm::vec3(0.7f);
    scene.materials.push_back(grey);
  }
  return scene;
}

}  // namespace px

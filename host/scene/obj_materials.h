// OBJ materials (obj_loader.cpp): material libraries found and read with their statements, textures
// read once each, and MTL materials turned into the renderer's model.
#pragma once

#include "scene/mtl_statements.h"
#include "scene/scene.h"

#include <tiny_obj_loader.h>

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace px::obj {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Material libraries: looked up beside the OBJ, also under their bare file name (exporters
// often write a path from their own project root, e.g. "mtllib scenes/x.mtl" for a file that
// sits beside the OBJ) and with Windows separators turned around. The directory each material
// came from is kept: its texture paths are relative to it.

class MtlLibraryReader : public tinyobj::MaterialReader {
 public:
  MtlLibraryReader(fs::path obj_dir, std::string obj_path, std::vector<std::string>& warnings)
      : obj_dir_(std::move(obj_dir)), obj_path_(std::move(obj_path)), warnings_(warnings) {}

  bool operator()(const std::string& name, std::vector<tinyobj::material_t>* materials,
                  std::map<std::string, int>* material_map, std::string* warn, std::string* err) override;

  // Where material `i` came from: the directory its textures are relative to, its library
  // file and the statements it wrote.
  struct Origin {
    fs::path directory;
    std::string library;
    MtlStatements statements;
  };
  Origin origin_of(std::size_t i) const { return i < origins_.size() ? origins_[i] : Origin{obj_dir_, obj_path_, {}}; }

 private:
  fs::path obj_dir_;
  std::string obj_path_;
  std::vector<std::string>& warnings_;
  std::vector<Origin> origins_;
};

// ---------------------------------------------------------------------------------------------
// Textures.

// kColour: map_Kd, map_Ks; kAlpha: map_d; kNormal: norm and bump (a direction per texel).
enum class TextureUse { kColour, kAlpha, kNormal };

class TextureCache {
 public:
  TextureCache(Scene& scene, std::string obj_path) : scene_(scene), obj_path_(std::move(obj_path)) {}

  // Returned by get() when `accept` turned the image down (no warning: the caller says why).
  static constexpr int kRejected = -2;

  // Index into scene.textures, or -1 (with a warning) when the file is missing or unreadable.
  // `what` (map_Kd, norm...) names the texture in warnings. `accept`, when given, decides from
  // the pixels whether the image is what the statement needs; a rejected image is not kept (a
  // bump height map would otherwise be uploaded for nothing).
  int get(const std::string& name, const std::vector<fs::path>& dirs, TextureUse use, const std::string& what,
          const std::string& material, bool (*accept)(const Texture&) = nullptr);

 private:
  Scene& scene_;
  std::string obj_path_;
  std::map<std::string, int> index_;
};

// One MTL material with its textures; what it asks for but is not rendered goes to `ignored`.
Material make_material(const tinyobj::material_t& m, const MtlLibraryReader::Origin& origin, const fs::path& obj_dir,
                       TextureCache& textures, IgnoredMtlFeatures& ignored);

}  // namespace px::obj

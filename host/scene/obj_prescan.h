// The OBJ pre-scan (obj_loader.cpp): walks the text with tinyobjloader's line and token rules
// before tinyobjloader sees it, so that bad indices and coordinates are refused or counted with
// their line.
#pragma once

#include <glm/glm.hpp>

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace px::obj {

struct ObjPrescan {
  std::vector<glm::vec3> positions;           // one per "v" line, NaN where unusable
  std::vector<std::size_t> bad_vertex_lines;  // first few lines with unusable coordinates
  std::size_t bad_vertices = 0;
  std::size_t short_faces = 0;  // faces with fewer than 3 corners
  std::size_t first_short_face_line = 0;
  std::size_t face_lines = 0, line_lines = 0, point_lines = 0;
  bool uses_materials = false;
  std::vector<std::string> warnings;
};

ObjPrescan prescan_obj(std::string_view text, const std::string& path);

}  // namespace px::obj

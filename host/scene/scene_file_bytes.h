// Reads a whole scene input file (OBJ, glTF) into memory with the loaders' error messages:
// SceneError "cannot open <kind> file '<path>': no such file / not a regular file / <errno>".
#pragma once

#include <string>

namespace px {

std::string read_scene_file_bytes(const std::string& path, const char* kind);

}  // namespace px

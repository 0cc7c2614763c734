// Which statements each material of an MTL file wrote, and which of them the renderer does
// not model.
//
// tinyobjloader fills every field of its material_t with a default, so "Kd absent" and
// "Kd 0 0 0" look the same to it; the MTL rules need the difference (a map_Kd without Kd is
// the texture's own colour). And a user must hear about statements that change the look but
// are not rendered, so this scanner also keeps the keywords it does not know.
#pragma once

#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace px {

struct MtlStatements {
  std::string material;            // name as tinyobjloader reads it (the rest of the newmtl line)
  std::set<std::string> keywords;  // first token of each statement line, as written
  bool has(const std::string& kw) const { return keywords.count(kw) > 0; }
};

// One entry per material, in file order, with tinyobjloader's rules: a material is created by
// a "newmtl" line with a non-empty name; statements before the first one belong to none.
std::vector<MtlStatements> scan_mtl_statements(std::string_view text);

// Keywords the loader never renders and why none is needed: ambient terms (Ka, map_Ka) have
// no meaning in a path tracer, which computes the light arriving from everywhere itself.
bool is_meaningless_in_path_tracer(const std::string& keyword);

// Keywords the loader models (some only in combination, e.g. Ni for glass): everything else
// a material writes is reported as ignored.
bool is_modelled_mtl_keyword(const std::string& keyword);

// Collects what each MTL file asks for but is not rendered, and says it in one line per file:
//   "lib.mtl: ignored MTL features: map_Ns (materials a, b), bump height map (wall)".
class IgnoredMtlFeatures {
 public:
  void add(const std::string& library, const std::string& feature, const std::string& material);
  // One warning line per library, in the order the libraries were first named.
  std::vector<std::string> warning_lines() const;

 private:
  std::vector<std::string> order_;
  std::map<std::string, std::vector<std::pair<std::string, std::vector<std::string>>>> features_;
};

}  // namespace px

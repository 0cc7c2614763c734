#include "scene/mtl_statements.h"

#include <algorithm>

namespace px {

namespace {

bool is_blank(char c) { return c == ' ' || c == '\t'; }

// Lines split as tinyobjloader's MTL reader splits them: on "\n", "\r\n" or a lone "\r".
template <typename F>
void for_each_line(std::string_view text, F&& visit) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find_first_of("\r\n", pos);
    if (end == std::string_view::npos) end = text.size();
    visit(text.substr(pos, end - pos));
    pos = end;
    if (pos < text.size() && text[pos] == '\r') ++pos;
    if (pos < text.size() && text[pos] == '\n') ++pos;
  }
}

}  // namespace

std::vector<MtlStatements> scan_mtl_statements(std::string_view text) {
  std::vector<MtlStatements> out;
  MtlStatements current;
  bool open = false;  // a material with a name is being read
  auto flush = [&] {
    if (open && !current.material.empty()) out.push_back(std::move(current));
    current = MtlStatements{};
  };
  for_each_line(text, [&](std::string_view line) {
    std::size_t i = 0;
    while (i < line.size() && is_blank(line[i])) ++i;
    line.remove_prefix(i);
    if (line.empty() || line.front() == '#') return;
    std::size_t j = 0;
    while (j < line.size() && !is_blank(line[j])) ++j;
    const std::string keyword(line.substr(0, j));
    if (keyword == "newmtl" && j < line.size()) {
      flush();
      current.material = std::string(line.substr(j + 1));
      open = true;
      return;
    }
    current.keywords.insert(keyword);
  });
  flush();
  return out;
}

bool is_meaningless_in_path_tracer(const std::string& keyword) { return keyword == "Ka" || keyword == "map_Ka"; }

bool is_modelled_mtl_keyword(const std::string& keyword) {
  static const std::set<std::string> kModelled = {"newmtl", "Kd",   "Ks",   "Ke",       "Ns",      "Ni",
                                                  "d",      "Tr",   "Tf",   "illum",    "map_Kd",  "map_Ks",
                                                  "map_d",  "norm", "bump", "map_bump", "map_Bump"};
  return kModelled.count(keyword) > 0;
}

void IgnoredMtlFeatures::add(const std::string& library, const std::string& feature, const std::string& material) {
  auto [it, inserted] = features_.try_emplace(library);
  if (inserted) order_.push_back(library);
  auto& list = it->second;
  auto f = std::find_if(list.begin(), list.end(), [&](const auto& e) { return e.first == feature; });
  if (f == list.end()) {
    list.push_back({feature, {}});
    f = list.end() - 1;
  }
  if (std::find(f->second.begin(), f->second.end(), material) == f->second.end()) f->second.push_back(material);
}

std::vector<std::string> IgnoredMtlFeatures::warning_lines() const {
  std::vector<std::string> lines;
  for (const std::string& library : order_) {
    std::string line = library + ": ignored MTL features (not rendered):";
    bool first = true;
    for (const auto& [feature, materials] : features_.at(library)) {
      line += first ? " " : ", ";
      first = false;
      line += feature + " (";
      // A handful of names says where to look; a long list would bury the line.
      const std::size_t shown = std::min<std::size_t>(materials.size(), 3);
      for (std::size_t k = 0; k < shown; ++k) line += (k ? ", " : "") + materials[k];
      if (materials.size() > shown) line += ", +" + std::to_string(materials.size() - shown) + " more";
      line += ")";
    }
    lines.push_back(std::move(line));
  }
  return lines;
}

}  // namespace px

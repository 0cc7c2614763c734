// The OBJ pre-scan: line splitting with tinyobjloader's rules, and the checks made before it
// parses (obj_prescan.h).
#include "scene/obj_prescan.h"

#include "scene/scene.h"

#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <unordered_set>

namespace px::obj {

namespace {

// ---------------------------------------------------------------------------------------------
// Line splitting with tinyobjloader's rules: "\n", "\r\n" and a lone "\r" end a
// line; a NUL ends its content (tinyobjloader parses through c_str()).

template <typename F>
void for_each_line(std::string_view text, F&& visit) {
  std::size_t line_no = 0, pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find_first_of("\r\n", pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    if (std::size_t nul = line.find('\0'); nul != std::string_view::npos) line = line.substr(0, nul);
    ++line_no;
    visit(line_no, line);
    pos = end;
    if (pos < text.size() && text[pos] == '\r') {
      ++pos;
      if (pos < text.size() && text[pos] == '\n') ++pos;
    } else if (pos < text.size()) {
      ++pos;  // '\n'
    }
  }
}

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view skip_blanks(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size() && is_blank(s[i])) ++i;
  return s.substr(i);
}

// Splits on blanks; empty fields are skipped.
std::vector<std::string_view> split_blanks(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_blank(s[i])) ++i;
    std::size_t j = i;
    while (j < s.size() && !is_blank(s[j])) ++j;
    if (j > i) out.push_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

// True when `line` starts with keyword `kw` followed by a blank (or end of line for keywords
// that may stand alone).
bool has_keyword(std::string_view line, std::string_view kw) {
  return line.size() > kw.size() && line.substr(0, kw.size()) == kw && is_blank(line[kw.size()]);
}

// A coordinate: a complete number token. Overflowing values become Inf (so they count as
// non-finite), underflowing ones are kept as the nearest float.
bool parse_coordinate(std::string_view tok, float& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  if (r.ec == std::errc::result_out_of_range) {
    const std::string copy(tok);
    char* end = nullptr;
    out = float(std::strtod(copy.c_str(), &end));
    return end == copy.c_str() + copy.size();
  }
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size();
}

bool parse_index(std::string_view tok, long long& out) {
  if (!tok.empty() && tok.front() == '+') tok.remove_prefix(1);
  if (tok.empty()) return false;
  const auto r = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return r.ec == std::errc() && r.ptr == tok.data() + tok.size() && out >= std::numeric_limits<int>::min() &&
         out <= std::numeric_limits<int>::max();
}

// ---------------------------------------------------------------------------------------------
// Pre-scan.

[[noreturn]] void fail_at(const std::string& path, std::size_t line, const std::string& what) {
  throw SceneError(path + ":" + std::to_string(line) + ": " + what);
}

}  // namespace

ObjPrescan prescan_obj(std::string_view text, const std::string& path) {
  ObjPrescan scan;
  std::size_t nvt = 0, nvn = 0;
  // Positive indices may refer forwards (tinyobjloader resolves them against the final
  // counts), so those beyond the current count are kept, with their line, and checked once the
  // whole file is read (well-formed files have none).
  std::vector<std::pair<std::size_t, long long>> forward[3];
  const char* kind_name[3] = {"vertex", "texture coordinate", "normal"};
  // A texture coordinate or normal index out of range loses only that attribute: warn (first
  // line) and let the conversion fall back. A bad vertex index loses geometry: refuse.
  std::size_t missing_line[3] = {0, 0, 0};
  auto note_missing_attribute = [&](int kind, std::size_t line_no) {
    if (missing_line[kind] == 0 || line_no < missing_line[kind]) missing_line[kind] = line_no;
  };

  for_each_line(text, [&](std::size_t line_no, std::string_view raw) {
    const std::string_view line = skip_blanks(raw);
    if (line.empty() || line.front() == '#') return;
    if (has_keyword(line, "v")) {
      const auto toks = split_blanks(line.substr(2));
      glm::vec3 p(std::numeric_limits<float>::quiet_NaN());
      bool ok = toks.size() >= 3;
      for (int a = 0; ok && a < 3; ++a) ok = parse_coordinate(toks[a], p[a]) && std::isfinite(p[a]);
      if (!ok) {
        p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
        if (scan.bad_vertices++ < 3) scan.bad_vertex_lines.push_back(line_no);
      }
      scan.positions.push_back(p);
      return;
    }
    if (has_keyword(line, "vt")) {
      ++nvt;
      return;
    }
    if (has_keyword(line, "vn")) {
      ++nvn;
      return;
    }
    if (line.substr(0, 6) == "usemtl") {
      scan.uses_materials = true;
      return;
    }
    const bool face = has_keyword(line, "f");
    if (!face && !has_keyword(line, "l") && !has_keyword(line, "p")) return;
    (face ? scan.face_lines : line.front() == 'l' ? scan.line_lines : scan.point_lines)++;

    const std::size_t counts[3] = {scan.positions.size(), nvt, nvn};
    const auto corners = split_blanks(line.substr(2));
    for (std::string_view corner : corners) {
      // i, i/j, i//k, i/j/k; a present field must be a non-zero integer.
      std::string_view fields[3];
      int nfields = 0;
      std::size_t start = 0;
      bool malformed = false;
      while (true) {
        const std::size_t slash = corner.find('/', start);
        if (nfields == 3) {
          malformed = true;
          break;
        }
        fields[nfields++] = corner.substr(start, slash == std::string_view::npos ? slash : slash - start);
        if (slash == std::string_view::npos) break;
        start = slash + 1;
      }
      // An empty field is only allowed for the texture coordinate of i//k.
      for (int f = 0; f < nfields && !malformed; ++f)
        if (fields[f].empty() && !(f == 1 && nfields == 3)) malformed = true;
      if (malformed) fail_at(path, line_no, "malformed index '" + std::string(corner) + "'");
      for (int f = 0; f < nfields; ++f) {
        if (fields[f].empty()) continue;
        long long idx = 0;
        if (!parse_index(fields[f], idx))
          fail_at(path, line_no, "invalid " + std::string(kind_name[f]) + " index '" + std::string(fields[f]) + "'");
        if (idx == 0)
          fail_at(path, line_no, std::string(kind_name[f]) + " index 0 is invalid (OBJ indices start at 1)");
        if (idx < 0 && -idx > static_cast<long long>(counts[f])) {
          if (f == 0)
            fail_at(path, line_no,
                    "relative vertex index " + std::to_string(idx) + " is out of range (only " +
                        std::to_string(counts[f]) + " defined so far)");
          note_missing_attribute(f, line_no);
        }
        if (idx > static_cast<long long>(counts[f])) forward[f].emplace_back(line_no, idx);
      }
    }
    if (face && corners.size() < 3) {
      if (scan.short_faces++ == 0) scan.first_short_face_line = line_no;
    }
  });

  const std::size_t final_counts[3] = {scan.positions.size(), nvt, nvn};
  for (int f = 0; f < 3; ++f)
    for (const auto& [line_no, idx] : forward[f]) {
      if (idx <= static_cast<long long>(final_counts[f])) continue;
      if (f == 0)
        fail_at(path, line_no,
                "vertex index " + std::to_string(idx) + " is out of range (the file defines " +
                    std::to_string(final_counts[0]) + ")");
      note_missing_attribute(f, line_no);
      break;
    }
  for (int f = 1; f < 3; ++f)
    if (missing_line[f] > 0)
      scan.warnings.push_back(path + ":" + std::to_string(missing_line[f]) + ": " + kind_name[f] +
                              " indices refer to " + kind_name[f] + "s the file does not define; " +
                              (f == 1 ? "using (0, 0)" : "using geometric normals"));
  return scan;
}

}  // namespace px::obj

// The light tree's build and refit (light_tree.h).
#include "render/light_tree.h"

#include "render/scene_tables.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace px {

namespace {

constexpr double kPi = std::numbers::pi;
// The trail is a uint: no leaf deeper than its bits.
constexpr unsigned kMaxDepth = 32;
constexpr int kBuckets = 12;

struct Vec3 {
  double x, y, z;
};
Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 operator*(Vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double length(Vec3 a) { return std::sqrt(dot(a, a)); }
Vec3 load(const float* v) { return {v[0], v[1], v[2]}; }
void store(float* dst, Vec3 v) {
  dst[0] = static_cast<float>(v.x);
  dst[1] = static_cast<float>(v.y);
  dst[2] = static_cast<float>(v.z);
}

double luminance(const float* c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

double safe_acos(double c) { return std::acos(std::clamp(c, -1.0, 1.0)); }

// The angle between unit vectors, accurate near 0 and pi too.
double angle_between(Vec3 a, Vec3 b) {
  if (dot(a, b) < 0.0) return kPi - 2.0 * std::asin(std::min(1.0, length(a + b) / 2.0));
  return 2.0 * std::asin(std::min(1.0, length(b - a) / 2.0));
}

// A union cone is widened by this much (radians) so that float rounding of its cosine never
// leaves a child's normals outside it.
constexpr double kConeSlack = 1e-5;

struct Cone {
  Vec3 w;
  double cos_theta;
};

Cone cone_union(Cone a, Cone b) {
  const double theta_a = safe_acos(a.cos_theta), theta_b = safe_acos(b.cos_theta);
  const double theta_d = angle_between(a.w, b.w);
  if (std::min(theta_d + theta_b, kPi) <= theta_a) return a;
  if (std::min(theta_d + theta_a, kPi) <= theta_b) return b;
  const double theta_o = (theta_a + theta_d + theta_b) / 2.0 + kConeSlack;
  if (theta_o >= kPi) return {a.w, -1.0};
  // Rotate a's axis towards b's by theta_o - theta_a, about the axis perpendicular to both.
  const Vec3 k = cross(a.w, b.w);
  const double k_len = length(k);
  if (k_len == 0.0) return {a.w, -1.0};
  const Vec3 kn = k * (1.0 / k_len);
  const double r = theta_o - kConeSlack - theta_a;
  Vec3 w = a.w * std::cos(r) + cross(kn, a.w) * std::sin(r);
  w = w * (1.0 / length(w));
  return {w, std::cos(theta_o)};
}

// pbrt-v4's EvaluateCost: power x the orientation cone's solid-angle measure x surface area,
// the axis' share of the box (Kr) favouring splits across the box's long side.
double split_cost(const LightBounds& b, int axis) {
  const double theta_o = safe_acos(b.cos_theta_o), theta_e = safe_acos(b.cos_theta_e);
  const double theta_w = std::min(theta_o + theta_e, kPi);
  const double sin_o = std::sin(theta_o);
  const double m_omega =
      2.0 * kPi * (1.0 - b.cos_theta_o) +
      kPi / 2.0 * (2.0 * theta_w * sin_o - std::cos(theta_o - 2.0 * theta_w) - 2.0 * theta_o * sin_o + b.cos_theta_o);
  double ext[3], max_ext = 0.0;
  for (int k = 0; k < 3; ++k) {
    ext[k] = static_cast<double>(b.hi[k]) - b.lo[k];
    max_ext = std::max(max_ext, ext[k]);
  }
  const double kr = ext[axis] > 0.0 ? max_ext / ext[axis] : 1.0;
  const double area = 2.0 * (ext[0] * ext[1] + ext[1] * ext[2] + ext[2] * ext[0]);
  return b.phi * m_omega * kr * area;
}

struct Item {
  LightBounds b;
  float centroid[3];
  std::uint32_t light;
};

unsigned ceil_log2(std::size_t n) {
  unsigned bits = 0;
  while ((std::size_t{1} << bits) < n) ++bits;
  return bits;
}

void node_from_bounds(LightTreeNode& node, const LightBounds& b) {
  std::memcpy(node.bounds_min, b.lo, sizeof b.lo);
  std::memcpy(node.bounds_max, b.hi, sizeof b.hi);
  node.phi = b.phi;
  std::memcpy(node.axis, b.axis, sizeof b.axis);
  node.cos_theta_o = b.cos_theta_o;
  node.cos_theta_e = b.cos_theta_e;
  // What the kernels' importance derives from the fields above, once here rather than at every
  // visit (kernels/shading/light_tree.h).
  node.sin_theta_o = std::sqrt(std::max(0.0f, 1.0f - b.cos_theta_o * b.cos_theta_o));
  const float dx = b.hi[0] - b.lo[0], dy = b.hi[1] - b.lo[1], dz = b.hi[2] - b.lo[2];
  node.radius = 0.5f * std::sqrt(dx * dx + dy * dy + dz * dz);
}

LightBounds bounds_of(const LightTreeNode& node) {
  LightBounds b;
  std::memcpy(b.lo, node.bounds_min, sizeof b.lo);
  std::memcpy(b.hi, node.bounds_max, sizeof b.hi);
  b.phi = node.phi;
  std::memcpy(b.axis, node.axis, sizeof b.axis);
  b.cos_theta_o = node.cos_theta_o;
  b.cos_theta_e = node.cos_theta_e;
  return b;
}

class Builder {
 public:
  Builder(std::vector<LightTreeNode>& nodes, std::vector<std::uint32_t>& trails, std::vector<std::uint8_t>& depths)
      : nodes_(nodes), trails_(trails), depths_(depths) {}

  // Builds the subtree over items [begin, end) and returns its node index.
  std::uint32_t build(Item* begin, Item* end, unsigned depth, std::uint32_t trail) {
    const auto index = static_cast<std::uint32_t>(nodes_.size());
    nodes_.emplace_back();
    const std::size_t count = static_cast<std::size_t>(end - begin);
    if (count == 1) {
      node_from_bounds(nodes_[index], begin->b);
      nodes_[index].child[0] = nodes_[index].child[1] = PX_LIGHT_TREE_LEAF | begin->light;
      trails_[begin->light] = trail;
      depths_[begin->light] = static_cast<std::uint8_t>(depth);
      return index;
    }
    Item* mid = split(begin, end, depth);
    const std::uint32_t left = build(begin, mid, depth + 1, trail);
    const std::uint32_t right = build(mid, end, depth + 1, trail | (std::uint32_t{1} << depth));
    LightTreeNode& node = nodes_[index];
    // From the children, exactly as refit computes it.
    node_from_bounds(node, union_of(bounds_of(nodes_[left]), bounds_of(nodes_[right])));
    node.child[0] = left;
    node.child[1] = right;
    return index;
  }

 private:
  Item* split(Item* begin, Item* end, unsigned depth) {
    const std::size_t count = static_cast<std::size_t>(end - begin);
    float clo[3], chi[3];
    for (int k = 0; k < 3; ++k) {
      clo[k] = std::numeric_limits<float>::infinity();
      chi[k] = -std::numeric_limits<float>::infinity();
    }
    for (const Item* it = begin; it != end; ++it)
      for (int k = 0; k < 3; ++k) {
        clo[k] = std::min(clo[k], it->centroid[k]);
        chi[k] = std::max(chi[k], it->centroid[k]);
      }
    int widest = 0;
    for (int k = 1; k < 3; ++k)
      if (chi[k] - clo[k] > chi[widest] - clo[widest]) widest = k;
    // Deep enough that a lopsided split could pass the trail's bits: halves by count from here on.
    if (depth + ceil_log2(count) < kMaxDepth) {
      double best = std::numeric_limits<double>::infinity();
      int best_axis = -1, best_bucket = -1;
      for (int axis = 0; axis < 3; ++axis) {
        const double extent = static_cast<double>(chi[axis]) - clo[axis];
        if (!(extent > 0.0)) continue;
        std::array<LightBounds, kBuckets> bucket;
        std::array<std::size_t, kBuckets> in{};
        for (const Item* it = begin; it != end; ++it) {
          const int b = bucket_of(it->centroid[axis], clo[axis], extent);
          bucket[b] = in[b]++ == 0 ? it->b : union_of(bucket[b], it->b);
        }
        // Costs of the lower side of each cut, then the upper side while sweeping down.
        std::array<double, kBuckets - 1> below{};
        LightBounds acc;
        std::size_t n = 0;
        for (int b = 0; b < kBuckets - 1; ++b) {
          if (in[b]) acc = n == 0 ? bucket[b] : union_of(acc, bucket[b]);
          n += in[b];
          below[b] = n > 0 ? split_cost(acc, axis) : -1.0;
        }
        n = 0;
        for (int b = kBuckets - 1; b >= 1; --b) {
          if (in[b]) acc = n == 0 ? bucket[b] : union_of(acc, bucket[b]);
          n += in[b];
          if (n == 0 || n == count || below[b - 1] < 0.0) continue;
          const double cost = below[b - 1] + split_cost(acc, axis);
          if (cost < best) {
            best = cost;
            best_axis = axis;
            best_bucket = b - 1;
          }
        }
      }
      if (best_axis >= 0) {
        const double extent = static_cast<double>(chi[best_axis]) - clo[best_axis];
        Item* mid = std::partition(begin, end, [&](const Item& it) {
          return bucket_of(it.centroid[best_axis], clo[best_axis], extent) <= best_bucket;
        });
        if (mid != begin && mid != end) return mid;
      }
    }
    Item* mid = begin + count / 2;
    std::nth_element(begin, mid, end,
                     [widest](const Item& a, const Item& b) { return a.centroid[widest] < b.centroid[widest]; });
    return mid;
  }

  static int bucket_of(float c, float lo, double extent) {
    const int b = static_cast<int>(kBuckets * ((static_cast<double>(c) - lo) / extent));
    return std::clamp(b, 0, kBuckets - 1);
  }

  std::vector<LightTreeNode>& nodes_;
  std::vector<std::uint32_t>& trails_;
  std::vector<std::uint8_t>& depths_;
};

}  // namespace

LightBounds triangle_light_bounds(const LightTriangle& light, bool two_sided) {
  LightBounds b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = std::min({light.v0[k], light.v1[k], light.v2[k]});
    b.hi[k] = std::max({light.v0[k], light.v1[k], light.v2[k]});
  }
  b.phi = static_cast<float>(light.area * luminance(light.emission) * (two_sided ? 2.0 : 1.0));
  const Vec3 v0 = load(light.v0);
  const Vec3 n = cross(load(light.v1) - v0, load(light.v2) - v0);
  const double len = length(n);
  store(b.axis, len > 0.0 ? n * (1.0 / len) : Vec3{0.0, 0.0, 1.0});
  // A degenerate triangle has no normal: the whole sphere keeps the bounds conservative.
  b.cos_theta_o = two_sided || !(len > 0.0) ? -1.0f : 1.0f;
  b.cos_theta_e = 0.0f;
  return b;
}

LightBounds punctual_light_bounds(const LightTriangle& light) {
  LightBounds b;
  std::memcpy(b.lo, light.v0, sizeof b.lo);
  std::memcpy(b.hi, light.v0, sizeof b.hi);
  // Its intensity, as a triangle's area x radiance is its intensity along its normal: the
  // importance's power / d^2 is then what each sends a point facing it.
  b.phi = static_cast<float>(std::max(0.0, luminance(light.emission)));
  const Vec3 axis = load(light.v1);
  const double len = length(axis);
  store(b.axis, len > 0.0 ? axis * (1.0 / len) : Vec3{0.0, 0.0, 1.0});
  // A spot emits within its outer cone (v2[2], its cosine; -1 for a point light: every way).
  b.cos_theta_o = len > 0.0 ? light.v2[2] : -1.0f;
  // theta_e pi/2, as a triangle's: a point inside the cone sees the whole intensity (cos_p 1 >
  // cos_theta_e); one outside, a cosine-weighted remainder (never zero where it could be lit).
  b.cos_theta_e = 0.0f;
  return b;
}

LightBounds light_bounds(const LightTriangle& light, bool two_sided) {
  return light.prim >= PX_LIGHT_PUNCTUAL ? punctual_light_bounds(light) : triangle_light_bounds(light, two_sided);
}

LightBounds union_of(const LightBounds& a, const LightBounds& b) {
  LightBounds u;
  for (int k = 0; k < 3; ++k) {
    u.lo[k] = std::min(a.lo[k], b.lo[k]);
    u.hi[k] = std::max(a.hi[k], b.hi[k]);
  }
  u.phi = a.phi + b.phi;
  const Cone c = cone_union({load(a.axis), a.cos_theta_o}, {load(b.axis), b.cos_theta_o});
  store(u.axis, c.w);
  u.cos_theta_o = static_cast<float>(c.cos_theta);
  u.cos_theta_e = std::min(a.cos_theta_e, b.cos_theta_e);
  return u;
}

LightTree LightTree::build(const std::vector<LightTriangle>& lights, const std::vector<std::uint8_t>& two_sided) {
  if (two_sided.size() != lights.size())
    throw std::logic_error("LightTree::build: two-sidedness for " + std::to_string(two_sided.size()) + " of " +
                           std::to_string(lights.size()) + " lights");
  LightTree tree;
  if (lights.empty()) return tree;
  if (lights.size() > PX_LIGHT_TREE_LEAF)
    throw std::length_error("LightTree::build: more lights than a child reference can name");
  std::vector<Item> items(lights.size());
  for (std::size_t i = 0; i < lights.size(); ++i) {
    Item& it = items[i];
    it.b = light_bounds(lights[i], two_sided[i] != 0);
    for (int k = 0; k < 3; ++k) it.centroid[k] = 0.5f * (it.b.lo[k] + it.b.hi[k]);
    it.light = static_cast<std::uint32_t>(i);
  }
  tree.nodes_.reserve(2 * lights.size() - 1);
  tree.trails_.assign(lights.size(), 0u);
  tree.depths_.assign(lights.size(), 0u);
  Builder(tree.nodes_, tree.trails_, tree.depths_).build(items.data(), items.data() + items.size(), 0, 0u);
  return tree;
}

bool LightTree::refit(const std::vector<LightTriangle>& lights, const std::vector<std::uint8_t>& two_sided) {
  if (lights.size() != trails_.size() || two_sided.size() != lights.size() || lights.empty()) return false;
  // Children follow their parents: from the back, every child is done before its parent.
  for (std::size_t i = nodes_.size(); i-- > 0;) {
    LightTreeNode& node = nodes_[i];
    const std::uint32_t c0 = node.child[0], c1 = node.child[1];
    LightBounds b;
    if (c0 & PX_LIGHT_TREE_LEAF) {
      const std::uint32_t l = c0 & ~PX_LIGHT_TREE_LEAF;
      b = light_bounds(lights[l], two_sided[l] != 0);
    } else {
      b = union_of(bounds_of(nodes_[c0]), bounds_of(nodes_[c1]));
    }
    node_from_bounds(node, b);
  }
  return true;
}

unsigned LightTree::depth() const {
  unsigned d = 0;
  for (std::uint8_t x : depths_) d = std::max<unsigned>(d, x);
  return d;
}

std::vector<std::uint8_t> light_two_sidedness(const Scene& scene, const std::vector<LightTriangle>& lights) {
  std::vector<std::uint8_t> out(lights.size());
  for (std::size_t i = 0; i < lights.size(); ++i)
    out[i] =
        lights[i].prim < PX_LIGHT_PUNCTUAL && scene.materials.at(scene.triangles.at(lights[i].prim).material).two_sided
            ? 1
            : 0;
  return out;
}

namespace {

// The wide node made from interior node `binary` of `nodes` (types.h, LightTreeWideNode), and,
// before it returns, those made from its interior lanes; returns its index in `wide`.
std::uint32_t collapse(const std::vector<LightTreeNode>& nodes, std::uint32_t binary,
                       std::vector<LightTreeWideNode>& wide) {
  const auto is_leaf = [&](std::uint32_t at) { return (nodes[at].child[0] & PX_LIGHT_TREE_LEAF) != 0; };
  const auto index = static_cast<std::uint32_t>(wide.size());
  wide.emplace_back();
  std::uint32_t lanes[4];
  bool used[4];
  for (int side = 0; side < 2; ++side) {
    const std::uint32_t c = nodes[binary].child[side];
    lanes[2 * side] = is_leaf(c) ? c : nodes[c].child[0];
    lanes[2 * side + 1] = is_leaf(c) ? c : nodes[c].child[1];
    used[2 * side] = true;
    used[2 * side + 1] = !is_leaf(c);
  }
  for (int k = 0; k < 4; ++k) {
    // Filled after the recursion: the vector may have moved.
    std::uint32_t child = PX_LIGHT_TREE_EMPTY;
    if (used[k]) child = is_leaf(lanes[k]) ? nodes[lanes[k]].child[0] : collapse(nodes, lanes[k], wide);
    LightTreeWideNode& w = wide[index];
    w.child[k] = child;
    if (!used[k]) continue;  // zero fields: importance 0, and the walk forces it besides
    const LightTreeNode& n = nodes[lanes[k]];
    for (int a = 0; a < 3; ++a) {
      w.bounds_min[a][k] = n.bounds_min[a];
      w.bounds_max[a][k] = n.bounds_max[a];
      w.axis[a][k] = n.axis[a];
    }
    w.phi[k] = n.phi;
    w.cos_theta_o[k] = n.cos_theta_o;
    w.sin_theta_o[k] = n.sin_theta_o;
    w.cos_theta_e[k] = n.cos_theta_e;
    w.radius[k] = n.radius;
  }
  // Lanes with the same box and cones differ only in power wherever the point is: weighing them by
  // power is what the importance would do, without its cost (a Cornell box's one quad lamp).
  LightTreeWideNode& w = wide[index];
  const auto same_shape = [&](int a, int b) {
    for (int c = 0; c < 3; ++c)
      if (w.bounds_min[c][a] != w.bounds_min[c][b] || w.bounds_max[c][a] != w.bounds_max[c][b] ||
          w.axis[c][a] != w.axis[c][b])
        return false;
    return w.cos_theta_o[a] == w.cos_theta_o[b] && w.cos_theta_e[a] == w.cos_theta_e[b];
  };
  bool by_power = true;
  for (int k = 1; k < 4; ++k)
    if (used[k]) by_power = by_power && same_shape(0, k);
  w.by_power = by_power ? 1u : 0u;
  return index;
}

}  // namespace

std::vector<LightTreeWideNode> wide_light_nodes(const LightTree& tree) {
  std::vector<LightTreeWideNode> wide;
  if (tree.light_count() < 2) return wide;
  wide.reserve(tree.nodes().size() / 2 + 1);
  collapse(tree.nodes(), 0, wide);
  return wide;
}

std::vector<LightTriangle> light_buffer(const std::vector<LightTriangle>& lights, const LightTree& tree) {
  if (lights.empty()) return {};
  if (tree.light_count() != lights.size() || tree.nodes().size() != 2 * lights.size() - 1)
    throw std::logic_error("light_buffer: a light tree of another light table");
  constexpr std::size_t kTrailsPerRecord = sizeof(LightTriangle) / sizeof(std::uint32_t);
  const std::size_t trail_records = (lights.size() + kTrailsPerRecord - 1) / kTrailsPerRecord;
  const std::vector<LightTreeWideNode> wide = wide_light_nodes(tree);
  constexpr std::size_t kRecordsPerWideNode = sizeof(LightTreeWideNode) / sizeof(LightTriangle);
  static_assert(sizeof(LightTreeWideNode) == kRecordsPerWideNode * sizeof(LightTriangle));
  std::vector<LightTriangle> out(lights.size() + trail_records + wide.size() * kRecordsPerWideNode);
  std::memcpy(out.data(), lights.data(), lights.size() * sizeof(LightTriangle));
  std::memcpy(out.data() + lights.size(), tree.trails().data(), tree.trails().size() * sizeof(std::uint32_t));
  if (!wide.empty())
    std::memcpy(out.data() + lights.size() + trail_records, wide.data(), wide.size() * sizeof(LightTreeWideNode));
  return out;
}

std::vector<LightTriangle> make_light_buffer(const Scene& scene, std::size_t& light_count, LightTree* tree) {
  const std::vector<LightTriangle> lights = make_light_table(scene);
  light_count = lights.size();
  LightTree built = LightTree::build(lights, light_two_sidedness(scene, lights));
  std::vector<LightTriangle> out = light_buffer(lights, built);
  if (tree) *tree = std::move(built);
  return out;
}

}  // namespace px

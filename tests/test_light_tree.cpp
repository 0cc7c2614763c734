// The light tree (host/render/light_tree.h, kernels/shading/light_tree.h) against independent
// references: a double-precision host evaluation of the importance and the walk, the bounds'
// definition (every node holds its lights), the pmf's sum, sampling frequencies, the geometry of
// which lights can light a point, and images: tree and power converge to the same picture.
#include "bvh/bvh_builder.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "render/device_scene.h"
#include "render/light_tree.h"
#include "render/path_tracer.h"
#include "render/scene_tables.h"
#include "render/stereo_camera.h"
#include "render/wavefront_path_tracer.h"
#include "scene/builtin_scenes.h"
#include "scene/primitives.h"
#include "scene/punctual_light.h"
#include "scene/scene_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <random>

namespace px {
namespace {

constexpr std::size_t kLocalSize = 64;
std::size_t round_up(std::size_t n) { return (n + kLocalSize - 1) / kLocalSize * kLocalSize; }

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

struct D3 {
  double x, y, z;
};
D3 operator-(D3 a, D3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
double dot(D3 a, D3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross(D3 a, D3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double norm(D3 a) { return std::sqrt(dot(a, a)); }
D3 d3(const float* v) { return {v[0], v[1], v[2]}; }

// pbrt-v4's LightBounds::Importance in double, written from its definition: angles, not the
// kernel's sine/cosine subtraction.
double host_importance(const LightTreeNode& node, D3 p, D3 n) {
  const D3 lo = d3(node.bounds_min), hi = d3(node.bounds_max);
  const D3 c{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
  const D3 diag = hi - lo;
  const D3 to_p = p - c;
  const double dist2 = dot(to_p, to_p);
  const double d2 = std::max(dist2, norm(diag) / 2);
  if (!(d2 > 0)) return 0;
  const double dist = std::sqrt(dist2);
  const D3 wi = dist > 0 ? D3{to_p.x / dist, to_p.y / dist, to_p.z / dist} : D3{0, 0, 1};
  const double theta_w = std::acos(std::clamp(dot(d3(node.axis), wi), -1.0, 1.0));
  const double r2 = dot(diag, diag) / 4;
  const double theta_b = dist2 < r2 ? M_PI : std::asin(std::min(1.0, std::sqrt(r2 / dist2)));
  const double theta_o = std::acos(std::clamp<double>(node.cos_theta_o, -1, 1));
  const double theta_e = std::acos(std::clamp<double>(node.cos_theta_e, -1, 1));
  const double theta_p = std::max(0.0, theta_w - theta_o - theta_b);
  if (theta_p >= theta_e) return 0;
  // One-sided at p: wi points from the lights to p, so the light lies along -wi.
  const double theta_i = std::acos(std::clamp(-dot(wi, n), -1.0, 1.0));
  return std::max(0.0, node.phi * std::cos(theta_p) / d2 * std::cos(std::max(0.0, theta_i - theta_b)));
}

// The probability of `light` by walking its trail with host_importance, as the kernels define the
// walk: from an interior node, one of the up to four nodes two levels below (a child that is a
// leaf stands for itself) in proportion to its importance among them.
double host_pmf(const LightTree& tree, D3 p, D3 n, std::size_t light) {
  if (tree.light_count() == 1) return 1.0;
  const auto& nodes = tree.nodes();
  const auto is_leaf = [&](std::uint32_t at) { return (nodes[at].child[0] & PX_LIGHT_TREE_LEAF) != 0; };
  const std::uint32_t trail = tree.trails()[light];
  std::uint32_t at = 0;
  unsigned depth = 0;
  double prob = 1.0;
  while (!is_leaf(at)) {
    std::vector<std::uint32_t> candidates;
    for (std::uint32_t c : nodes[at].child) {
      if (is_leaf(c)) {
        candidates.push_back(c);
      } else {
        candidates.push_back(nodes[c].child[0]);
        candidates.push_back(nodes[c].child[1]);
      }
    }
    // Candidates alike in everything but power are weighed by power (their importances' ratio).
    bool alike = true;
    for (std::uint32_t c : candidates) {
      const LightTreeNode &a = nodes[candidates[0]], &b = nodes[c];
      for (int k = 0; k < 3; ++k)
        alike =
            alike && a.bounds_min[k] == b.bounds_min[k] && a.bounds_max[k] == b.bounds_max[k] && a.axis[k] == b.axis[k];
      alike = alike && a.cos_theta_o == b.cos_theta_o && a.cos_theta_e == b.cos_theta_e;
    }
    const auto weight = [&](std::uint32_t c) { return alike ? double(nodes[c].phi) : host_importance(nodes[c], p, n); };
    double total = 0;
    for (std::uint32_t c : candidates) total += weight(c);
    if (!(total > 0)) return 0;
    const std::uint32_t child = nodes[at].child[(trail >> depth++) & 1u];
    const std::uint32_t next = is_leaf(child) ? child : nodes[child].child[(trail >> depth++) & 1u];
    prob *= weight(next) / total;
    at = next;
  }
  EXPECT_EQ(nodes[at].child[0] & ~PX_LIGHT_TREE_LEAF, light) << "the trail leads to another leaf";
  return prob;
}

// `count` emissive triangles of varied size, orientation, power and sidedness in [-10, 10]^3.
Scene random_lights(std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Scene s;
  for (int m = 0; m < 8; ++m) {
    Material mat;
    mat.emission = glm::vec3(0.1f + 20.0f * u(rng) * u(rng), 0.1f + 5.0f * u(rng), 0.1f + u(rng));
    mat.two_sided = m % 3 == 0;
    s.materials.push_back(mat);
  }
  Material grey;
  s.materials.push_back(grey);
  for (std::size_t i = 0; i < count; ++i) {
    const glm::vec3 c(20.0f * u(rng) - 10.0f, 20.0f * u(rng) - 10.0f, 20.0f * u(rng) - 10.0f);
    const float size = 0.05f + 1.5f * u(rng) * u(rng);
    auto corner = [&] { return c + size * glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f); };
    append_triangle(s.triangles, corner(), corner(), corner(), static_cast<std::uint32_t>(i % 8));
    if (i % 5 == 0) append_triangle(s.triangles, corner(), corner(), corner(), 8);  // not a light: gaps in prims
  }
  return s;
}

struct TreeSetup {
  std::vector<LightTriangle> lights;
  std::vector<std::uint8_t> two_sided;
  LightTree tree;
  explicit TreeSetup(const Scene& s)
      : lights(make_light_table(s)),
        two_sided(light_two_sidedness(s, lights)),
        tree(LightTree::build(lights, two_sided)) {}
};

// Every node's box holds its lights' vertices, its power is theirs summed, its cone holds their
// normals (and every light's trail leads to its leaf, through each node once).
void expect_bounds_hold(const TreeSetup& t) {
  const auto& nodes = t.tree.nodes();
  ASSERT_EQ(nodes.size(), 2 * t.lights.size() - 1);
  std::vector<int> reached(nodes.size(), 0);
  for (std::size_t l = 0; l < t.lights.size(); ++l) {
    const LightTriangle& lt = t.lights[l];
    const D3 v0 = d3(lt.v0), ng = cross(d3(lt.v1) - v0, d3(lt.v2) - v0);
    std::uint32_t at = 0;
    for (unsigned depth = 0;; ++depth) {
      ASSERT_LE(depth, 32u);
      const LightTreeNode& node = nodes[at];
      ++reached[at];
      for (const float* v : {lt.v0, lt.v1, lt.v2})
        for (int k = 0; k < 3; ++k) {
          EXPECT_LE(node.bounds_min[k], v[k]);
          EXPECT_GE(node.bounds_max[k], v[k]);
        }
      if (!t.two_sided[l] && norm(ng) > 0) {
        const double angle = std::atan2(norm(cross(d3(node.axis), ng)), dot(d3(node.axis), ng));
        EXPECT_LE(angle, std::acos(std::clamp<double>(node.cos_theta_o, -1, 1)) + 1e-4) << "node " << at;
      }
      if (node.child[0] & PX_LIGHT_TREE_LEAF) {
        EXPECT_EQ(node.child[0] & ~PX_LIGHT_TREE_LEAF, l);
        break;
      }
      at = node.child[(t.tree.trails()[l] >> depth) & 1u];
    }
  }
  // Power: each interior node's is its children's sum; the root's, the table's total.
  double total = 0;
  for (std::size_t l = 0; l < t.lights.size(); ++l)
    total += triangle_light_bounds(t.lights[l], t.two_sided[l] != 0).phi;
  EXPECT_NEAR(nodes[0].phi, total, 1e-4 * total);
  for (const LightTreeNode& node : nodes)
    if (!(node.child[0] & PX_LIGHT_TREE_LEAF)) {
      EXPECT_NEAR(node.phi, nodes[node.child[0]].phi + nodes[node.child[1]].phi, 1e-5 * node.phi);
    }
}

// The kernel's pmf of every light at each (p, n): out[i * count + k].
std::vector<float> kernel_pmfs(const std::vector<LightTriangle>& buffer, std::size_t count,
                               const std::vector<cl_float4>& p, const std::vector<cl_float4>& n) {
  DeviceSet& set = one_device();
  auto& q = set.devices()[0].queue;
  cl::Buffer lights(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, buffer.size() * sizeof(LightTriangle),
                    const_cast<LightTriangle*>(buffer.data()));
  cl::Buffer pb(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, p.size() * sizeof(cl_float4),
                const_cast<cl_float4*>(p.data()));
  cl::Buffer nb(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, n.size() * sizeof(cl_float4),
                const_cast<cl_float4*>(n.data()));
  std::vector<float> out(p.size() * count);
  cl::Buffer ob(set.context(), CL_MEM_WRITE_ONLY, out.size() * sizeof(float));
  cl::Kernel k(set.program("testing/light_tree_probe.cl"), "light_tree_pmfs");
  k.setArg(0, lights);
  k.setArg(1, static_cast<cl_uint>(count));
  k.setArg(2, pb);
  k.setArg(3, nb);
  k.setArg(4, static_cast<cl_uint>(p.size()));
  k.setArg(5, ob);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(p.size())), cl::NDRange(kLocalSize));
  q.enqueueReadBuffer(ob, CL_TRUE, 0, out.size() * sizeof(float), out.data());
  return out;
}

struct Samples {
  std::vector<cl_int> light;
  std::vector<float> pmf, pmf_again;
};

Samples kernel_samples(const std::vector<LightTriangle>& buffer, std::size_t count, cl_float4 p, cl_float4 n,
                       std::size_t samples) {
  DeviceSet& set = one_device();
  auto& q = set.devices()[0].queue;
  cl::Buffer lights(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, buffer.size() * sizeof(LightTriangle),
                    const_cast<LightTriangle*>(buffer.data()));
  Samples s;
  s.light.resize(samples);
  s.pmf.resize(samples);
  s.pmf_again.resize(samples);
  cl::Buffer lb(set.context(), CL_MEM_WRITE_ONLY, samples * sizeof(cl_int));
  cl::Buffer pb(set.context(), CL_MEM_WRITE_ONLY, samples * sizeof(float));
  cl::Buffer ab(set.context(), CL_MEM_WRITE_ONLY, samples * sizeof(float));
  cl::Kernel k(set.program("testing/light_tree_probe.cl"), "light_tree_samples");
  k.setArg(0, lights);
  k.setArg(1, static_cast<cl_uint>(count));
  k.setArg(2, p);
  k.setArg(3, n);
  k.setArg(4, static_cast<cl_uint>(samples));
  k.setArg(5, lb);
  k.setArg(6, pb);
  k.setArg(7, ab);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(samples)), cl::NDRange(kLocalSize));
  q.enqueueReadBuffer(lb, CL_FALSE, 0, samples * sizeof(cl_int), s.light.data());
  q.enqueueReadBuffer(pb, CL_FALSE, 0, samples * sizeof(float), s.pmf.data());
  q.enqueueReadBuffer(ab, CL_TRUE, 0, samples * sizeof(float), s.pmf_again.data());
  return s;
}

// Random shading points in [-12, 12]^3 with random unit normals.
void random_points(std::size_t count, unsigned seed, std::vector<cl_float4>& p, std::vector<cl_float4>& n) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  std::uniform_real_distribution<float> u(-12.0f, 12.0f);
  for (std::size_t i = 0; i < count; ++i) {
    p.push_back({{u(rng), u(rng), u(rng), 0.0f}});
    glm::vec3 d(g(rng), g(rng), g(rng));
    d = glm::normalize(d);
    n.push_back({{d.x, d.y, d.z, 0.0f}});
  }
}

D3 d3(const cl_float4& v) { return {v.s[0], v.s[1], v.s[2]}; }

TEST(LightTree, BuildBoundsEveryNodesLightsAndStaysShallow) {
  for (std::size_t count : {1u, 2u, 3u, 300u, 5000u}) {
    const TreeSetup t(random_lights(count, 7));
    ASSERT_EQ(t.lights.size(), count);
    expect_bounds_hold(t);
    EXPECT_LE(t.tree.depth(), 32u);
  }
  // Identical lights (no split separates them by position) still make a tree of bounded depth.
  Scene same;
  Material m;
  m.emission = glm::vec3(1.0f);
  same.materials.push_back(m);
  for (int i = 0; i < 3000; ++i)
    append_triangle(same.triangles, glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), 0);
  const TreeSetup t(same);
  EXPECT_LE(t.tree.depth(), 12u);
}

// The pmf's sum at (p, n): 1, less the mass of subtrees that a node's importance sends the walk
// into but none of whose lights can reach p (both children of some node have importance 0 there);
// sampling returns no light (-1) with exactly that probability, so the sum and the fraction of
// stratified samples without a light add up to 1.
void expect_pmf_sums_to_one(const std::vector<LightTriangle>& buffer, std::size_t count, const std::vector<float>& pmf,
                            const std::vector<cl_float4>& p, const std::vector<cl_float4>& n) {
  constexpr std::size_t kSamples = 1u << 14;
  for (std::size_t i = 0; i < p.size(); ++i) {
    double sum = 0;
    for (std::size_t k = 0; k < count; ++k) sum += pmf[i * count + k];
    const Samples s = kernel_samples(buffer, count, p[i], n[i], kSamples);
    const double none = double(std::count(s.light.begin(), s.light.end(), -1)) / kSamples;
    EXPECT_NEAR(sum + none, 1.0, 1e-4 + 64.0 / kSamples) << "point " << i;
    EXPECT_LE(sum, 1.0 + 1e-4) << "point " << i;
  }
}

// Quad lamps (two triangles with one box and one normal each) of varied power: the wide nodes
// made of one quad's triangles weigh them by power (types.h, LightTreeWideNode::by_power); the
// kernel's pmf is the host walk's, which applies the same rule from the binary tree, and the pmf
// sums to 1 below the lamps, where every lamp faces the points. Breaking the rule on either side
// (the flag ignored, or set on lanes of different shape) fails the comparison.
TEST(LightTree, QuadLampsAreWeighedByPowerWithinTheQuad) {
  Scene s;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f), w(0.1f, 1.0f);
  for (int m = 0; m < 6; ++m) {
    Material mat;
    mat.emission = glm::vec3(0.5f + 3.0f * m, 1.0f + m, 2.0f);
    s.materials.push_back(mat);
  }
  for (int i = 0; i < 40; ++i) {
    const glm::vec3 c(u(rng), 8.0f + 0.05f * u(rng), u(rng));
    const glm::vec3 dx(w(rng), 0, 0), dz(0, 0, w(rng));
    const auto m = static_cast<std::uint32_t>(i % 6);
    // Facing down (-y): (c + dx - c) x (c + dx + dz - c) = dx x dz points down.
    append_triangle(s.triangles, c, c + dx, c + dx + dz, m);
    append_triangle(s.triangles, c, c + dx + dz, c + dz, m);
  }
  const TreeSetup t(s);
  const std::size_t count = t.lights.size();
  ASSERT_EQ(count, 80u);
  const std::vector<LightTreeWideNode> wide = wide_light_nodes(t.tree);
  const auto by_power = std::count_if(wide.begin(), wide.end(), [](const LightTreeWideNode& n) { return n.by_power; });
  EXPECT_GE(by_power, 10) << "of " << wide.size() << " wide nodes";
  std::vector<cl_float4> p, n;
  std::uniform_real_distribution<float> floor(-12.0f, 12.0f);
  for (int i = 0; i < 24; ++i) {
    p.push_back({{floor(rng), 0.5f * w(rng), floor(rng), 0.0f}});
    n.push_back({{0.0f, 1.0f, 0.0f, 0.0f}});
  }
  const auto buffer = light_buffer(t.lights, t.tree);
  const std::vector<float> pmf = kernel_pmfs(buffer, count, p, n);
  for (std::size_t i = 0; i < p.size(); ++i) {
    double sum = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const float got = pmf[i * count + k];
      const double want = host_pmf(t.tree, d3(p[i]), d3(n[i]), k);
      EXPECT_NEAR(got, want, 1e-3 * want + 1e-7) << "point " << i << " light " << k;
      sum += got;
    }
    EXPECT_NEAR(sum, 1.0, 1e-4) << "point " << i;
  }
  expect_pmf_sums_to_one(buffer, count, pmf, p, n);
  // One quad lamp of two powers (a root weighed by power): behind it as in front of it, the pmf is
  // the powers' ratio, where importances would give 0 behind (no light; here a light that sends
  // nothing, either way no contribution).
  Scene one;
  one.materials = {s.materials[0], s.materials[5]};
  const glm::vec3 c(0.0f, 8.0f, 0.0f), dx(1.0f, 0, 0), dz(0, 0, 1.0f);
  append_triangle(one.triangles, c, c + dx, c + dx + dz, 0);
  append_triangle(one.triangles, c, c + dx + dz, c + dz, 1);
  const TreeSetup q(one);
  ASSERT_EQ(q.lights.size(), 2u);
  ASSERT_EQ(wide_light_nodes(q.tree).at(0).by_power, 1u);
  const std::vector<cl_float4> sides = {{{0.5f, 0.0f, 0.5f, 0.0f}}, {{0.5f, 12.0f, 0.5f, 0.0f}}};
  const std::vector<cl_float4> up = {{{0.0f, 1.0f, 0.0f, 0.0f}}, {{0.0f, 1.0f, 0.0f, 0.0f}}};
  const std::vector<float> quad_pmf = kernel_pmfs(light_buffer(q.lights, q.tree), 2, sides, up);
  const double phi0 = q.tree.nodes()[q.tree.nodes()[0].child[0]].phi,
               phi1 = q.tree.nodes()[q.tree.nodes()[0].child[1]].phi;
  ASSERT_NE(phi0, phi1);
  for (std::size_t i = 0; i < 2; ++i)
    for (std::size_t k = 0; k < 2; ++k) {
      EXPECT_NEAR(quad_pmf[i * 2 + k], host_pmf(q.tree, d3(sides[i]), d3(up[i]), k), 1e-6) << i << " " << k;
      EXPECT_GT(quad_pmf[i * 2 + k], 0.0f) << i << " " << k;
    }
  EXPECT_NEAR(quad_pmf[0] + quad_pmf[1], 1.0, 1e-6);
}

TEST(LightTree, PmfSumsToOneAndMatchesTheHostWalk) {
  const Scene scene = random_lights(300, 11);
  const TreeSetup t(scene);
  const std::size_t count = t.lights.size();
  std::vector<cl_float4> p, n;
  random_points(48, 5, p, n);
  const auto buffer = light_buffer(t.lights, t.tree);
  const std::vector<float> pmf = kernel_pmfs(buffer, count, p, n);
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const float got = pmf[i * count + k];
      const double want = host_pmf(t.tree, d3(p[i]), d3(n[i]), k);
      // Float against double: a relative tolerance; a node at the edge of theta_e may differ.
      if (std::abs(got - want) > 1e-3 * want + 1e-7) ++mismatches;
    }
  EXPECT_LE(mismatches, p.size() * count / 1000) << "of " << p.size() * count;
  expect_pmf_sums_to_one(buffer, count, pmf, p, n);
  // Lights that all face the points' side (a ceiling of lamps over a floor of points): nothing is
  // lost, the pmf sums to 1.
  Scene ceiling = random_lights(0, 1);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f);
  for (int i = 0; i < 300; ++i) {
    const glm::vec3 c(u(rng), 8.0f + 0.1f * u(rng), u(rng));
    append_triangle(ceiling.triangles, c, c + glm::vec3(0.3f, 0, 0), c + glm::vec3(0, 0.05f * u(rng), 0.3f),
                    static_cast<std::uint32_t>(i % 8));
  }
  const TreeSetup c(ceiling);
  std::vector<cl_float4> floor_p, floor_n;
  for (int i = 0; i < 16; ++i) {
    floor_p.push_back({{u(rng), 0.0f, u(rng), 0.0f}});
    floor_n.push_back({{0.0f, 1.0f, 0.0f, 0.0f}});
  }
  const std::vector<float> floor_pmf = kernel_pmfs(light_buffer(c.lights, c.tree), c.lights.size(), floor_p, floor_n);
  for (std::size_t i = 0; i < floor_p.size(); ++i) {
    double sum = 0;
    for (std::size_t k = 0; k < c.lights.size(); ++k) sum += floor_pmf[i * c.lights.size() + k];
    EXPECT_NEAR(sum, 1.0, 1e-4) << "floor point " << i;
  }
}

// Point and spot lights among the triangles (Scene::punctual_lights, after them in the table):
// each leaf is its light's point with phi its intensity's luminance and the whole sphere (a spot:
// its axis and outer cone); the kernel's pmf is the host walk's with host_importance written from
// angles, and sums to 1 with what sampling finds; the table's pmf is each light's power share.
TEST(LightTree, PointAndSpotLightLeavesAndPmf) {
  Scene scene = random_lights(120, 7);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f);
  for (int i = 0; i < 40; ++i) {
    PunctualLight l;
    l.spot = i % 2 == 1;
    l.position = glm::vec3(u(rng), u(rng), u(rng));
    l.direction = glm::normalize(glm::vec3(u(rng), u(rng), u(rng)));
    l.intensity = glm::vec3(1.0f + std::abs(u(rng)), 2.0f, 0.5f);
    l.inner_cone_rad = 0.2f;
    l.outer_cone_rad = 0.3f + 0.1f * float(i % 7);
    scene.punctual_lights.push_back(l);
  }
  const TreeSetup t(scene);
  const std::size_t count = t.lights.size();
  std::size_t first = count;
  for (std::size_t k = 0; k < count; ++k)
    if (t.lights[k].prim >= PX_LIGHT_PUNCTUAL && first == count) first = k;
  ASSERT_EQ(count - first, 40u);
  for (std::size_t k = first; k < count; ++k) {
    const PunctualLight& l = scene.punctual_lights[t.lights[k].prim - PX_LIGHT_PUNCTUAL];
    EXPECT_EQ(t.lights[k].area, 0.0f);
    if (k > 0) {
      EXPECT_GT(t.lights[k].prim, t.lights[k - 1].prim);  // still sorted by prim
    }
    std::uint32_t at = 0;
    for (unsigned depth = 0; !(t.tree.nodes()[at].child[0] & PX_LIGHT_TREE_LEAF); ++depth)
      at = t.tree.nodes()[at].child[(t.tree.trails()[k] >> depth) & 1u];
    const LightTreeNode& leaf = t.tree.nodes()[at];
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(leaf.bounds_min[c], l.position[c]);
      EXPECT_EQ(leaf.bounds_max[c], l.position[c]);
    }
    EXPECT_NEAR(leaf.phi, 0.2126 * l.intensity.x + 0.7152 * l.intensity.y + 0.0722 * l.intensity.z, 1e-5);
    EXPECT_NEAR(leaf.cos_theta_o, l.spot ? std::cos(l.outer_cone_rad) : -1.0f, 1e-6);
    // The CDF's power: 4 pi I (a spot: the cone halfway between its angles), in watts / pi.
    const double lum = leaf.phi;
    const double want =
        l.spot ? 2.0 * (1.0 - 0.5 * (std::cos(0.2) + std::cos(double(l.outer_cone_rad)))) * lum : 4.0 * lum;
    double total = 0.0;
    for (std::size_t j = 0; j < count; ++j)
      total += j < first ? triangle_light_bounds(t.lights[j], t.two_sided[j] != 0).phi : 0.0;
    for (const PunctualLight& q : scene.punctual_lights) total += punctual_light_power(q);
    EXPECT_NEAR(t.lights[k].pdf_select, want / total, 1e-4 * want / total);
  }
  std::vector<cl_float4> p, n;
  random_points(32, 9, p, n);
  const auto buffer = light_buffer(t.lights, t.tree);
  const std::vector<float> pmf = kernel_pmfs(buffer, count, p, n);
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const double want = host_pmf(t.tree, d3(p[i]), d3(n[i]), k);
      if (std::abs(pmf[i * count + k] - want) > 1e-3 * want + 1e-7) ++mismatches;
    }
  EXPECT_LE(mismatches, p.size() * count / 1000) << "of " << p.size() * count;
  expect_pmf_sums_to_one(buffer, count, pmf, p, n);
}

TEST(LightTree, SamplingFrequenciesMatchThePmfAndItsBits) {
  const TreeSetup t(random_lights(200, 3));
  const std::size_t count = t.lights.size();
  const auto buffer = light_buffer(t.lights, t.tree);
  std::vector<cl_float4> p, n;
  random_points(3, 9, p, n);
  const std::vector<float> pmf = kernel_pmfs(buffer, count, p, n);
  constexpr std::size_t kSamples = 1u << 18;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Samples s = kernel_samples(buffer, count, p[i], n[i], kSamples);
    std::vector<double> freq(count, 0.0);
    std::size_t bit_differences = 0;
    for (std::size_t j = 0; j < kSamples; ++j) {
      if (s.light[j] < 0) continue;  // a subtree none of whose lights reaches p (expect_pmf_sums_to_one)
      const auto l = static_cast<std::size_t>(s.light[j]);
      freq[l] += 1.0 / kSamples;
      bit_differences += std::memcmp(&s.pmf[j], &s.pmf_again[j], sizeof(float)) != 0;
      bit_differences += std::memcmp(&s.pmf[j], &pmf[i * count + l], sizeof(float)) != 0;
    }
    EXPECT_EQ(bit_differences, 0u) << "the sample's pmf is not px_light_tree_pmf's, point " << i;
    // Stratified u: each light gets an interval of length pmf, so frequencies are exact up to one
    // sample per interval boundary crossed.
    for (std::size_t k = 0; k < count; ++k) {
      const double want = pmf[i * count + k];
      if (want == 0.0) {
        EXPECT_EQ(freq[k], 0.0) << "light " << k << " sampled with pmf 0";
      }
      if (want > 1e-3) {
        EXPECT_NEAR(freq[k], want, 0.01 * want + 64.0 / kSamples) << "light " << k;
      }
    }
  }
}

TEST(LightTree, ZeroOnlyWhereTheLightCannotReachThePoint) {
  const TreeSetup t(random_lights(300, 21));
  const std::size_t count = t.lights.size();
  std::vector<cl_float4> p, n;
  random_points(32, 17, p, n);
  const std::vector<float> pmf = kernel_pmfs(light_buffer(t.lights, t.tree), count, p, n);
  std::size_t away = 0, behind = 0, facing = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const LightTriangle& l = t.lights[k];
      const D3 v0 = d3(l.v0), ng = cross(d3(l.v1) - v0, d3(l.v2) - v0);
      const D3 c{(l.v0[0] + l.v1[0] + l.v2[0]) / 3.0, (l.v0[1] + l.v1[1] + l.v2[1]) / 3.0,
                 (l.v0[2] + l.v1[2] + l.v2[2]) / 3.0};
      const D3 to_p = d3(p[i]) - c;
      const double cos_side = dot(to_p, ng) / (norm(to_p) * norm(ng));
      const float got = pmf[i * count + k];
      // How far in front of the point's tangent plane the light's corners reach (cosines).
      double in_front = -1;
      for (const float* v : {l.v0, l.v1, l.v2}) {
        const D3 to_v = d3(v) - d3(p[i]);
        in_front = std::max(in_front, dot(to_v, d3(n[i])) / norm(to_v));
      }
      if ((t.two_sided[k] || cos_side > 1e-3) && in_front > 1e-3) {
        ++facing;
        EXPECT_GT(got, 0.0f) << "light " << k << " faces point " << i;
      }
      if (got == 0.0f) {
        const bool behind_light = !t.two_sided[k] && dot(d3(p[i]) - v0, ng) <= 1e-6;
        EXPECT_TRUE(behind_light || in_front <= 1e-6) << "light " << k << " with pmf 0 lights point " << i;
      }
      // Clearly behind a one-sided light: beyond the angle its box's bounding sphere subtends.
      D3 lo{1e30, 1e30, 1e30}, hi{-1e30, -1e30, -1e30};
      for (const float* v : {l.v0, l.v1, l.v2}) {
        lo = {std::min(lo.x, double(v[0])), std::min(lo.y, double(v[1])), std::min(lo.z, double(v[2]))};
        hi = {std::max(hi.x, double(v[0])), std::max(hi.y, double(v[1])), std::max(hi.z, double(v[2]))};
      }
      const D3 centre{(lo.x + hi.x) / 2, (lo.y + hi.y) / 2, (lo.z + hi.z) / 2};
      const D3 from_box = d3(p[i]) - centre;
      const double d = norm(from_box), r = norm(hi - lo) / 2;
      const double theta_w = std::acos(std::clamp(dot(from_box, ng) / (d * norm(ng)), -1.0, 1.0));
      if (!t.two_sided[k] && d > 2 * r && theta_w > M_PI / 2 + std::asin(r / d) + 0.05) {
        ++away;
        EXPECT_EQ(got, 0.0f) << "light " << k << " faces away from point " << i;
      }
      // Clearly behind the point's tangent plane: no BSDF here reflects what it sends.
      const double theta_i = std::acos(std::clamp(-dot(from_box, d3(n[i])) / d, -1.0, 1.0));
      if (d > 2 * r && theta_i > M_PI / 2 + std::asin(r / d) + 0.05) {
        ++behind;
        EXPECT_EQ(got, 0.0f) << "light " << k << " lies behind point " << i;
      }
    }
  std::printf("[ cases ] behind the light %zu, behind the point %zu, facing %zu\n", away, behind, facing);
  EXPECT_GT(away, 100u);
  EXPECT_GT(behind, 100u);
  EXPECT_GT(facing, 100u);
  // Every light faces away: nothing to sample.
  Scene ceiling;
  Material m;
  m.emission = glm::vec3(4.0f);
  ceiling.materials.push_back(m);
  for (int i = 0; i < 10; ++i) {
    const float x = static_cast<float>(i);
    append_triangle(ceiling.triangles, glm::vec3(x, 5, 0), glm::vec3(x, 5, 1), glm::vec3(x + 1, 5, 0), 0);  // faces -y
  }
  const TreeSetup c(ceiling);  // the triangles face +y
  const auto buffer = light_buffer(c.lights, c.tree);
  const cl_float4 above{{4.0f, 20.0f, 0.5f, 0.0f}}, below{{4.0f, 0.0f, 0.5f, 0.0f}}, up{{0.0f, 1.0f, 0.0f, 0.0f}};
  const Samples s = kernel_samples(buffer, c.lights.size(), below, up, 64);
  for (std::size_t j = 0; j < 64; ++j) {
    EXPECT_EQ(s.light[j], -1);
    EXPECT_EQ(s.pmf[j], 0.0f);
  }
  const cl_float4 down{{0.0f, -1.0f, 0.0f, 0.0f}};
  const Samples b = kernel_samples(buffer, c.lights.size(), above, down, 64);
  for (std::size_t j = 0; j < 64; ++j) EXPECT_GE(b.light[j], 0);
}

TEST(LightTree, RefitAfterMovingLightsKeepsBoundsAndPmf) {
  Scene scene = random_lights(300, 31);
  TreeSetup t(scene);
  const std::size_t count = t.lights.size();
  // Move, turn and scale some emitters; the table keeps its triangles (and order).
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  for (std::size_t i = 0; i < scene.triangles.size(); i += 3) {
    const glm::vec3 shift(u(rng), u(rng), u(rng));
    SceneTriangle& tri = scene.triangles[i];
    tri.p[1] = tri.p[0] + 0.5f * (tri.p[2] - tri.p[0]) + glm::vec3(0.1f * u(rng), 0.2f, 0.0f);
    for (auto& v : tri.p) v += shift;
  }
  const std::vector<LightTriangle> moved = make_light_table(scene);
  ASSERT_EQ(moved.size(), count);
  TreeSetup after = t;
  after.lights = moved;
  ASSERT_TRUE(after.tree.refit(moved, after.two_sided));
  EXPECT_EQ(after.tree.trails(), t.tree.trails());  // the topology stays
  expect_bounds_hold(after);
  std::vector<cl_float4> p, n;
  random_points(24, 8, p, n);
  const auto buffer = light_buffer(moved, after.tree);
  const std::vector<float> pmf = kernel_pmfs(buffer, count, p, n);
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t k = 0; k < count; ++k) {
      const double want = host_pmf(after.tree, d3(p[i]), d3(n[i]), k);
      if (std::abs(pmf[i * count + k] - want) > 1e-3 * want + 1e-7) ++mismatches;
    }
  EXPECT_LE(mismatches, p.size() * count / 1000);
  expect_pmf_sums_to_one(buffer, count, pmf, p, n);
  // A refit of the unmoved lights is the build's tree, to the bit.
  TreeSetup again = t;
  ASSERT_TRUE(again.tree.refit(t.lights, t.two_sided));
  ASSERT_EQ(again.tree.nodes().size(), t.tree.nodes().size());
  EXPECT_EQ(
      std::memcmp(again.tree.nodes().data(), t.tree.nodes().data(), t.tree.nodes().size() * sizeof(LightTreeNode)), 0);
  EXPECT_FALSE(again.tree.refit(std::vector<LightTriangle>(moved.begin(), moved.end() - 1),
                                std::vector<std::uint8_t>(count - 1, 0)));
}

// A floor and a back wall lit by small lamps at varied heights and distances, some two-sided,
// some tilted, of varied colour and power.
Scene lamp_room() {
  Scene s;
  s.name = "lamp-room";
  Material grey;
  grey.diffuse = glm::vec3(0.6f);
  s.materials.push_back(grey);
  append_quad(s.triangles, glm::vec3(-6, 0, -6), glm::vec3(-6, 0, 6), glm::vec3(6, 0, 6), glm::vec3(6, 0, -6), 0);
  append_quad(s.triangles, glm::vec3(-6, 0, -6), glm::vec3(6, 0, -6), glm::vec3(6, 6, -6), glm::vec3(-6, 6, -6), 0);
  append_box(s.triangles, glm::vec3(-1, 0, -1), glm::vec3(1, 1.5f, 1), 0);
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < 24; ++i) {
    Material lamp;
    lamp.emission = glm::vec3(2.0f + 30.0f * u(rng), 2.0f + 20.0f * u(rng), 2.0f + 10.0f * u(rng));
    lamp.two_sided = i % 4 == 0;
    s.materials.push_back(lamp);
    const glm::vec3 c(11.0f * u(rng) - 5.5f, 0.5f + 5.0f * u(rng), 11.0f * u(rng) - 5.5f);
    const float h = 0.05f + 0.2f * u(rng);
    const float tilt = i % 3 == 0 ? 0.5f * h : 0.0f;
    append_quad_facing(s.triangles, c + glm::vec3(-h, tilt, -h), c + glm::vec3(h, tilt, -h), c + glm::vec3(h, -tilt, h),
                       c + glm::vec3(-h, -tilt, h), glm::vec3(0.2f * (u(rng) - 0.5f), -1.0f, 0.0f),
                       static_cast<std::uint32_t>(s.materials.size() - 1));
  }
  s.camera.position = glm::vec3(0.0f, 3.0f, 9.0f);
  s.camera.target = glm::vec3(0.0f, 1.5f, 0.0f);
  s.camera.vfov_deg = 60.0f;
  return s;
}

struct Render {
  Scene scene;
  FlatBvh bvh;
  std::unique_ptr<DeviceScene> device_scene;
  std::unique_ptr<PathTracer> tracer;
  explicit Render(Scene s) : scene(std::move(s)) {
    bvh = build_bvh(scene.triangles);
    device_scene = std::make_unique<DeviceScene>(one_device(), scene, bvh);
    tracer = std::make_unique<PathTracer>(one_device(), *device_scene, scene);
  }
};

double luminance_mean(const ImageRGB& img) {
  double s = 0;
  for (std::size_t i = 0; i < img.rgb.size(); i += 3)
    s += 0.2126 * img.rgb[i] + 0.7152 * img.rgb[i + 1] + 0.0722 * img.rgb[i + 2];
  return s / (img.rgb.size() / 3);
}

double rel_mse(const ImageRGB& a, const ImageRGB& b) {
  double s = 0;
  for (std::size_t i = 0; i < a.rgb.size(); ++i) {
    const double d = a.rgb[i] - b.rgb[i];
    s += d * d / (double(b.rgb[i]) * b.rgb[i] + 0.01);
  }
  return s / a.rgb.size();
}

TEST(LightTree, TreeAndPowerConvergeToTheSameImage) {
  for (Scene scene : {lamp_room(), make_builtin_scene("cornell-glossy")}) {
    Render r(scene);
    PathTracer::Options opt;
    opt.spp = 128;
    opt.bounces = 3;
    opt.direct_light = DirectLight::Power;
    const auto power = r.tracer->render_stereo(0.0f, 0, 32, 24, opt);
    opt.seed = 7;
    const auto power2 = r.tracer->render_stereo(0.0f, 0, 32, 24, opt);
    opt.direct_light = DirectLight::Tree;
    opt.seed = 99;  // independent samples
    const auto tree = r.tracer->render_stereo(0.0f, 0, 32, 24, opt);
    opt.direct_light = DirectLight::Restir;  // render_stereo runs no ReSTIR stage: restir is the tree there
    const auto restir = r.tracer->render_stereo(0.0f, 0, 32, 24, opt);
    for (int e = 0; e < 2; ++e) {
      const double mp = luminance_mean(power[e]), mt = luminance_mean(tree[e]);
      EXPECT_NEAR(mt, mp, 0.04 * mp) << scene.name << " eye " << e;
      // Against power, tree's difference is both noises (a bias would add to them): of the order of
      // power's own between two seeds (at 2048 spp the means agree within 0.2% and the relMSE
      // between the two is that of power against power, within a factor 2: single bright paths).
      const double noise = rel_mse(power2[e], power[e]);
      EXPECT_LT(rel_mse(tree[e], power[e]), 2.0 * noise) << scene.name << " eye " << e;
      std::printf("[ image ] %s eye %d: relMSE tree vs power %.4g, power vs power %.4g; mean %.4g vs %.4g\n",
                  scene.name.c_str(), e, rel_mse(tree[e], power[e]), noise, mt, mp);
      EXPECT_EQ(std::memcmp(tree[e].rgb.data(), restir[e].rgb.data(), tree[e].rgb.size() * sizeof(float)), 0);
    }
    EXPECT_EQ(r.tracer->nonfinite_paths(), 0u);
  }
}

TEST(LightTree, WavefrontGivesTheMegakernelsPixels) {
  // prev_p travels in the path state's spare w components: the wavefront tracer's MIS weights
  // must be the megakernel's, to the bit.
  Render r(lamp_room());
  DeviceSet& set = one_device();
  const cl::CommandQueue& queue = set.devices()[0].queue;
  const unsigned w = 24, h = 16;
  PathTracer::Options opt;
  opt.spp = 3;
  opt.bounces = 4;
  opt.direct_light = DirectLight::Tree;
  const FrameParams fp = PathTracer::frame_params(r.scene, r.device_scene->light_count(), opt, 0, 0, h, 1);
  const CameraParams cam = make_eye_camera(evaluate_camera(r.scene, 0.0f), Eye::Left, r.scene.ipd_units(), w, h);
  const std::size_t bytes = std::size_t{w} * h * sizeof(cl_float4);
  auto run = [&](const std::function<void(const PathTracer::Targets&)>& trace) {
    cl::Buffer radiance(set.context(), CL_MEM_READ_WRITE, bytes), albedo(set.context(), CL_MEM_READ_WRITE, bytes);
    cl::Buffer nonfinite(set.context(), CL_MEM_READ_WRITE, sizeof(cl_uint));
    queue.enqueueFillBuffer(nonfinite, cl_uint{0}, 0, sizeof(cl_uint));
    trace({radiance, albedo, nonfinite});
    std::vector<cl_float4> out(std::size_t{w} * h);
    queue.enqueueReadBuffer(radiance, CL_TRUE, 0, bytes, out.data());
    return out;
  };
  const auto mega = run([&](const PathTracer::Targets& t) {
    PathTracer::launch(queue, set.program("pathtrace/path_trace.cl"), r.device_scene->on(0), t, fp, cam, w);
  });
  WavefrontPathTracer::Scratch scratch;
  const auto wave = run([&](const PathTracer::Targets& t) {
    WavefrontPathTracer::trace_rows(set.context(), queue, set.program("pathtrace/wavefront.cl"), r.device_scene->on(0),
                                    scratch, t, fp, cam, w);
  });
  EXPECT_EQ(std::memcmp(mega.data(), wave.data(), bytes), 0);
  double sum = 0;
  for (const auto& px : mega) sum += px.s[0];
  EXPECT_GT(sum, 0.0);
}

}  // namespace
}  // namespace px

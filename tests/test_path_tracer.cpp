// The path tracer against analytic answers (furnace tests), its BSDF routines against their
// own integrals, its three estimators against each other, and its determinism.
#include "bvh/bvh_builder.h"
#include "bvh/flat_bvh.h"
#include "cl/device_set.h"
#include "cl/launch.h"
#include "denoise/svgf_constants.h"
#include "render/device_scene.h"
#include "render/path_tracer.h"
#include "render/stereo_camera.h"
#include "render/wavefront_path_tracer.h"
#include "scene/builtin_scenes.h"
#include "scene/primitives.h"
#include "scene/scene_loader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <random>

namespace px {
namespace {

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

struct RenderFixture {
  Scene scene;
  FlatBvh bvh;
  std::unique_ptr<DeviceScene> device_scene;
  std::unique_ptr<PathTracer> tracer;
  RenderFixture(DeviceSet& devices, Scene s) : scene(std::move(s)) {
    bvh = build_bvh(scene.triangles);
    device_scene = std::make_unique<DeviceScene>(devices, scene, bvh);
    tracer = std::make_unique<PathTracer>(devices, *device_scene, scene);
  }
  std::array<ImageRGB, 2> render(unsigned w, unsigned h, PathTracer::Options opt, std::uint32_t frame = 0) {
    return tracer->render_stereo(0.0f, frame, w, h, opt);
  }
};

double mean(const ImageRGB& img) {
  double s = 0;
  for (float v : img.rgb) s += v;
  return s / img.rgb.size();
}

double rmse_to(const ImageRGB& img, double value) {
  double s = 0;
  for (float v : img.rgb) s += (v - value) * (v - value);
  return std::sqrt(s / img.rgb.size());
}

// A unit sphere of material `m` at the origin under a uniform white sky (radiance 1 from every
// direction), seen from 3 units away: the furnace set-up.
Scene sphere_in_uniform_sky(const Material& m, int subdivisions) {
  Scene s;
  s.materials.push_back(m);
  append_icosphere(s.triangles, glm::vec3(0.0f), 1.0f, subdivisions, 0);
  s.sky.enabled = true;
  s.sky.zenith = s.sky.horizon = s.sky.ground = glm::vec3(1.0f);
  s.camera.position = glm::vec3(0.0f, 0.0f, -3.0f);
  s.camera.target = glm::vec3(0.0f);
  s.camera.vfov_deg = 50.0f;
  return s;
}

// Inside a closed sphere whose surface has albedo a and emits Le, radiance is Le / (1 - a)
// everywhere (the geometric series of bounces); no other light exists.
Scene closed_emissive_sphere(float albedo, float le) {
  Scene s;
  s.name = "furnace-sphere";
  Material m;
  m.diffuse = glm::vec3(albedo);
  m.emission = glm::vec3(le);
  m.two_sided = true;  // the camera inside sees the faces' backs (outward winding)
  s.materials.push_back(m);
  append_icosphere(s.triangles, glm::vec3(0.0f), 1.0f, 3, 0);
  s.camera.position = glm::vec3(0.0f);
  s.camera.target = glm::vec3(0.0f, 0.0f, 1.0f);
  s.camera.vfov_deg = 90.0f;
  s.ipd_m = 0.062f;
  return s;
}

TEST(PathTracer, FurnaceClosedSphereMatchesGeometricSeries) {
  const float a = 0.5f, le = 0.25f;
  const double expected = le / (1.0 - a);
  RenderFixture f(one_device(), closed_emissive_sphere(a, le));
  PathTracer::Options opt;
  opt.bounces = 64;  // the series' tail beyond 64 bounces is 0.5^65: negligible
  double previous_rmse = 0.0;
  for (unsigned spp : {4u, 64u}) {
    opt.spp = spp;
    auto eyes = f.render(48, 32, opt);
    for (const auto& eye : eyes) EXPECT_NEAR(mean(eye), expected, 0.01 * expected) << spp << " spp";
    const double rmse = rmse_to(eyes[0], expected);
    if (previous_rmse > 0.0) {
      // 16x the samples: error falls by sqrt(16) = 4 for an unbiased estimator (wide band for noise).
      EXPECT_GT(previous_rmse / rmse, 2.8) << "error does not fall as 1/sqrt(spp)";
      EXPECT_LT(previous_rmse / rmse, 5.5);
    }
    previous_rmse = rmse;
  }
  EXPECT_EQ(f.tracer->nonfinite_paths(), 0u);
}

TEST(PathTracer, FurnaceWhiteSphereUnderUniformSky) {
  // A white Lambertian convex object under a uniform sky of radiance 1 reflects exactly 1
  // everywhere; the background is the sky itself. Every pixel must be 1.
  for (auto mode : {LightSampling::Mis, LightSampling::Nee, LightSampling::Bsdf}) {
    Material white;
    white.diffuse = glm::vec3(1.0f);
    RenderFixture f(one_device(), sphere_in_uniform_sky(white, 3));
    PathTracer::Options opt;
    opt.spp = 32;
    opt.bounces = 8;
    opt.light_sampling = mode;
    auto eyes = f.render(40, 30, opt);
    for (const auto& eye : eyes) {
      EXPECT_NEAR(mean(eye), 1.0, 0.01) << "light sampling " << static_cast<int>(mode);
      EXPECT_LT(rmse_to(eye, 1.0), 0.15);
    }
  }
}

// ---- BSDF routines, through the probe kernel ----

struct BsdfCase {
  glm::vec3 diffuse, specular;  // for a dielectric, diffuse is its transmission filter
  float alpha;
  bool mirror;
  glm::vec3 wo;
  float ior = 0.0f;     // > 0: a smooth dielectric of this index
  bool outside = true;  // dielectric: wo lies outside the glass
};

struct ProbeResult {
  std::vector<cl_float4> sample, sample2;
};

// Kernel arguments 3..7 of both probe kernels: the BSDF and the outgoing direction.
void set_case_args(cl::Kernel& k, const BsdfCase& c) {
  k.setArg(3, cl_float4{{c.diffuse.x, c.diffuse.y, c.diffuse.z, 0}});
  k.setArg(4, cl_float4{{c.specular.x, c.specular.y, c.specular.z, c.alpha}});
  k.setArg(5, static_cast<cl_uint>(c.mirror));
  k.setArg(6, cl_float4{{c.wo.x, c.wo.y, c.wo.z, 0}});
  k.setArg(7, cl_float4{{c.ior, c.outside ? 1.0f : 0.0f, 0, 0}});
}

ProbeResult probe_samples(const BsdfCase& c, std::uint32_t count) {
  auto& set = one_device();
  auto& q = set.devices()[0].queue;
  const auto& prog = set.program("testing/bsdf_probe.cl");
  cl::Buffer out(set.context(), CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Buffer out2(set.context(), CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Kernel k(prog, "probe_sample");
  k.setArg(0, out);
  k.setArg(1, out2);
  k.setArg(2, count);
  set_case_args(k, c);
  k.setArg(8, static_cast<cl_uint>(17));
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(count)), cl::NDRange(kLocalSize));
  ProbeResult r;
  r.sample.resize(count);
  r.sample2.resize(count);
  q.enqueueReadBuffer(out, CL_FALSE, 0, count * sizeof(cl_float4), r.sample.data());
  q.enqueueReadBuffer(out2, CL_TRUE, 0, count * sizeof(cl_float4), r.sample2.data());
  return r;
}

std::vector<cl_float4> probe_eval(const BsdfCase& c, const std::vector<cl_float4>& dirs) {
  auto& set = one_device();
  auto& q = set.devices()[0].queue;
  const cl_uint count = static_cast<cl_uint>(dirs.size());
  cl::Buffer in(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, count * sizeof(cl_float4),
                const_cast<cl_float4*>(dirs.data()));
  cl::Buffer out(set.context(), CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Kernel k(set.program("testing/bsdf_probe.cl"), "probe_eval");
  k.setArg(0, in);
  k.setArg(1, out);
  k.setArg(2, count);
  set_case_args(k, c);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(count)), cl::NDRange(kLocalSize));
  std::vector<cl_float4> r(count);
  q.enqueueReadBuffer(out, CL_TRUE, 0, count * sizeof(cl_float4), r.data());
  return r;
}

// Uniform directions over the sphere (host RNG, independent of the kernel's streams).
std::vector<cl_float4> uniform_directions(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<cl_float4> d(n);
  for (auto& v : d) {
    const float z = 1.0f - 2.0f * u(rng), r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = 6.2831853f * u(rng);
    v = {{r * std::cos(phi), r * std::sin(phi), z, 0.0f}};
  }
  return d;
}

const BsdfCase kCases[] = {
    {{0.8f, 0.6f, 0.4f}, {0, 0, 0}, 1.0f, false, {0.3f, 0.1f, 0.9f}},           // Lambertian
    {{0.5f, 0.5f, 0.5f}, {0.3f, 0.3f, 0.3f}, 0.3f, false, {0.5f, 0.0f, 0.6f}},  // diffuse + GGX
    {{0, 0, 0}, {0.9f, 0.9f, 0.9f}, 0.1f, false, {0.2f, 0.3f, 0.8f}},           // sharp GGX
    {{0, 0, 0}, {0.9f, 0.9f, 0.9f}, 0.6f, false, {0.9f, 0.0f, 0.15f}},          // rough GGX, grazing
    {{0.4f, 0.4f, 0.4f}, {0.5f, 0.5f, 0.5f}, 0.0f, true, {0.1f, 0.2f, 0.9f}},   // diffuse + mirror
};

TEST(Bsdf, PdfIntegratesToFractionOfValidSamples) {
  for (const auto& c : kCases) {
    const std::uint32_t n = 1u << 18;
    auto dirs = uniform_directions(n, 3);
    auto ev = probe_eval(c, dirs);
    double pdf_integral = 0.0;
    for (auto& e : ev) pdf_integral += e.s[3] * 4.0 * M_PI / n;
    auto smp = probe_samples(c, n);
    double valid_smooth = 0.0;  // non-delta valid samples
    for (auto& s : smp.sample) valid_smooth += s.s[3] > 0.0f;
    valid_smooth /= n;
    EXPECT_NEAR(pdf_integral, valid_smooth, 0.02) << "alpha " << c.alpha;
    EXPECT_LE(pdf_integral, 1.02);
  }
}

TEST(Bsdf, SampleAndPdfAgree) {
  for (const auto& c : kCases) {
    auto smp = probe_samples(c, 1u << 14);
    int checked = 0;
    for (std::size_t i = 0; i < smp.sample.size(); ++i) {
      const auto& s = smp.sample[i];
      const auto& s2 = smp.sample2[i];
      if (s.s[3] <= 0.0f) continue;  // invalid or delta
      ++checked;
      EXPECT_NEAR(s.s[3], s2.s[3], 1e-3f * s.s[3]) << "pdf from sample vs pdf(): case alpha " << c.alpha;
      // The weight is f cos / pdf: recompute it from eval.
      auto ev = probe_eval(c, {cl_float4{{s.s[0], s.s[1], s.s[2], 0}}});
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(s2.s[k], ev[0].s[k] * s.s[2] / s.s[3], 1e-3f * (1.0f + s2.s[k]));
      if (checked > 50) break;  // the eval round trip is slow; 50 per case is plenty
    }
    EXPECT_GT(checked, 10);
  }
}

TEST(Bsdf, SampledDistributionMatchesPdfAndAlbedo) {
  // Directional albedo two ways: E[weight] over the kernel's samples, and the integral of
  // f cos over uniform directions. And a binned comparison of the sample histogram with the
  // pdf's mass per bin (8 x 8 bins in cos(theta) and phi).
  for (const auto& c : kCases) {
    const std::uint32_t n = 1u << 18;
    auto smp = probe_samples(c, n);
    double albedo_sampled = 0.0;
    std::vector<double> hist(64, 0.0);
    auto bin_of = [](float x, float y, float z) {
      const int bz = std::min(7, static_cast<int>(std::max(0.0f, z) * 8.0f));
      float phi = std::atan2(y, x);
      if (phi < 0) phi += 6.2831853f;
      const int bp = std::min(7, static_cast<int>(phi / 6.2831853f * 8.0f));
      return bz * 8 + bp;
    };
    double delta_weight = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto& s = smp.sample[i];
      const auto& w = smp.sample2[i];
      const double lum = (w.s[0] + w.s[1] + w.s[2]) / 3.0;
      if (s.s[3] < 0.0f) {  // delta lobe
        delta_weight += lum;
        continue;
      }
      albedo_sampled += lum;
      if (s.s[3] > 0.0f && s.s[2] > 0.0f) hist[bin_of(s.s[0], s.s[1], s.s[2])] += 1.0;
    }
    albedo_sampled /= n;
    delta_weight /= n;
    auto dirs = uniform_directions(n, 9);
    auto ev = probe_eval(c, dirs);
    double albedo_integral = 0.0;
    std::vector<double> mass(64, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& d = dirs[i];
      if (d.s[2] <= 0.0f) continue;
      albedo_integral += (ev[i].s[0] + ev[i].s[1] + ev[i].s[2]) / 3.0 * d.s[2] * 4.0 * M_PI / n;
      mass[bin_of(d.s[0], d.s[1], d.s[2])] += ev[i].s[3] * 4.0 * M_PI / n;
    }
    EXPECT_NEAR(albedo_sampled, albedo_integral, 0.02 + 0.03 * albedo_integral) << "alpha " << c.alpha;
    if (c.mirror) {
      EXPECT_NEAR(delta_weight, 0.5, 0.01);  // mirror reflects ks = 0.5 exactly
    }
    EXPECT_LE(albedo_integral + delta_weight, 1.01) << "energy gain";
    for (int b = 0; b < 64; ++b) {
      const double expected = mass[b] * n;
      if (expected < 2000) continue;  // sparse bins are too noisy in either estimate
      EXPECT_NEAR(hist[b], expected, 0.06 * expected + 4.0 * std::sqrt(expected))
          << "bin " << b << " alpha " << c.alpha;
    }
  }
}

// ---- GGX against an independent implementation ----
//
// What shading/bsdf.h claims its opaque BSDF is, written again here in double precision from
// the textbook forms rather than from the kernel's code:
//   f(wo, wi) = kd (1 - max ks) / pi + ks D(h) G(wo, wi) / (4 cos_o cos_i),
//   D: Trowbridge-Reitz (GGX) with the stored alpha, D = 1 / (pi a^2 cos^4 (1 + tan^2 / a^2)^2);
//   G: the separable Smith form G1(wo) G1(wi), G1 = 1 / (1 + Lambda),
//      Lambda = (sqrt(1 + a^2 tan^2) - 1) / 2 (Heitz 2014, eq. 72);
//   no Fresnel: ks is a constant reflectance, so ks = 1 is a white specular surface.
// The tests compare the kernel's f with these pointwise, and its directional albedo (from its
// eval and from its sampling weights) with a quadrature of these, which is itself checked
// against the masking identity and a second quadrature.
namespace ggx {

struct Dir {
  double x, y, z;
};
Dir unit(double x, double y, double z) {
  const double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}
double dot(Dir a, Dir b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Dir from_float(const cl_float4& v) { return {v.s[0], v.s[1], v.s[2]}; }
cl_float4 to_float(Dir d) {
  return {{static_cast<float>(d.x), static_cast<float>(d.y), static_cast<float>(d.z), 0.0f}};
}
// The view direction at cos(theta) = c, in the xz-plane.
Dir view(double c) { return {std::sqrt(std::max(0.0, 1.0 - c * c)), 0.0, c}; }

double tan2(double c) { return (1.0 - c * c) / (c * c); }
double distribution(double cos_h, double a) {
  if (cos_h <= 0.0) return 0.0;
  const double e = 1.0 + tan2(cos_h) / (a * a);
  return 1.0 / (M_PI * a * a * std::pow(cos_h, 4) * e * e);
}
double lambda(double cos_v, double a) { return 0.5 * (std::sqrt(1.0 + a * a * tan2(cos_v)) - 1.0); }
double masking(double cos_v, double a) { return 1.0 / (1.0 + lambda(cos_v, a)); }

// The specular lobe with ks = 1; `correlated`: the height-correlated Smith G 1 / (1 + Lo + Li)
// instead of the separable one (for comparison only: the renderer claims the separable form).
double specular(Dir wo, Dir wi, double a, bool correlated = false) {
  if (wo.z <= 0.0 || wi.z <= 0.0) return 0.0;
  const Dir h = unit(wo.x + wi.x, wo.y + wi.y, wo.z + wi.z);
  const double g = correlated ? 1.0 / (1.0 + lambda(wo.z, a) + lambda(wi.z, a)) : masking(wo.z, a) * masking(wi.z, a);
  return distribution(h.z, a) * g / (4.0 * wo.z * wi.z);
}

// The half-vector h at grid variables (s, phi): u = 1 - s^2, tan^2(theta_h) = a^2 u / (1 - u),
// the map under which D(h) cos(theta_h) d(omega_h) = du dphi / (2 pi) = s ds dphi / pi. In s
// (not u) the integrands below stay bounded as theta_h -> 90 degrees (cos_h ~ s / a).
Dir half_vector(double s, double phi, double a) {
  const double u = 1.0 - s * s;
  const double c2 = (1.0 - u) / (1.0 - u + a * a * u);  // cos^2 theta_h, without 0 / 0 at u = 1
  const double c = std::sqrt(c2), r = std::sqrt(std::max(0.0, 1.0 - c2));
  return {r * std::cos(phi), r * std::sin(phi), c};
}

// Quadrature nodes for integrals over wi (above the surface) of functions peaked around wo's
// mirror direction: midpoint rule in (s, phi), phi over [0, pi) only (wo lies in the xz-plane,
// everything here is symmetric in y), wi the reflection of wo about h. The weight w makes
// sum w g(wi) approximate the integral of g over solid angle: d(omega_i) = 4 (wo.h) d(omega_h).
struct Node {
  Dir wi;
  double w;
};
std::vector<Node> albedo_nodes(Dir wo, double a, int ns, int nphi) {
  std::vector<Node> nodes;
  nodes.reserve(static_cast<std::size_t>(ns) * nphi);
  const double ds = 1.0 / ns, dphi = M_PI / nphi;
  for (int i = 0; i < ns; ++i) {
    const double s = (i + 0.5) * ds;
    for (int j = 0; j < nphi; ++j) {
      const Dir h = half_vector(s, (j + 0.5) * dphi, a);
      const double oh = dot(wo, h);
      if (oh <= 0.0) continue;
      const Dir wi{2.0 * oh * h.x - wo.x, 2.0 * oh * h.y - wo.y, 2.0 * oh * h.z - wo.z};
      if (wi.z <= 0.0) continue;
      const double dens = s / M_PI;  // D cos_h per unit (s, phi)
      nodes.push_back({wi, 2.0 * ds * dphi * dens * 4.0 * oh / (distribution(h.z, a) * h.z)});
    }
  }
  return nodes;
}

// Directional albedo of the ks = 1 lobe: the integral of f cos_i over wi.
double albedo(Dir wo, double a, bool correlated = false, int ns = 1024, int nphi = 512) {
  double e = 0.0;
  for (const auto& n : albedo_nodes(wo, a, ns, nphi)) e += n.w * specular(wo, n.wi, a, correlated) * n.wi.z;
  return e;
}

}  // namespace ggx

// The kernel's f at pairs (wo[i], wi[i]), through testing/ggx_probe.cl: (f.xyz, pdf).
std::vector<cl_float4> ggx_eval(glm::vec3 kd, glm::vec3 ks, float alpha, const std::vector<cl_float4>& wo,
                                const std::vector<cl_float4>& wi) {
  auto& set = one_device();
  auto& q = set.devices()[0].queue;
  const cl_uint count = static_cast<cl_uint>(wi.size());
  cl::Buffer bo(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, count * sizeof(cl_float4),
                const_cast<cl_float4*>(wo.data()));
  cl::Buffer bi(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, count * sizeof(cl_float4),
                const_cast<cl_float4*>(wi.data()));
  cl::Buffer out(set.context(), CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Kernel k(set.program("testing/ggx_probe.cl"), "ggx_eval");
  k.setArg(0, bo);
  k.setArg(1, bi);
  k.setArg(2, out);
  k.setArg(3, count);
  k.setArg(4, cl_float4{{kd.x, kd.y, kd.z, 0.0f}});
  k.setArg(5, cl_float4{{ks.x, ks.y, ks.z, alpha}});
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(count)), cl::NDRange(kLocalSize));
  std::vector<cl_float4> r(count);
  q.enqueueReadBuffer(out, CL_TRUE, 0, count * sizeof(cl_float4), r.data());
  return r;
}

// `count` samples of the kernel's px_bsdf_sample from wo: (weight.xyz, 1 if valid else 0).
std::vector<cl_float4> ggx_sample(glm::vec3 ks, float alpha, ggx::Dir wo, cl_uint count, cl_uint seed) {
  auto& set = one_device();
  auto& q = set.devices()[0].queue;
  cl::Buffer out(set.context(), CL_MEM_WRITE_ONLY, count * sizeof(cl_float4));
  cl::Kernel k(set.program("testing/ggx_probe.cl"), "ggx_sample");
  k.setArg(0, out);
  k.setArg(1, count);
  k.setArg(2, cl_float4{{0.0f, 0.0f, 0.0f, 0.0f}});
  k.setArg(3, cl_float4{{ks.x, ks.y, ks.z, alpha}});
  k.setArg(4, ggx::to_float(wo));
  k.setArg(5, seed);
  q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(count)), cl::NDRange(kLocalSize));
  std::vector<cl_float4> r(count);
  q.enqueueReadBuffer(out, CL_TRUE, 0, count * sizeof(cl_float4), r.data());
  return r;
}

const double kGgxAlphas[] = {0.05, 0.2, 0.5, 1.0};
const double kGgxViewCos[] = {1.0, 0.5, 0.1};  // normal, 60 degrees, grazing (84 degrees)

TEST(Ggx, HostReferenceSatisfiesTheMaskingIdentityAndAgreesWithAPlainQuadrature) {
  for (double a : kGgxAlphas)
    for (double c : kGgxViewCos) {
      const ggx::Dir wo = ggx::view(c);
      // Smith masking is normalised so that the projected area of the visible microfacets is
      // the macro-surface's: integral of G1(wo) D(h) max(0, wo.h) d(omega_h) = cos_o (Heitz
      // 2014, eq. 18). Checks D, Lambda and the (s, phi) map together; f plays no part.
      const int ns = 1024, nphi = 512;
      double projected = 0.0;
      for (int i = 0; i < ns; ++i)
        for (int j = 0; j < nphi; ++j) {
          const ggx::Dir h = ggx::half_vector((i + 0.5) / ns, (j + 0.5) * M_PI / nphi, a);
          const double s = (i + 0.5) / ns;
          projected += 2.0 / ns * (M_PI / nphi) * (s / M_PI) * std::max(0.0, ggx::dot(wo, h)) / h.z;
        }
      EXPECT_NEAR(ggx::masking(c, a) * projected, c, 2e-4 * c) << "alpha " << a << " cos_o " << c;
      // The albedo is at most 1 (white furnace: single scattering loses energy, never gains it),
      // and the separable G masks more than the height-correlated one.
      const double e = ggx::albedo(wo, a), e_corr = ggx::albedo(wo, a, true);
      EXPECT_LE(e, 1.0) << "alpha " << a << " cos_o " << c;
      EXPECT_LE(e, e_corr + 1e-9);
      EXPECT_LE(e_corr, 1.0);
      std::printf(
          "[ measure  ] GGX ks 1, alpha %.2f, cos_o %.1f: albedo %.5f (separable G), %.5f (height-correlated)\n", a, c,
          e, e_corr);
      // Converged: half the nodes each way change nothing that matters (measured: 2e-5 at most;
      // twice the nodes, 5e-6).
      EXPECT_NEAR(ggx::albedo(wo, a, false, 512, 256), e, 1e-4) << "alpha " << a << " cos_o " << c;
      // Where the lobe is wide, a plain midpoint rule over wi = (cos theta_i, phi) must agree:
      // checks the half-vector map's Jacobian.
      if (a >= 0.5) {
        const int nm = 1000, np = 500;
        double plain = 0.0;
        for (int i = 0; i < nm; ++i)
          for (int j = 0; j < np; ++j) {
            const double mu = (i + 0.5) / nm, phi = (j + 0.5) * M_PI / np, r = std::sqrt(1.0 - mu * mu);
            plain +=
                2.0 * (1.0 / nm) * (M_PI / np) * ggx::specular(wo, {r * std::cos(phi), r * std::sin(phi), mu}, a) * mu;
          }
        EXPECT_NEAR(plain, e, 1e-3) << "alpha " << a << " cos_o " << c;
      }
    }
}

TEST(Ggx, AlbedoAtNormalIncidenceOfTheRoughestLobeIsOneMinusLn2) {
  // alpha = 1: D = 1 / pi for every h, G1(n) = 1 and G1(mu) = 2 mu / (1 + mu), so
  // E(n) = (1 / 4 pi) integral of G1(cos_i) d(omega_i) = (1 / 2) integral_0^1 2 mu / (1 + mu) d mu
  //      = 1 - ln 2, a closed form that neither quadrature nor kernel is needed for.
  EXPECT_NEAR(ggx::albedo(ggx::view(1.0), 1.0), 1.0 - std::log(2.0), 1e-4);
  const auto nodes = ggx::albedo_nodes(ggx::view(1.0), 1.0, 256, 128);
  std::vector<cl_float4> wo(nodes.size(), ggx::to_float(ggx::view(1.0))), wi;
  for (const auto& n : nodes) wi.push_back(ggx::to_float(n.wi));
  const auto ev = ggx_eval(glm::vec3(0.0f), glm::vec3(1.0f), 1.0f, wo, wi);
  double e = 0.0;
  for (std::size_t n = 0; n < nodes.size(); ++n) e += nodes[n].w * ev[n].s[0] * nodes[n].wi.z;
  EXPECT_NEAR(e, 1.0 - std::log(2.0), 1e-3) << "the kernel's lobe";
}

TEST(Ggx, EvalMatchesTheIndependentFormulaPointwise) {
  // Random pairs, half of them near the lobe's peak (wi drawn through the half-vector map from
  // host random numbers), for a white lobe alone and for a tinted lobe over a diffuse base.
  struct Colours {
    glm::vec3 kd, ks;
  };
  const Colours colours[] = {{glm::vec3(0.0f), glm::vec3(1.0f)},
                             {glm::vec3(0.5f, 0.7f, 0.9f), glm::vec3(0.6f, 0.3f, 0.15f)}};
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (double a : kGgxAlphas)
    for (const auto& col : colours) {
      std::vector<cl_float4> wo, wi;
      for (double c : kGgxViewCos)
        for (int k = 0; k < 64; ++k) {
          const ggx::Dir o = ggx::view(c);
          ggx::Dir i;
          if (k % 2 == 0) {
            const ggx::Dir h = ggx::half_vector(std::sqrt(u01(rng)), 2.0 * M_PI * u01(rng), a);
            const double oh = ggx::dot(o, h);
            i = {2.0 * oh * h.x - o.x, 2.0 * oh * h.y - o.y, 2.0 * oh * h.z - o.z};
          } else {
            i = ggx::unit(2.0 * u01(rng) - 1.0, 2.0 * u01(rng) - 1.0, u01(rng));
          }
          if (i.z < 0.02) continue;  // below or at the horizon: f is 0 there, nothing to compare
          wo.push_back(ggx::to_float(o));
          wi.push_back(ggx::to_float(i));
        }
      const auto ev = ggx_eval(col.kd, col.ks, static_cast<float>(a), wo, wi);
      const double ks_max = std::max({col.ks.x, col.ks.y, col.ks.z});
      // Float rounding: near the peak D's denominator 1 - cos_h^2 (1 - a^2) ~ a^2 cancels about
      // 1 / a^2 of single precision (measured: 2e-4 at alpha 0.05, 1e-5 at 0.2, 2e-7 at 1).
      const double tolerance = 1e-5 + 1e-6 / (a * a);
      double worst = 0.0;
      for (std::size_t n = 0; n < wi.size(); ++n) {
        // The directions the kernel saw (floats), renormalised in double.
        const ggx::Dir o = ggx::from_float(wo[n]), i = ggx::from_float(wi[n]);
        const double spec = ggx::specular(o, i, a);
        for (int ch = 0; ch < 3; ++ch) {
          const double expected = col.kd[ch] * (1.0 - ks_max) / M_PI + col.ks[ch] * spec;
          const double rel = std::abs(ev[n].s[ch] - expected) / expected;
          worst = std::max(worst, rel);
          EXPECT_NEAR(ev[n].s[ch], expected, tolerance * expected)
              << "alpha " << a << " channel " << ch << " cos_o " << o.z << " wi (" << i.x << ", " << i.y << ", " << i.z
              << ")";
        }
      }
      std::printf("[ measure  ] alpha %.2f kd %.1f: %zu pairs, largest relative difference %.2e\n", a, col.kd.x,
                  wi.size(), worst);
    }
}

TEST(Ggx, DirectionalAlbedoFromEvalAndFromSamplingMatchesTheQuadrature) {
  // White specular (ks = 1, so the diffuse part is 0): a white furnace for the lobe alone. Its
  // albedo is what single scattering keeps, below 1; the kernel's must be the quadrature's, both
  // integrated from its eval and as the mean of its sampling weights f cos / pdf.
  for (double a : kGgxAlphas)
    for (double c : kGgxViewCos) {
      const ggx::Dir wo = ggx::view(c);
      const double expected = ggx::albedo(wo, a);
      const auto nodes = ggx::albedo_nodes(wo, a, 256, 128);
      std::vector<cl_float4> wos(nodes.size(), ggx::to_float(wo)), wis;
      wis.reserve(nodes.size());
      for (const auto& n : nodes) wis.push_back(ggx::to_float(n.wi));
      const auto ev = ggx_eval(glm::vec3(0.0f), glm::vec3(1.0f), static_cast<float>(a), wos, wis);
      double from_eval = 0.0;
      for (std::size_t n = 0; n < nodes.size(); ++n) from_eval += nodes[n].w * ev[n].s[0] * nodes[n].wi.z;
      const cl_uint count = 1u << 17;
      const auto smp = ggx_sample(glm::vec3(1.0f), static_cast<float>(a), wo, count, 5);
      double sum = 0.0, sum2 = 0.0;
      for (const auto& s : smp) {
        sum += s.s[0];
        sum2 += double(s.s[0]) * s.s[0];
      }
      const double sampled = sum / count, se = std::sqrt(std::max(0.0, sum2 / count - sampled * sampled) / count);
      std::printf(
          "[ measure  ] alpha %.2f cos_o %.1f: albedo quadrature %.5f, kernel eval %.5f, kernel sampling "
          "%.5f +- %.5f\n",
          a, c, expected, from_eval, sampled, se);
      EXPECT_NEAR(from_eval, expected, 1e-3) << "alpha " << a << " cos_o " << c;
      EXPECT_NEAR(sampled, expected, 5.0 * se + 1e-3) << "alpha " << a << " cos_o " << c;
      EXPECT_LE(from_eval, 1.0 + 1e-3);
      EXPECT_LE(sampled, 1.0 + 5.0 * se);
    }
}

// A large GGX plane z = 0 of alpha `alpha` and ks 1 under a uniform sky of radiance 1, seen
// through a narrow view at `theta` degrees from its normal. The plane sees only the sky, so
// with one bounce each pixel is the lobe's directional albedo at that view angle.
Scene ggx_plane_in_uniform_sky(float alpha, double theta_deg) {
  Scene s;
  Material m;
  m.diffuse = glm::vec3(0.0f);
  m.specular = glm::vec3(1.0f);
  m.roughness = alpha;
  s.materials.push_back(m);
  append_quad(s.triangles, glm::vec3(-100, -100, 0), glm::vec3(100, -100, 0), glm::vec3(100, 100, 0),
              glm::vec3(-100, 100, 0), 0);
  s.sky.enabled = true;
  s.sky.zenith = s.sky.horizon = s.sky.ground = glm::vec3(1.0f);
  const double t = theta_deg * M_PI / 180.0;
  s.camera.position = glm::vec3(float(4.0 * std::sin(t)), 0.0f, float(4.0 * std::cos(t)));
  s.camera.target = glm::vec3(0.0f);
  s.camera.vfov_deg = 0.5f;
  s.ipd_m = 0.0f;
  return s;
}

TEST(Ggx, WhiteFurnacePlaneRendersTheQuadratureAlbedo) {
  struct Case {
    float alpha;
    double theta_deg;
  };
  for (const Case c : {Case{0.2f, 0.0}, Case{0.5f, 60.0}, Case{1.0f, 0.0}, Case{1.0f, 75.0}}) {
    RenderFixture f(one_device(), ggx_plane_in_uniform_sky(c.alpha, c.theta_deg));
    PathTracer::Options opt;
    opt.spp = 64;
    opt.bounces = 1;
    auto eyes = f.render(8, 8, opt);
    const double expected = ggx::albedo(ggx::view(std::cos(c.theta_deg * M_PI / 180.0)), c.alpha);
    double m = 0.0, m2 = 0.0;
    for (const auto& eye : eyes)
      for (float v : eye.rgb) {
        m += v;
        m2 += double(v) * v;
      }
    const double n = 2.0 * eyes[0].rgb.size();
    m /= n;
    // Channels of a pixel are equal (grey), so only a third of the values are independent.
    const double se = std::sqrt(std::max(0.0, m2 / n - m * m) / (n / 3.0));
    std::printf("[ measure  ] alpha %.2f at %.0f degrees: rendered %.5f +- %.5f, quadrature %.5f\n", c.alpha,
                c.theta_deg, m, se, expected);
    EXPECT_NEAR(m, expected, 5.0 * se + 2e-3) << "alpha " << c.alpha << " at " << c.theta_deg << " degrees";
    EXPECT_EQ(f.tracer->nonfinite_paths(), 0u);
  }
}

// ---- estimators agree ----

// Mean squared difference of 4x4 block averages: averaging removes most of the noise, so a
// bias between estimators shows up against a small noise floor.
double block_mse(const ImageRGB& a, const ImageRGB& b) {
  double s = 0;
  int n = 0;
  for (int by = 0; by + 4 <= a.height; by += 4)
    for (int bx = 0; bx + 4 <= a.width; bx += 4)
      for (int c = 0; c < 3; ++c) {
        double ma = 0, mb = 0;
        for (int y = by; y < by + 4; ++y)
          for (int x = bx; x < bx + 4; ++x) {
            ma += a.rgb[(y * a.width + x) * 3 + c];
            mb += b.rgb[(y * b.width + x) * 3 + c];
          }
        s += (ma - mb) * (ma - mb) / 256.0;
        ++n;
      }
  return s / n;
}

TEST(PathTracer, NeeBsdfAndMisConvergeToTheSameCornellImage) {
  RenderFixture f(one_device(), make_builtin_scene("cornell"));
  PathTracer::Options opt;
  opt.spp = 128;
  opt.bounces = 4;
  std::map<LightSampling, std::array<ImageRGB, 2>> first, second;
  std::map<LightSampling, double> noise;
  for (auto mode : {LightSampling::Mis, LightSampling::Nee, LightSampling::Bsdf}) {
    opt.light_sampling = mode;
    opt.seed = 1;
    first[mode] = f.render(48, 36, opt);
    opt.seed = 2;
    second[mode] = f.render(48, 36, opt);
    // Two independent renders differ by twice the estimator's variance.
    noise[mode] = 0.5 * block_mse(first[mode][0], second[mode][0]);
  }
  EXPECT_LT(noise[LightSampling::Mis], noise[LightSampling::Bsdf]) << "MIS should beat BSDF sampling on a small light";
  for (auto [a, b] : {std::pair{LightSampling::Mis, LightSampling::Nee},
                      {LightSampling::Mis, LightSampling::Bsdf},
                      {LightSampling::Nee, LightSampling::Bsdf}}) {
    const double diff = block_mse(first[a][0], first[b][0]);
    // Unbiased estimators differ by their summed variance only; allow 2x for chance.
    EXPECT_LT(diff, 2.0 * (noise[a] + noise[b]) + 1e-6)
        << static_cast<int>(a) << " vs " << static_cast<int>(b) << ": noise " << noise[a] << ", " << noise[b];
  }
}

// ---- emitters: one-sided by default ----

// A white Lambertian floor (y = 0) under a square emitter of half-side `half` at height `h`
// (radiance `le`), seen at a grazing-free angle through a narrow field of view centred on the
// point right under the light (the view's footprint is small enough that the irradiance is
// constant over it to well under 0.1%). `facing_down` = the emitter's winding normal points at the floor.
Scene floor_under_square_light(float albedo, float le, float half, float h, bool facing_down) {
  Scene s;
  Material floor, light;
  floor.diffuse = glm::vec3(albedo);
  light.diffuse = glm::vec3(0.0f);
  light.emission = glm::vec3(le);
  s.materials = {floor, light};
  append_quad_facing(s.triangles, {-50, 0, -50}, {50, 0, -50}, {50, 0, 50}, {-50, 0, 50}, {0, 1, 0}, 0);
  append_quad_facing(s.triangles, {-half, h, -half}, {half, h, -half}, {half, h, half}, {-half, h, half},
                     {0, facing_down ? -1.0f : 1.0f, 0}, 1);
  // Looking down at 45 degrees past the light's edge, so the light never blocks the view.
  s.camera.position = {0.0f, 3.0f * h, 3.0f * h};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 1.0f;
  s.ipd_m = 0.0f;
  return s;
}

// Irradiance at a point under the centre of a parallel square of half-side `half` at height h
// and radiance le: four corner rectangles, each with the closed-form point-to-parallel-
// rectangle form factor F = 1/(2 pi) [A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + (A <-> B)], E = pi le F.
double irradiance_under_square(double le, double half, double h) {
  const double a = half / h, r = std::sqrt(1.0 + a * a);
  const double corner = (1.0 / (2.0 * M_PI)) * 2.0 * (a / r) * std::atan(a / r);
  return M_PI * le * 4.0 * corner;
}

TEST(PathTracer, SquareLightIrradianceMatchesClosedFormForEveryEstimator) {
  const float albedo = 0.5f, le = 4.0f, half = 0.5f, h = 1.0f;
  const double expected = albedo / M_PI * irradiance_under_square(le, half, h);
  RenderFixture f(one_device(), floor_under_square_light(albedo, le, half, h, true));
  for (LightSampling mode : {LightSampling::Mis, LightSampling::Nee, LightSampling::Bsdf}) {
    PathTracer::Options opt;
    opt.spp = mode == LightSampling::Bsdf ? 1024 : 256;
    opt.bounces = 1;  // the floor cannot see itself and the light reflects nothing: direct light is all
    opt.light_sampling = mode;
    auto eyes = f.render(8, 8, opt);
    std::printf("[ measure  ] light sampling %d: %.5f, closed form %.5f\n", static_cast<int>(mode), mean(eyes[0]),
                expected);
    EXPECT_NEAR(mean(eyes[0]), expected, 0.015 * expected) << "light sampling " << static_cast<int>(mode);
  }
}

TEST(PathTracer, OneSidedEmitterLightsOnlyItsFrontAndTwoSidedIsAnOptIn) {
  const float albedo = 0.5f, le = 4.0f, half = 0.5f, h = 1.0f;
  const double expected = albedo / M_PI * irradiance_under_square(le, half, h);
  for (LightSampling mode : {LightSampling::Mis, LightSampling::Nee, LightSampling::Bsdf}) {
    PathTracer::Options opt;
    opt.spp = 64;
    opt.bounces = 1;
    opt.light_sampling = mode;
    // Facing up, away from the floor: the floor gets nothing at all, by any estimator.
    Scene away = floor_under_square_light(albedo, le, half, h, false);
    RenderFixture f(one_device(), away);
    EXPECT_EQ(mean(f.render(8, 8, opt)[0]), 0.0) << "light sampling " << static_cast<int>(mode);
    // The same light marked two-sided lights the floor as the front face would.
    away.materials[1].two_sided = true;
    RenderFixture both(one_device(), away);
    opt.spp = mode == LightSampling::Bsdf ? 1024 : 256;
    EXPECT_NEAR(mean(both.render(8, 8, opt)[0]), expected, 0.015 * expected)
        << "two-sided, light sampling " << static_cast<int>(mode);
  }
  // Seen from behind, a one-sided emitter is black; from the front it shows its radiance.
  Scene s;
  Material light;
  light.diffuse = glm::vec3(0.0f);
  light.emission = glm::vec3(2.0f);
  s.materials = {light};
  append_quad_facing(s.triangles, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0, 0, 1}, 0);
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 10.0f;
  s.ipd_m = 0.0f;
  PathTracer::Options opt;
  opt.spp = 4;
  s.camera.position = {0.0f, 0.0f, 5.0f};
  RenderFixture front(one_device(), s);
  EXPECT_NEAR(mean(front.render(8, 8, opt)[0]), 2.0, 1e-5);
  s.camera.position = {0.0f, 0.0f, -5.0f};
  RenderFixture back(one_device(), s);
  EXPECT_EQ(mean(back.render(8, 8, opt)[0]), 0.0);
}

TEST(PathTracer, SymmetricSceneGivesMirrorImageEyes) {
  // A room symmetric about x = 0 with the camera on that plane: the left eye, mirrored
  // horizontally, sees what the right eye sees.
  Scene s;
  Material white, red, light;
  white.diffuse = glm::vec3(0.7f);
  red.diffuse = glm::vec3(0.7f, 0.2f, 0.2f);
  light.diffuse = glm::vec3(0.0f);
  light.emission = glm::vec3(8.0f);
  s.materials = {white, red, light};
  append_box(s.triangles, {-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}, 0);   // the room (seen from inside)
  append_box(s.triangles, {-0.9f, -1.0f, -0.2f}, {-0.5f, 0.0f, 0.2f}, 1);  // symmetric pair of red blocks
  append_box(s.triangles, {0.5f, -1.0f, -0.2f}, {0.9f, 0.0f, 0.2f}, 1);
  append_icosphere(s.triangles, {0.0f, -0.7f, 0.3f}, 0.3f, 2, 0);
  append_quad(s.triangles, {-0.3f, 0.99f, -0.3f}, {0.3f, 0.99f, -0.3f}, {0.3f, 0.99f, 0.3f}, {-0.3f, 0.99f, 0.3f}, 2);
  s.camera.position = {0.0f, 0.0f, -0.95f};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 70.0f;
  s.ipd_m = 0.3f;  // wide, so the eyes really differ
  RenderFixture f(one_device(), s);
  PathTracer::Options opt;
  opt.spp = 64;
  opt.bounces = 3;
  auto eyes = f.render(48, 36, opt);
  ImageRGB mirrored = eyes[0];
  for (int y = 0; y < mirrored.height; ++y)
    for (int x = 0; x < mirrored.width; ++x)
      for (int c = 0; c < 3; ++c)
        mirrored.rgb[(y * mirrored.width + x) * 3 + c] =
            eyes[0].rgb[(y * mirrored.width + (mirrored.width - 1 - x)) * 3 + c];
  opt.seed = 99;
  auto again = f.render(48, 36, opt);
  const double noise = 0.5 * block_mse(eyes[1], again[1]);
  const double unmirrored = block_mse(eyes[0], eyes[1]);
  const double diff = block_mse(mirrored, eyes[1]);
  EXPECT_LT(diff, 3.0 * noise + 1e-6) << "mirrored left vs right";
  EXPECT_GT(unmirrored, 5.0 * diff) << "the eyes should differ before mirroring (else the test says nothing)";
}

TEST(PathTracer, DeterministicAndDeviceCountInvariant) {
  Scene s = make_builtin_scene("cornell-glossy");
  PathTracer::Options opt;
  opt.spp = 2;
  std::array<ImageRGB, 2> reference;
  for (int n : {1, 2, 4}) {
    DeviceSet set = DeviceSet::create({n, DeviceMode::Auto, "", std::nullopt});
    RenderFixture f(set, s);
    auto eyes = f.render(40, 27, opt, 3);  // 27 rows: not divisible by 2 or 4
    if (n == 1) {
      reference = eyes;
      auto again = f.render(40, 27, opt, 3);
      for (int e = 0; e < 2; ++e)
        EXPECT_EQ(0, std::memcmp(again[e].rgb.data(), eyes[e].rgb.data(), eyes[e].rgb.size() * sizeof(float)))
            << "same seed, same device: not bit-identical";
      PathTracer::Options other = opt;
      other.seed = 5;
      auto different = f.render(40, 27, other, 3);
      EXPECT_NE(0, std::memcmp(different[0].rgb.data(), eyes[0].rgb.data(), eyes[0].rgb.size() * sizeof(float)))
          << "another seed should give another image";
      continue;
    }
    for (int e = 0; e < 2; ++e)
      EXPECT_EQ(0, std::memcmp(reference[e].rgb.data(), eyes[e].rgb.data(), eyes[e].rgb.size() * sizeof(float)))
          << n << " devices differ from 1 device, eye " << e;
  }
}

TEST(PathTracer, NonFiniteRadianceIsDroppedAndCounted) {
  // An emitter near the float limit: paths that see it through a bounce overflow to Inf.
  Scene s = closed_emissive_sphere(0.9f, 3.0e38f);
  RenderFixture f(one_device(), s);
  PathTracer::Options opt;
  opt.spp = 2;
  opt.bounces = 3;
  auto eyes = f.render(16, 12, opt);
  for (const auto& eye : eyes)
    for (float v : eye.rgb) ASSERT_TRUE(std::isfinite(v));
  EXPECT_GT(f.tracer->nonfinite_paths(), 0u);
}

// ---- the wavefront tracer against the megakernel, kernel by kernel ----

// A strip of rows traced by both tracers into full-frame buffers, and a list of scattered
// pixels (stage 5's hole list) by the wavefront tracer: the same pixels and albedos to the bit,
// and the same non-finite counts, also when a pixel's samples come in several launches
// (max_paths below spp paths per pixel: batches of 2, 2 and 1 samples, their sums carried over).
struct TracedBuffers {
  std::vector<cl_float4> radiance, albedo;
  cl_uint nonfinite = 0;
};

void expect_same_pixels(const TracedBuffers& a, const TracedBuffers& b, const std::vector<cl_uint>& pixels,
                        const std::string& what, bool same_count = true) {
  int differ = 0;
  for (cl_uint p : pixels) {
    differ += std::memcmp(&a.radiance[p], &b.radiance[p], sizeof(cl_float4)) != 0;
    differ += std::memcmp(&a.albedo[p], &b.albedo[p], sizeof(cl_float4)) != 0;
  }
  EXPECT_EQ(differ, 0) << what << ": of " << pixels.size() << " pixels";
  if (same_count) {
    EXPECT_EQ(a.nonfinite, b.nonfinite) << what;
  }
}

// Full-frame radiance and albedo buffers of `pixels` pixels filled with -1 (a pixel no launch
// wrote reads -1) and a zeroed non-finite counter: the targets of a launch whose pixels a test
// compares, and their contents once it has run.
struct TraceTargets {
  std::size_t pixels;
  cl::Buffer radiance, albedo, nonfinite;
  TraceTargets(DeviceSet& set, const cl::CommandQueue& queue, std::size_t n)
      : pixels(n),
        radiance(set.context(), CL_MEM_READ_WRITE, n * sizeof(cl_float4)),
        albedo(set.context(), CL_MEM_READ_WRITE, n * sizeof(cl_float4)),
        nonfinite(set.context(), CL_MEM_READ_WRITE, sizeof(cl_uint)) {
    queue.enqueueFillBuffer(radiance, cl_float{-1.0f}, 0, n * sizeof(cl_float4));
    queue.enqueueFillBuffer(albedo, cl_float{-1.0f}, 0, n * sizeof(cl_float4));
    queue.enqueueFillBuffer(nonfinite, cl_uint{0}, 0, sizeof(cl_uint));
  }
  PathTracer::Targets targets() const { return {radiance, albedo, nonfinite}; }
  TracedBuffers read(const cl::CommandQueue& queue) const {
    TracedBuffers out;
    out.radiance.resize(pixels);
    out.albedo.resize(pixels);
    queue.enqueueReadBuffer(radiance, CL_TRUE, 0, pixels * sizeof(cl_float4), out.radiance.data());
    queue.enqueueReadBuffer(albedo, CL_TRUE, 0, pixels * sizeof(cl_float4), out.albedo.data());
    queue.enqueueReadBuffer(nonfinite, CL_TRUE, 0, sizeof(cl_uint), &out.nonfinite);
    return out;
  }
};

// The scenes the tracers are compared on: glossy and diffuse surfaces, and paths that overflow to Inf.
std::vector<Scene> tracer_comparison_scenes() {
  return {make_builtin_scene("cornell-glossy"), closed_emissive_sphere(0.9f, 3.0e38f)};
}

TEST(WavefrontPathTracer, SamplesInBatchesGiveTheMegakernelsPixels) {
  for (Scene scene : tracer_comparison_scenes()) {
    RenderFixture f(one_device(), scene);
    DeviceSet& set = one_device();
    const cl::CommandQueue& queue = set.devices()[0].queue;
    const unsigned w = 24, h = 16, row0 = 4, rows = 9;
    PathTracer::Options opt;
    opt.spp = 5;
    opt.bounces = 4;
    const FrameParams fp = PathTracer::frame_params(scene, f.device_scene->light_count(), opt, 0, row0, rows, 3);
    const CameraParams cam = make_eye_camera(evaluate_camera(scene, 0.0f), Eye::Left, scene.ipd_units(), w, h);
    auto run = [&](const std::function<void(const PathTracer::Targets&)>& trace) {
      const TraceTargets t(set, queue, std::size_t{w} * h);
      trace(t.targets());
      return t.read(queue);
    };
    const TracedBuffers mega = run([&](const PathTracer::Targets& t) {
      PathTracer::launch(queue, set.program("pathtrace/path_trace.cl"), f.device_scene->on(0), t, fp, cam, w);
    });
    std::vector<cl_uint> strip;
    for (cl_uint p = row0 * w; p < (row0 + rows) * w; ++p) strip.push_back(p);
    const cl::Program& wavefront = set.program("pathtrace/wavefront.cl");
    for (std::size_t max_paths : {WavefrontPathTracer::kMaxPathsPerLaunch, std::size_t{2} * rows * w}) {
      WavefrontPathTracer::Scratch scratch;
      const TracedBuffers wave = run([&](const PathTracer::Targets& t) {
        WavefrontPathTracer::trace_rows(set.context(), queue, wavefront, f.device_scene->on(0), scratch, t, fp, cam, w,
                                        max_paths);
      });
      const std::string what = scene.name + ", rows, at most " + std::to_string(max_paths) + " paths a launch";
      expect_same_pixels(mega, wave, strip, what);
      // Nothing outside the strip was written.
      for (cl_uint p = 0; p < row0 * w; ++p) ASSERT_EQ(wave.radiance[p].s[0], -1.0f) << what << ", pixel " << p;
    }
    // A hole list: every third pixel of the strip, 1 to 5 paths a launch.
    std::vector<cl_uint> holes;
    for (std::size_t i = 0; i < strip.size(); i += 3) holes.push_back(strip[i]);
    const cl_uint count = static_cast<cl_uint>(holes.size());
    cl::Buffer hole_buf(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, holes.size() * sizeof(cl_uint),
                        holes.data());
    cl::Buffer count_buf(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof(cl_uint),
                         const_cast<cl_uint*>(&count));
    // The megakernel's own run over the list: the reference for the list's non-finite count.
    const FrameParams mega_fp = fp;
    TracedBuffers mega_holes;
    {
      cl::Kernel k(set.program("pathtrace/path_trace.cl"), "path_trace_list");
      mega_holes = run([&](const PathTracer::Targets& t) {
        k.setArg(0, t.radiance);
        k.setArg(1, t.albedo);
        k.setArg(2, t.nonfinite);
        k.setArg(3, hole_buf);
        k.setArg(4, count_buf);
        k.setArg(5, cl::Buffer());  // no centre hits: every sample traces its camera ray
        k.setArg(6, mega_fp);
        k.setArg(7, cam);
        f.device_scene->on(0).bind(k, 8);
        launch_1d(queue, k, holes.size());
      });
    }
    expect_same_pixels(mega, mega_holes, holes, scene.name + ": the megakernel's own list against its strip", false);
    for (std::size_t max_paths : {WavefrontPathTracer::kMaxPathsPerLaunch, holes.size() * 2, holes.size()}) {
      WavefrontPathTracer::Scratch scratch;
      const TracedBuffers wave = run([&](const PathTracer::Targets& t) {
        WavefrontPathTracer::trace_list(set.context(), queue, wavefront, f.device_scene->on(0), scratch, t, hole_buf,
                                        count_buf, strip.size(), fp, cam, nullptr, max_paths);
      });
      expect_same_pixels(mega_holes, wave, holes,
                         scene.name + ", hole list, at most " + std::to_string(max_paths) + " paths a launch");
    }
  }
}

// ---- one kernel for stages 2 and 5 on CPUs ----

// path_trace_pixels' gradient inputs (arguments first .. first + 3) where its mode is not the
// gradient one: null buffers and zero parameters.
void bind_no_gradient(cl::Kernel& k, cl_uint first) {
  for (cl_uint a = first; a < first + 3; ++a) k.setArg(a, cl::Buffer());
  k.setArg(first + 3, GradientParams{});
}

// CPUs launch path_trace_pixels for the left eye's strip, for the hole list, for the G-buffer
// pass and for the temporal gradients' shading, GPUs path_trace, path_trace_list, gbuffer and
// gradient_shade (one kernel compiles once on PoCL). Each way, explicitly on this device: the
// strip's pixels, albedos, non-finite count and G-buffer texels, the list's pixels with and
// without the G-buffer pass's hits, the G-buffer pass's texels and hits, and the gradients'
// strata and shades, the same to the bit.
TEST(PathTracer, OneKernelForStripHolesGBufferAndGradientsGivesTheOtherKernelsResults) {
  for (Scene scene : tracer_comparison_scenes()) {
    RenderFixture f(one_device(), scene);
    DeviceSet& set = one_device();
    const cl::CommandQueue& queue = set.devices()[0].queue;
    const cl::Program& program = set.program("pathtrace/path_trace.cl", f.device_scene->kernel_options());
    const unsigned w = 24, h = 16, row0 = 3, rows = 10;
    PathTracer::Options opt;
    opt.spp = 3;
    opt.bounces = 4;
    const FrameParams fp = PathTracer::frame_params(scene, f.device_scene->light_count(), opt, 0, row0, rows, 2);
    ASSERT_NE(fp.gbuffer_ray_samples, cl_uint{PX_GBUFFER_RAY_NONE});
    const CameraParams cam = make_eye_camera(evaluate_camera(scene, 0.0f), Eye::Right, scene.ipd_units(), w, h);
    const std::size_t n = std::size_t{w} * h;
    struct Out {
      TracedBuffers traced;
      std::vector<GBufferTexel> texels;
    };
    // Runs `bind` (which sets every argument from 3 on) for `items` work-items of `kernel`.
    auto run = [&](const char* kernel, std::size_t items,
                   const std::function<void(cl::Kernel&, const cl::Buffer&)>& bind) {
      const TraceTargets t(set, queue, n);
      cl::Buffer texels(set.context(), CL_MEM_READ_WRITE, n * sizeof(GBufferTexel));
      queue.enqueueFillBuffer(texels, cl_uchar{0xAB}, 0, n * sizeof(GBufferTexel));
      cl::Kernel k(program, kernel);
      k.setArg(0, t.radiance);
      k.setArg(1, t.albedo);
      k.setArg(2, t.nonfinite);
      bind(k, texels);
      launch_1d(queue, k, items);
      Out out;
      out.traced = t.read(queue);
      out.texels.resize(n);
      queue.enqueueReadBuffer(texels, CL_TRUE, 0, n * sizeof(GBufferTexel), out.texels.data());
      return out;
    };
    std::vector<cl_uint> all(n), strip;
    for (cl_uint p = 0; p < n; ++p) all[p] = p;
    for (cl_uint p = row0 * w; p < (row0 + rows) * w; ++p) strip.push_back(p);

    const Out two = run("path_trace", strip.size(), [&](cl::Kernel& k, const cl::Buffer& texels) {
      k.setArg(3, texels);
      k.setArg(4, fp);
      k.setArg(5, cam);
      f.device_scene->on(0).bind(k, 6);
    });
    const Out one = run("path_trace_pixels", strip.size(), [&](cl::Kernel& k, const cl::Buffer& texels) {
      k.setArg(3, texels);
      for (cl_uint a = 4; a < 8; ++a) k.setArg(a, cl::Buffer());  // holes, count, hits in, hits out
      k.setArg(8, cl_uint{PX_PIXELS_PATHS});
      bind_no_gradient(k, 9);
      k.setArg(13, fp);
      k.setArg(14, cam);
      f.device_scene->on(0).bind(k, 15);
    });
    // Every pixel: the strip's the same, the rest untouched by both.
    expect_same_pixels(two.traced, one.traced, all, scene.name + ": the strip");
    EXPECT_EQ(std::memcmp(two.texels.data(), one.texels.data(), n * sizeof(GBufferTexel)), 0)
        << scene.name << ": the strip's G-buffer texels";
    EXPECT_NE(std::memcmp(&one.texels[strip[0]], &one.texels[0], sizeof(GBufferTexel)), 0)
        << scene.name << ": the strip wrote its G-buffer texels";
    for (cl_uint p = 0; p < row0 * w; ++p) ASSERT_EQ(one.traced.radiance[p].s[0], -1.0f) << "pixel " << p;

    // The G-buffer pass's hits for the list's first samples.
    cl::Buffer hits(set.context(), CL_MEM_READ_WRITE, n * sizeof(Hit));
    cl::Buffer texels(set.context(), CL_MEM_READ_WRITE, n * sizeof(GBufferTexel));
    queue.enqueueFillBuffer(hits, cl_uchar{0xAB}, 0, n * sizeof(Hit));
    queue.enqueueFillBuffer(texels, cl_uchar{0xAB}, 0, n * sizeof(GBufferTexel));
    {
      cl::Kernel g(set.program("pipeline/gbuffer.cl", f.device_scene->kernel_options()), "gbuffer");
      g.setArg(0, texels);
      g.setArg(1, hits);
      g.setArg(2, cl_uint{row0});
      g.setArg(3, cl_uint{rows});
      g.setArg(4, cam);
      f.device_scene->on(0).bind(g, 5);
      launch_1d(queue, g, strip.size());
    }
    std::vector<cl_uint> holes;
    for (std::size_t i = 0; i < strip.size(); i += 3) holes.push_back(strip[strip.size() - 1 - i]);
    const cl_uint count = static_cast<cl_uint>(holes.size());
    cl::Buffer hole_buf(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, holes.size() * sizeof(cl_uint),
                        holes.data());
    cl::Buffer count_buf(set.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof(cl_uint),
                         const_cast<cl_uint*>(&count));
    const cl::Buffer* no_hits = nullptr;
    for (const cl::Buffer* first_hits : {no_hits, static_cast<const cl::Buffer*>(&hits)}) {
      const std::string what = scene.name + (first_hits ? ": the list from the G-buffer's hits" : ": the list");
      // The list's arguments, from `first` on: the two kernels take the same ones (path_trace_pixels
      // after its G-buffer target, null here).
      const auto bind_list = [&](cl::Kernel& k, cl_uint first) {
        k.setArg(first, hole_buf);
        k.setArg(first + 1, count_buf);
        set_optional_buffer(k, first + 2, first_hits);
        k.setArg(first + 3, fp);
        k.setArg(first + 4, cam);
        f.device_scene->on(0).bind(k, first + 5);
      };
      const Out two_list =
          run("path_trace_list", strip.size(), [&](cl::Kernel& k, const cl::Buffer&) { bind_list(k, 3); });
      const Out one_list = run("path_trace_pixels", strip.size(), [&](cl::Kernel& k, const cl::Buffer&) {
        k.setArg(3, cl::Buffer());
        k.setArg(4, hole_buf);
        k.setArg(5, count_buf);
        set_optional_buffer(k, 6, first_hits);
        k.setArg(7, cl::Buffer());  // no hits written
        k.setArg(8, cl_uint{PX_PIXELS_PATHS});
        bind_no_gradient(k, 9);
        k.setArg(13, fp);
        k.setArg(14, cam);
        f.device_scene->on(0).bind(k, 15);
      });
      expect_same_pixels(two_list.traced, one_list.traced, all, what);
      int listed = 0;
      for (cl_uint p : holes) listed += one_list.traced.radiance[p].s[0] != -1.0f;
      EXPECT_EQ(listed, static_cast<int>(holes.size())) << what << ": every listed pixel written";
      // Only the listed pixels: the one before each listed pixel is not listed (every third).
      EXPECT_EQ(one_list.traced.radiance[holes[0] - 1].s[0], -1.0f) << what;
    }
    // The G-buffer pass in path_trace_pixels (PathTracer::launch_gbuffer, CPUs): gbuffer's texels
    // and hits to the bit, on the strip's rows and nowhere else.
    if (!set.devices()[0].is_gpu()) {
      cl::Buffer pass_hits(set.context(), CL_MEM_READ_WRITE, n * sizeof(Hit));
      cl::Buffer pass_texels(set.context(), CL_MEM_READ_WRITE, n * sizeof(GBufferTexel));
      queue.enqueueFillBuffer(pass_hits, cl_uchar{0xAB}, 0, n * sizeof(Hit));
      queue.enqueueFillBuffer(pass_texels, cl_uchar{0xAB}, 0, n * sizeof(GBufferTexel));
      PathTracer::launch_gbuffer(queue, program, f.device_scene->on(0), pass_texels, &pass_hits,
                                 PathTracer::gbuffer_params(1, row0, rows, 2), cam, w);
      std::vector<Hit> want_hits(n), got_hits(n);
      std::vector<GBufferTexel> want_texels(n), got_texels(n);
      queue.enqueueReadBuffer(hits, CL_TRUE, 0, n * sizeof(Hit), want_hits.data());
      queue.enqueueReadBuffer(pass_hits, CL_TRUE, 0, n * sizeof(Hit), got_hits.data());
      queue.enqueueReadBuffer(texels, CL_TRUE, 0, n * sizeof(GBufferTexel), want_texels.data());
      queue.enqueueReadBuffer(pass_texels, CL_TRUE, 0, n * sizeof(GBufferTexel), got_texels.data());
      EXPECT_EQ(std::memcmp(want_hits.data(), got_hits.data(), n * sizeof(Hit)), 0)
          << scene.name << ": the G-buffer pass's hits";
      EXPECT_EQ(std::memcmp(want_texels.data(), got_texels.data(), n * sizeof(GBufferTexel)), 0)
          << scene.name << ": the G-buffer pass's texels";
      int hit_texels = 0;
      for (cl_uint p : strip) hit_texels += got_hits[p].prim != PX_NO_HIT;
      EXPECT_GT(hit_texels, static_cast<int>(strip.size()) / 2) << scene.name << ": the pass hit something";
      EXPECT_THROW(PathTracer::launch_gbuffer(queue, program, f.device_scene->on(0), pass_texels, nullptr, fp, cam, w),
                   std::logic_error)
          << "the path's own params (3 spp) are not the G-buffer pass's";

      // The temporal gradients' shading in path_trace_pixels (PathTracer::launch_gradient, CPUs):
      // gradient_shade's strata and shades to the bit, over two frames, so that the second compares
      // its shades with the first's (the history), with the same non-finite count.
      const cl_uint sw = (w + PX_GRADIENT_STRATUM - 1) / PX_GRADIENT_STRATUM;
      const cl_uint sh = (h + PX_GRADIENT_STRATUM - 1) / PX_GRADIENT_STRATUM;
      const cl_uint s_lo = (row0 + PX_GRADIENT_STRATUM - 1) / PX_GRADIENT_STRATUM;
      const cl_uint s_hi = (row0 + rows) / PX_GRADIENT_STRATUM;
      ASSERT_GT(s_hi, s_lo + 1);
      struct GradientRun {
        std::vector<cl_float4> raw, ref[2];
        cl_uint nonfinite = 0;
      };
      const auto gradients = [&](bool in_path_tracer) {
        const cl_float4 zero{{0, 0, 0, 0}};
        cl::Buffer raw(set.context(), CL_MEM_READ_WRITE, std::size_t{sw} * sh * sizeof(cl_float4));
        cl::Buffer ref[2] = {cl::Buffer(set.context(), CL_MEM_READ_WRITE, n * sizeof(cl_float4)),
                             cl::Buffer(set.context(), CL_MEM_READ_WRITE, n * sizeof(cl_float4))};
        cl::Buffer nonfinite(set.context(), CL_MEM_READ_WRITE, sizeof(cl_uint));
        queue.enqueueFillBuffer(raw, zero, 0, std::size_t{sw} * sh * sizeof(cl_float4));
        for (const cl::Buffer& b : ref) queue.enqueueFillBuffer(b, zero, 0, n * sizeof(cl_float4));
        queue.enqueueFillBuffer(nonfinite, cl_uint{0}, 0, sizeof(cl_uint));
        FrameParams shade_fp = fp;
        shade_fp.max_bounces = std::min<cl_uint>(fp.max_bounces, PX_GRADIENT_MAX_BOUNCES);
        for (cl_uint frame = 4; frame < 6; ++frame) {
          GradientParams gp{};
          gp.width = w;
          gp.height = h;
          gp.strata_w = sw;
          gp.strata_h = sh;
          gp.s_row0 = gp.s_lo = s_lo;
          gp.s_rows = s_hi - s_lo;
          gp.s_hi = s_hi;
          gp.lo_row = row0;
          gp.hi_row = row0 + rows;
          gp.frame = frame;
          gp.eye = 1;
          gp.seed = fp.seed;
          gp.have_history = frame > 4 ? 1u : 0u;
          const cl::Buffer& now = ref[frame % 2];
          const cl::Buffer& before = ref[1 - frame % 2];
          // Last frame's G-buffer is this frame's: nothing moved.
          if (in_path_tracer) {
            const PathTracer::GradientInputs in{raw, now, before, texels, texels, nonfinite, nullptr, gp};
            PathTracer::launch_gradient(queue, program, f.device_scene->on(0), in, shade_fp, cam);
          } else {
            cl::Kernel k(program, "gradient_shade");
            cl_uint a = 0;
            for (const cl::Buffer* b :
                 std::initializer_list<const cl::Buffer*>{&raw, &now, &before, &texels, &texels, &nonfinite})
              k.setArg(a++, *b);
            k.setArg(a++, cl::Buffer());  // no motion
            k.setArg(a++, shade_fp);
            k.setArg(a++, cam);
            k.setArg(a++, gp);
            f.device_scene->on(0).bind(k, a);
            launch_1d(queue, k, std::size_t{gp.s_rows} * sw);
          }
        }
        GradientRun out;
        out.raw.resize(std::size_t{sw} * sh);
        queue.enqueueReadBuffer(raw, CL_TRUE, 0, out.raw.size() * sizeof(cl_float4), out.raw.data());
        for (int k = 0; k < 2; ++k) {
          out.ref[k].resize(n);
          queue.enqueueReadBuffer(ref[k], CL_TRUE, 0, n * sizeof(cl_float4), out.ref[k].data());
        }
        queue.enqueueReadBuffer(nonfinite, CL_TRUE, 0, sizeof(cl_uint), &out.nonfinite);
        return out;
      };
      const GradientRun want = gradients(false), got = gradients(true);
      EXPECT_EQ(std::memcmp(want.raw.data(), got.raw.data(), want.raw.size() * sizeof(cl_float4)), 0)
          << scene.name << ": the strata's gradients";
      for (int k = 0; k < 2; ++k)
        EXPECT_EQ(std::memcmp(want.ref[k].data(), got.ref[k].data(), n * sizeof(cl_float4)), 0)
            << scene.name << ": the shades of frame " << 4 + k;
      EXPECT_EQ(want.nonfinite, got.nonfinite) << scene.name << ": non-finite shades";
      // Not vacuous: strata with a gradient (a valid shade now and last frame), or shades dropped as
      // non-finite (the overflowing scene).
      int with_gradient = 0;
      for (const cl_float4& r : got.raw) with_gradient += r.s[1] > 0.0f;
      EXPECT_TRUE(with_gradient > 0 || got.nonfinite > 0) << scene.name << ": no stratum was shaded";
    }
    // The pipeline's launches (PathTracer::launch / launch_list) pick the kernel by device type
    // and give the same pixels either way.
    const TraceTargets staged(set, queue, n);
    const PathTracer::Targets with_texels{staged.radiance, staged.albedo, staged.nonfinite, &texels};
    PathTracer::launch(queue, program, f.device_scene->on(0), with_texels, fp, cam, w);
    expect_same_pixels(two.traced, staged.read(queue), all, scene.name + ": PathTracer::launch");
  }
}

// ---- glass: a smooth dielectric ----

// Unpolarised Fresnel reflectance in Fresnel's own angle form (Born & Wolf, sec. 1.5):
// rs = -sin(ti - tt) / sin(ti + tt), rp = tan(ti - tt) / tan(ti + tt), with Snell's law for tt.
// A second formulation, in double, against which the kernel's cosine form is checked.
double fresnel_angle_form(double theta_i, double n_near, double n_far) {
  const double sin_t = n_near / n_far * std::sin(theta_i);
  if (sin_t >= 1.0) return 1.0;
  const double tt = std::asin(sin_t);
  if (theta_i == 0.0) return std::pow((n_far - n_near) / (n_far + n_near), 2.0);
  const double rs = -std::sin(theta_i - tt) / std::sin(theta_i + tt);
  const double rp = std::tan(theta_i - tt) / std::tan(theta_i + tt);
  return 0.5 * (rs * rs + rp * rp);
}

BsdfCase glass_case(float ior, bool outside, double theta_i, glm::vec3 transmission = glm::vec3(1.0f)) {
  BsdfCase c{transmission, glm::vec3(0.0f), 0.0f, false,
             glm::vec3(float(std::sin(theta_i)), 0.0f, float(std::cos(theta_i)))};
  c.ior = ior;
  c.outside = outside;
  return c;
}

struct GlassSplit {
  double reflected = 0.0;  // fraction of samples reflected
  std::size_t count = 0;
};

// Samples the dielectric and checks every sample's geometry and weight on the way: a
// reflection is the mirror direction with weight 1 (white reflection tint), a refraction obeys
// Snell's law and carries the filter times (eta_near / eta_far)^2.
GlassSplit sample_glass(const BsdfCase& c, std::uint32_t n) {
  const double n_near = c.outside ? 1.0 : c.ior, n_far = c.outside ? c.ior : 1.0;
  const glm::dvec3 wo = glm::normalize(glm::dvec3(c.wo));
  const double sin_i = std::sqrt(std::max(0.0, 1.0 - wo.z * wo.z));
  const double sin_t = n_near / n_far * sin_i;
  auto smp = probe_samples(c, n);
  GlassSplit split;
  split.count = n;
  int bad = 0;
  for (std::size_t i = 0; i < n && bad < 5; ++i) {
    const auto& s = smp.sample[i];
    const auto& w = smp.sample2[i];
    if (s.s[3] != -1.0f) {
      ADD_FAILURE() << "glass sample " << i << " is not a valid delta sample";
      ++bad;
      continue;
    }
    const glm::dvec3 wi(s.s[0], s.s[1], s.s[2]);
    if (wi.z > 0.0) {
      split.reflected += 1.0;
      const bool ok = glm::length(wi - glm::dvec3(-wo.x, -wo.y, wo.z)) < 1e-5 && std::abs(w.s[0] - 1.0f) < 1e-6f &&
                      std::abs(w.s[1] - 1.0f) < 1e-6f;
      if (!ok) {
        ADD_FAILURE() << "reflection " << i << ": wi (" << wi.x << ", " << wi.y << ", " << wi.z << ") weight "
                      << w.s[0];
        ++bad;
      }
    } else {
      // Snell: the refracted ray continues sideways (-x) with sin(theta_t) = n_near / n_far sin(theta_i).
      const double expect_weight = c.diffuse.x * (n_near * n_near) / (n_far * n_far);
      const bool ok = std::abs(wi.x + sin_t) < 1e-5 && std::abs(wi.y) < 1e-5 &&
                      std::abs(wi.z + std::sqrt(std::max(0.0, 1.0 - sin_t * sin_t))) < 1e-5 &&
                      std::abs(w.s[0] - expect_weight) < 1e-5 * expect_weight;
      if (!ok) {
        ADD_FAILURE() << "refraction " << i << ": wi (" << wi.x << ", " << wi.y << ", " << wi.z << "), expected sin_t "
                      << sin_t << "; weight " << w.s[0] << " expected " << expect_weight;
        ++bad;
      }
    }
  }
  split.reflected /= n;
  return split;
}

// Binomial noise bound on a sampled fraction: five standard deviations, and never below what a
// handful of samples could move it.
double fraction_tolerance(double p, std::size_t n) {
  return 5.0 * std::sqrt(std::max(p * (1.0 - p), 1e-4) / double(n)) + 2.0 / double(n);
}

TEST(Glass, FresnelAtNormalIncidenceIsTheSquaredIndexRatio) {
  const std::uint32_t n = 1u << 18;
  for (float ior : {1.33f, 1.5f, 2.4f})
    for (bool outside : {true, false}) {
      const double f0 = std::pow((ior - 1.0) / (ior + 1.0), 2.0);  // ((n - 1) / (n + 1))^2
      const GlassSplit split = sample_glass(glass_case(ior, outside, 0.0), n);
      EXPECT_NEAR(split.reflected, f0, fraction_tolerance(f0, n))
          << "ior " << ior << (outside ? " from outside" : " from inside");
    }
}

TEST(Glass, FresnelAtObliqueIncidenceMatchesTheAngleForm) {
  const std::uint32_t n = 1u << 17;
  const double deg = M_PI / 180.0;
  struct Case {
    double theta;
    bool outside;
  };
  // From inside, the critical angle of 1.5 is 41.81 degrees: 40 degrees is just below it.
  for (const Case c : {Case{30 * deg, true}, Case{60 * deg, true}, Case{80 * deg, true}, Case{20 * deg, false},
                       Case{35 * deg, false}, Case{40 * deg, false}}) {
    const double expected = c.outside ? fresnel_angle_form(c.theta, 1.0, 1.5) : fresnel_angle_form(c.theta, 1.5, 1.0);
    const GlassSplit split = sample_glass(glass_case(1.5f, c.outside, c.theta, glm::vec3(0.8f)), n);
    EXPECT_NEAR(split.reflected, expected, fraction_tolerance(expected, n))
        << "theta " << c.theta / deg << (c.outside ? " from outside" : " from inside");
    EXPECT_LT(split.reflected, 1.0) << "below the critical angle some light must refract";
  }
}

TEST(Glass, TotalInternalReflectionBeyondTheCriticalAngle) {
  // From inside glass of index 1.5, beyond asin(1 / 1.5) = 41.81 degrees, everything reflects
  // (sample_glass checks each one is the mirror direction with weight 1).
  const double deg = M_PI / 180.0;
  for (double theta : {42.5 * deg, 60.0 * deg, 85.0 * deg}) {
    const GlassSplit split = sample_glass(glass_case(1.5f, false, theta), 1u << 14);
    EXPECT_EQ(split.reflected, 1.0) << "theta " << theta / deg;
  }
  // The same angles from outside refract most of the light: the side matters.
  const GlassSplit outside = sample_glass(glass_case(1.5f, true, 60.0 * deg), 1u << 14);
  EXPECT_LT(outside.reflected, 0.2);
}

TEST(Glass, FurnaceSphereInUniformSkyStaysUniform) {
  // A clear dielectric sphere in a uniform environment of radiance 1, nothing else: every path
  // leaves to the environment with throughput 1 (reflection and refraction are chosen with
  // their Fresnel probabilities, and the 1 / eta^2 on entering cancels the eta^2 on leaving),
  // so the image is the environment, sphere or not.
  Material glass;
  glass.dielectric = true;
  glass.ior = 1.5f;
  glass.diffuse = glm::vec3(0.0f);  // unused by a dielectric: a bug reading it shows as dark
  RenderFixture f(one_device(), sphere_in_uniform_sky(glass, 4));
  PathTracer::Options opt;
  opt.spp = 32;
  opt.bounces = 32;
  opt.rr_start_bounce = 32;  // no roulette: every path is exactly 1
  auto eyes = f.render(40, 30, opt);
  for (const auto& eye : eyes) {
    EXPECT_NEAR(mean(eye), 1.0, 0.01);
    EXPECT_LT(rmse_to(eye, 1.0), 0.05);
    std::size_t off = 0;
    for (float v : eye.rgb) off += std::abs(v - 1.0f) > 0.1f;
    EXPECT_LE(off, eye.rgb.size() / 200) << "channels more than 10% off the environment";
  }
  EXPECT_EQ(f.tracer->nonfinite_paths(), 0u);
}

// ---- normal maps ----

// A white-ish Lambertian plane z = 0 lit by a sun of angular radius r from elevation
// 90 - alpha degrees (towards +x); nothing else. Its radiance is exactly
//   (a / pi) R pi sin^2(r) cos(angle between the shading normal and the sun)
// (the cosine integrated over the sun's cone: its sideways parts cancel by symmetry).
Scene sunlit_plane(const float* normal_texel) {
  Scene s;
  Material m;
  m.diffuse = glm::vec3(0.5f);
  if (normal_texel) {
    Texture t;
    t.width = t.height = 1;
    t.rgba.assign(normal_texel, normal_texel + 4);
    s.textures.push_back(t);
    m.normal_texture = 0;
  }
  s.materials.push_back(m);
  // u grows along +x, v along +y: the tangent frame is (x, y, z).
  append_quad(s.triangles, glm::vec3(-10, -10, 0), glm::vec3(10, -10, 0), glm::vec3(10, 10, 0), glm::vec3(-10, 10, 0),
              0);
  s.sun.enabled = true;
  const double alpha = 40.0 * M_PI / 180.0;
  s.sun.direction = glm::vec3(float(std::sin(alpha)), 0.0f, float(std::cos(alpha)));
  s.sun.angular_radius_deg = 5.0f;
  s.sun.radiance = glm::vec3(250.0f);
  s.camera.position = glm::vec3(0.0f, 0.0f, 4.0f);
  s.camera.target = glm::vec3(0.0f);
  s.camera.vfov_deg = 40.0f;
  return s;
}

double sunlit_plane_radiance(double normal_tilt_towards_sun) {
  const double alpha = 40.0 * M_PI / 180.0, r = 5.0 * M_PI / 180.0;
  return 0.5 * 250.0 * std::pow(std::sin(r), 2.0) * std::cos(alpha - normal_tilt_towards_sun);
}

TEST(NormalMap, FlatMapChangesNothingAndTiltedMapFollowsTheCosine) {
  PathTracer::Options opt;
  opt.spp = 8;
  opt.bounces = 2;
  RenderFixture plain(one_device(), sunlit_plane(nullptr));
  const auto reference = plain.render(32, 24, opt);
  EXPECT_NEAR(mean(reference[0]), sunlit_plane_radiance(0.0), 0.01 * sunlit_plane_radiance(0.0));

  // (0.5, 0.5, 1) encodes the unperturbed normal: the same image, pixel for pixel.
  const float flat[4] = {0.5f, 0.5f, 1.0f, 1.0f};
  RenderFixture flat_map(one_device(), sunlit_plane(flat));
  const auto same = flat_map.render(32, 24, opt);
  for (int e = 0; e < 2; ++e)
    for (std::size_t i = 0; i < same[e].rgb.size(); ++i)
      ASSERT_NEAR(same[e].rgb[i], reference[e].rgb[i], 1e-4f * (1.0f + reference[e].rgb[i]))
          << "eye " << e << " value " << i;

  // A constant normal tilted by 20 degrees towards the sun (+x, the map's +u), then away.
  const double tilt = 20.0 * M_PI / 180.0;
  for (double sign : {1.0, -1.0}) {
    const float texel[4] = {float(0.5 + 0.5 * sign * std::sin(tilt)), 0.5f, float(0.5 + 0.5 * std::cos(tilt)), 1.0f};
    RenderFixture tilted(one_device(), sunlit_plane(texel));
    const auto eyes = tilted.render(32, 24, opt);
    const double expected = sunlit_plane_radiance(sign * tilt);
    for (const auto& eye : eyes) EXPECT_NEAR(mean(eye), expected, 0.01 * expected) << "tilt sign " << sign;
  }
}

}  // namespace
}  // namespace px

// SVGF (stages 6-7): the a-trous kernel against a straightforward host implementation, the
// filter's behaviour on synthetic inputs with known answers (constant, edges, convergence,
// disocclusion), and the distributed properties (halo = bit-identical for any device count;
// independent seams differ only near seams; bilateral seams soften the seam within their band;
// denoising brings Cornell closer to an independent reference).
#include "app/scene_setup.h"
#include "cl/launch.h"
#include "denoise/svgf_constants.h"
#include "pipeline/stages/svgf_denoiser.h"
#include "image/image_metrics.h"
#include "pipeline/stereo_pipeline.h"
#include "render/reference_render.h"
#include "render/stereo_camera.h"
#include "scene/primitives.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>

namespace px {
namespace {

DeviceSet& one_device() {
  static DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  return set;
}

template <typename T>
cl::Buffer upload(const std::vector<T>& v) {
  return cl::Buffer(one_device().context(), CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, v.size() * sizeof(T),
                    const_cast<T*>(v.data()));
}

template <typename T>
std::vector<T> download(const cl::Buffer& b, std::size_t n) {
  std::vector<T> v(n);
  one_device().devices()[0].queue.enqueueReadBuffer(b, CL_TRUE, 0, n * sizeof(T), v.data());
  return v;
}

float lum(const cl_float4& c) { return 0.2126f * c.s[0] + 0.7152f * c.s[1] + 0.0722f * c.s[2]; }

// ---- a-trous against the host ----

// The a-trous kernels: svgf_atrous (a pixel per work-item), svgf_atrous8 (eight pixels per
// work-item in float8, what CPU devices run; param 8) and svgf_atrous_tiled (8x8-pixel tiles
// whose taps come from local memory, what GPUs run at steps 1-4; param 64). 43 columns: the last
// group of eight (and tile) is partial, and at steps 2 and 4 taps leave the image on both sides
// of whole groups; the strip's 20 rows end in a partial row of tiles.
class AtrousKernel : public ::testing::TestWithParam<unsigned> {};

TEST_P(AtrousKernel, MatchesHostImplementation) {
  const unsigned lanes = GetParam() == 8 ? 8 : 1;
  const bool tiled = GetParam() == 64;
  const unsigned w = 43, h = 30;
  const std::size_t n = w * h;
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<cl_float4> illum(n), moments(n);
  std::vector<GBufferTexel> g(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
    illum[i] = {{u(rng), u(rng), u(rng), 0.05f * u(rng)}};
    // A few unfiltered pixels, every other one a silhouette pixel that borrows a neighbour's
    // geometry (PX_SVGF_BORROWED).
    // History lengths 1 .. 6 frames: tap pairs from their own weights to the lesser one.
    moments[i] = {
        {0, 0, static_cast<float>(1 + i % 6), (i % 17 == 0) ? ((i / 17) % 2 ? PX_SVGF_BORROWED : 0.0f) : 1.0f}};
    GBufferTexel t{};
    glm::vec3 nn = glm::normalize(glm::vec3(0.3f * std::sin(0.2f * x), 0.2f * std::cos(0.3f * y), 1.0f));
    if (x > 25) nn = glm::normalize(glm::vec3(1.0f, 0.0f, 0.3f));  // a crease
    // Scattered pixels whose normal no neighbour shares (like foliage cards): isolated.
    if ((x * 7 + y * 3) % 23 == 0) nn = glm::normalize(glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, 1.0f));
    t.normal[0] = nn.x;
    t.normal[1] = nn.y;
    t.normal[2] = nn.z;
    t.depth = 2.0f + 0.01f * x + (y > 20 ? 1.0f : 0.0f);  // a depth step
    t.material_class = moments[i].s[3] == 1.0f ? PX_CLASS_DIFFUSE : PX_CLASS_MISS;
    g[i] = t;
  }
  int isolated = 0;   // pixels that took the loose normal weights (the fallback must be exercised)
  int borrowing = 0;  // silhouette pixels filtered with a neighbour's geometry
  // The usual integer normal exponent (squarings) and a fractional one (the pow path).
  for (float sigma_n : {128.0f, 2.5f}) {
    SCOPED_TRACE("sigma_n " + std::to_string(sigma_n));
    SvgfParams p{};
    p.sigma_l = 4.0f;
    p.sigma_z = 1.0f;
    p.sigma_n = sigma_n;
    p.width = w;
    p.height = h;
    p.row0 = 3;
    p.rows = 20;  // a strip in the middle
    p.lo_row = 0;
    p.hi_row = 26;  // readable rows: reads beyond must be skipped
    for (unsigned step : {1u, 2u, 4u}) {
      p.step = step;
      auto bi = upload(illum), bg = upload(g), bm = upload(moments);
      // A sentinel outside the strip: the pass writes its rows and no other.
      auto out = upload(std::vector<cl_float4>(n, cl_float4{{-7.0f, -7.0f, -7.0f, -7.0f}}));
      // The guide texels of every row, then the a-trous step reading them.
      cl::Buffer guide(one_device().context(), CL_MEM_READ_WRITE, n * sizeof(cl_float4));
      SvgfParams all = p;
      all.row0 = 0;
      all.rows = h;
      all.lo_row = 0;
      all.hi_row = h;
      cl::Kernel kg(one_device().program("denoise/svgf_temporal.cl"), "svgf_guide");
      kg.setArg(0, guide);
      kg.setArg(1, bg);
      kg.setArg(2, all);
      launch_1d(one_device().devices()[0].queue, kg, all.rows * w);
      // The luminance guide of every readable row (svgf_luma), checked against a host version.
      cl::Buffer luma(one_device().context(), CL_MEM_READ_WRITE, n * sizeof(cl_float2));
      SvgfParams readable_rows = p;
      readable_rows.row0 = p.lo_row;
      readable_rows.rows = p.hi_row - p.lo_row;
      cl::Kernel kl(one_device().program("denoise/svgf_atrous.cl"), "svgf_luma");
      kl.setArg(0, luma);
      kl.setArg(1, bi);
      kl.setArg(2, guide);
      kl.setArg(3, readable_rows);
      launch_1d(one_device().devices()[0].queue, kl, readable_rows.rows * w);
      const std::vector<cl_float2> got_luma = download<cl_float2>(luma, n);
      cl::Kernel k(one_device().program("denoise/svgf_atrous.cl"), tiled        ? "svgf_atrous_tiled"
                                                                   : lanes == 8 ? "svgf_atrous8"
                                                                                : "svgf_atrous");
      k.setArg(0, out);
      k.setArg(1, bi);
      k.setArg(2, guide);
      k.setArg(3, bm);
      k.setArg(4, luma);
      k.setArg(5, p);
      launch_1d(one_device().devices()[0].queue, k,
                tiled ? ((w + PX_ATROUS_TILE - 1) / PX_ATROUS_TILE) * ((p.rows + PX_ATROUS_TILE - 1) / PX_ATROUS_TILE) *
                            PX_LOCAL_SIZE
                      : p.rows * ((w + lanes - 1) / lanes));
      auto got = download<cl_float4>(out, n);
      for (std::size_t i = 0; i < n; ++i) {
        if (i / w >= p.row0 && i / w < p.row0 + p.rows) continue;
        ASSERT_EQ(got[i].s[0], -7.0f) << "pixel " << i << " outside the strip";
      }
      // Host version of the same filter, written from the SVGF paper's formulas.
      auto readable = [&](int y) {
        return y >= static_cast<int>(p.lo_row) && y < static_cast<int>(p.hi_row) && y < static_cast<int>(h) && y >= 0;
      };
      auto at = [&](int x, int y) { return static_cast<std::size_t>(y) * w + x; };
      auto filtered = [&](std::size_t j) { return moments[j].s[3] == 1.0f; };
      // The lender of a borrowing pixel: its filtered 8-neighbour of least depth in readable
      // rows, the first in scan order on ties.
      auto lender = [&](int x, int y) {
        long best = -1;
        float best_depth = std::numeric_limits<float>::infinity();
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int tx = x + dx, ty = y + dy;
            if ((dx == 0 && dy == 0) || !readable(ty) || tx < 0 || tx >= static_cast<int>(w)) continue;
            if (filtered(at(tx, ty)) && g[at(tx, ty)].depth < best_depth) {
              best = static_cast<long>(at(tx, ty));
              best_depth = g[at(tx, ty)].depth;
            }
          }
        return best;
      };
      // What an a-trous tap's luminance test compares, per pixel: the luminance of a filtered
      // pixel averaged over its 3x3 neighbours on the same surface (filtered, normal cosine >= 0.9,
      // depth within 10%) with the weights (1/2 centre, 1/4 beside) per axis, any other pixel's
      // own; and the variance averaged with the same weights over the filtered neighbours.
      std::vector<double> luma_host(n, 0.0), var_host(n, 0.0);
      for (int y = static_cast<int>(p.lo_row); y < static_cast<int>(p.hi_row); ++y)
        for (int x = 0; x < static_cast<int>(w); ++x) {
          const std::size_t i = at(x, y);
          const glm::dvec3 n0(g[i].normal[0], g[i].normal[1], g[i].normal[2]);
          double sum = 0, wsum = 0, var = 0, vw = 0;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int tx = x + dx, ty = y + dy;
              if (!readable(ty) || tx < 0 || tx >= static_cast<int>(w) || !filtered(at(tx, ty))) continue;
              const std::size_t j = at(tx, ty);
              const double kk = (dx == 0 ? 0.5 : 0.25) * (dy == 0 ? 0.5 : 0.25);
              var += kk * illum[j].s[3];
              vw += kk;
              const glm::dvec3 n1(g[j].normal[0], g[j].normal[1], g[j].normal[2]);
              if (glm::dot(n0, n1) < 0.9 || std::abs(g[j].depth - g[i].depth) > 0.1 * g[i].depth) continue;
              sum += kk * lum(illum[j]);
              wsum += kk;
            }
          luma_host[i] = filtered(i) ? sum / wsum : lum(illum[i]);
          var_host[i] = vw > 0 ? var / vw : illum[i].s[3];
          ASSERT_NEAR(got_luma[i].s[0], luma_host[i], 1e-5 * (1.0 + luma_host[i]))
              << "luminance guide at " << x << "," << y;
          ASSERT_NEAR(got_luma[i].s[1], var_host[i], 1e-5 * (1.0 + var_host[i]))
              << "variance guide at " << x << "," << y;
        }
      for (unsigned y = p.row0; y < p.row0 + p.rows; ++y)
        for (unsigned x = 0; x < w; ++x) {
          const std::size_t i = at(x, y);
          // The edge-stopping centre: the pixel itself, or a borrowing pixel's lender.
          std::size_t ci = i;
          if (!filtered(i)) {
            const long lent = moments[i].s[3] == PX_SVGF_BORROWED ? lender(x, y) : -1;
            if (lent < 0) {
              for (int c = 0; c < 4; ++c) ASSERT_EQ(got[i].s[c], illum[i].s[c]);
              continue;
            }
            ci = static_cast<std::size_t>(lent);
            if (sigma_n == 128.0f) ++borrowing;
          }
          const int cx = static_cast<int>(ci % w), cy = static_cast<int>(ci / w);
          // depth gradient at the centre: central differences, one-sided at the image/readable edge
          const int xl = std::max<int>(cx - 1, 0), xr = std::min<int>(cx + 1, w - 1);
          const int yu = readable(cy - 1) ? cy - 1 : cy, yd = readable(cy + 1) ? cy + 1 : cy;
          const double gx = xr > xl ? (g[at(xr, cy)].depth - g[at(xl, cy)].depth) / double(xr - xl) : 0.0;
          const double gy = yd > yu ? (g[at(cx, yd)].depth - g[at(cx, yu)].depth) / double(yd - yu) : 0.0;
          const double var = var_host[i];  // the pixel's own, a borrowing one's too
          const double hk[5] = {1 / 16.0, 1 / 4.0, 3 / 8.0, 1 / 4.0, 1 / 16.0};
          const glm::dvec3 n0(g[ci].normal[0], g[ci].normal[1], g[ci].normal[2]);
          // Twice: with the normal exponent 128, and with the loose exponent that an isolated
          // pixel (others' total weight < PX_SVGF_ISOLATED x its own) falls back to.
          double ws = 0, vs = 0, cs[3] = {0, 0, 0};
          for (double exponent : {double(sigma_n), std::min(double(sigma_n), double(PX_SVGF_LOOSE_SIGMA_N))}) {
            ws = vs = cs[0] = cs[1] = cs[2] = 0;
            // Every tap's normal weight and the rest of its weight first (normal weight -1 outside
            // the image or the readable rows, 0 on an unfiltered pixel), then the sum with each
            // normal weight moved towards the lesser of its own and its mirror image's through the
            // centre where both lie inside, by the share the history length gives: none on a first
            // frame, all from 1 + 4 frames.
            const double share = std::clamp((moments[i].s[2] - 1.0) / 4.0, 0.0, 1.0);
            double tap_n[5][5], tap_rest[5][5] = {};
            for (auto& row : tap_n)
              for (double& v : row) v = -1.0;
            for (int ky = -2; ky <= 2; ++ky)
              for (int kx = -2; kx <= 2; ++kx) {
                const int tx = x + kx * step, ty = y + ky * step;
                if (!readable(ty) || tx < 0 || tx >= static_cast<int>(w)) continue;
                const std::size_t j = at(tx, ty);
                double& wt = tap_rest[ky + 2][kx + 2];
                tap_n[ky + 2][kx + 2] = 0.0;
                if (!filtered(j) && (kx || ky)) continue;  // the centre is always a tap
                tap_n[ky + 2][kx + 2] = 1.0;
                wt = hk[kx + 2] * hk[ky + 2];
                if (kx || ky) {
                  const glm::dvec3 n1(g[j].normal[0], g[j].normal[1], g[j].normal[2]);
                  const double wn = std::pow(std::max(0.0, glm::dot(n0, n1)), exponent);
                  const double wz =
                      std::exp(-std::abs(g[ci].depth - g[j].depth) /
                               (1.0 * std::abs(gx * kx * step + gy * ky * step) + 1e-3 * g[ci].depth + 1e-6));
                  // the scale is the pair's: the mean of both prefiltered variances
                  const double wl =
                      std::exp(-std::abs(luma_host[i] - luma_host[j]) /
                               (4.0 * std::sqrt(0.5 * (std::max(0.0, var) + std::max(0.0, var_host[j]))) + 1e-6));
                  tap_n[ky + 2][kx + 2] = wn;
                  wt *= wz * wl;
                }
              }
            for (int ky = -2; ky <= 2; ++ky)
              for (int kx = -2; kx <= 2; ++kx) {
                const double own = tap_n[ky + 2][kx + 2], mirror = tap_n[2 - ky][2 - kx];
                const double normal = own >= 0.0 && mirror >= 0.0 ? own + share * (std::min(own, mirror) - own) : own;
                const double wt = std::max(normal, 0.0) * tap_rest[ky + 2][kx + 2];
                if (wt == 0.0) continue;
                const std::size_t j = at(x + kx * static_cast<int>(step), y + ky * static_cast<int>(step));
                ws += wt;
                vs += wt * wt * illum[j].s[3];
                for (int c = 0; c < 3; ++c) cs[c] += wt * illum[j].s[c];
              }
            const double centre = hk[2] * hk[2];
            if (exponent == double(sigma_n)) {
              if (ws - centre >= PX_SVGF_ISOLATED * centre) break;  // not isolated: the strict result stands
              if (sigma_n == 128.0f) ++isolated;
            }
          }
          for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(got[i].s[c], cs[c] / ws, 2e-4 * (1.0 + std::abs(cs[c] / ws)))
                << "pixel " << x << "," << y << " step " << step;
          ASSERT_NEAR(got[i].s[3], vs / (ws * ws), 2e-4 * (1e-3 + vs / (ws * ws))) << "variance at " << x << "," << y;
        }
    }
  }
  EXPECT_GT(isolated, 10);
  EXPECT_GT(borrowing, 10);
}

INSTANTIATE_TEST_SUITE_P(Svgf, AtrousKernel, ::testing::Values(1u, 8u, 64u),
                         [](const ::testing::TestParamInfo<unsigned>& info) {
                           return info.param == 64  ? std::string("TilesInLocalMemory")
                                  : info.param == 8 ? std::string("EightPixelsPerItem")
                                                    : std::string("OnePixelPerItem");
                         });

TEST(Svgf, FilterExpMatchesDoublePrecisionExp) {
  // px_exp (kernels/math/exp.h), the filters' weight function, over its whole range and the
  // values around its edges.
  std::vector<float> x;
  for (int i = 0; i <= 200000; ++i) x.push_back(-87.0f + 175.0f * static_cast<float>(i) / 200000.0f);
  for (float v : {0.0f, -0.0f, 1e-30f, -1e-30f, 0.3465736f, -0.3465736f, 1.0f, -1.0f, -86.99f, 87.99f}) x.push_back(v);
  const std::size_t n_ranged = x.size();
  const float inf = std::numeric_limits<float>::infinity();
  for (float v : {-87.5f, -100.0f, -1e30f, -inf, 88.5f, 1e30f, inf, std::numeric_limits<float>::quiet_NaN()})
    x.push_back(v);
  const auto n = static_cast<cl_uint>(x.size());
  auto in = upload(x);
  cl::Buffer out(one_device().context(), CL_MEM_READ_WRITE, n * sizeof(float));
  cl::Kernel k(one_device().program("testing/math_probe.cl"), "probe_exp");
  k.setArg(0, out);
  k.setArg(1, in);
  k.setArg(2, n);
  launch_1d(one_device().devices()[0].queue, k, n);
  const auto got = download<float>(out, n);
  double worst = 0.0;
  for (std::size_t i = 0; i < n_ranged; ++i) {
    const double want = std::exp(static_cast<double>(x[i]));
    const double rel = std::abs(got[i] - want) / want;
    worst = std::max(worst, rel);
    ASSERT_LT(rel, 4e-7) << "exp(" << x[i] << ") = " << got[i] << ", want " << want;
  }
  std::printf("[ measure  ] px_exp: worst relative error %.3g over [-87, 88]\n", worst);
  for (std::size_t i = n_ranged; i < n; ++i) {
    if (std::isnan(x[i]))
      EXPECT_TRUE(std::isnan(got[i]));
    else if (x[i] < 0.0f)
      EXPECT_EQ(got[i], 0.0f) << "exp(" << x[i] << ")";
    else
      EXPECT_EQ(got[i], inf) << "exp(" << x[i] << ")";
  }
  // px_exp8 (eight taps at once, svgf_atrous8) is the same operations lane by lane: same bits.
  const cl_uint n8 = n / 8 * 8;
  cl::Buffer out8(one_device().context(), CL_MEM_READ_WRITE, n8 * sizeof(float));
  cl::Kernel k8(one_device().program("testing/math_probe.cl"), "probe_exp8");
  k8.setArg(0, out8);
  k8.setArg(1, in);
  k8.setArg(2, n8);
  launch_1d(one_device().devices()[0].queue, k8, n8 / 8);
  const auto got8 = download<float>(out8, n8);
  for (std::size_t i = 0; i < n8; ++i) {
    if (std::isnan(got[i])) {
      EXPECT_TRUE(std::isnan(got8[i])) << "exp8(" << x[i] << ")";
      continue;
    }
    ASSERT_EQ(std::memcmp(&got8[i], &got[i], sizeof(float)), 0)
        << "exp8(" << x[i] << ") = " << got8[i] << ", exp " << got[i];
  }
}

// ---- synthetic scenes through the full filter ----

// A camera at the origin looking down +z; its G-buffer for surfaces given by a function of the
// pixel: depth along z and normal.
struct SyntheticView {
  unsigned w = 64, h = 48;
  CameraParams cam{};
  SyntheticView() {
    Camera c;
    c.position = glm::vec3(0.0f);
    c.target = glm::vec3(0.0f, 0.0f, 1.0f);
    c.vfov_deg = 50.0f;
    cam = make_eye_camera(c, Eye::Left, 0.0f, w, h);
  }
  glm::vec3 dir(unsigned x, unsigned y) const {  // the kernels' pixel-centre ray
    const float sx = ((x + 0.5f) / w * 2.0f - 1.0f) * cam.tan_half_fov_y * cam.aspect;
    const float sy = (1.0f - (y + 0.5f) / h * 2.0f) * cam.tan_half_fov_y;
    const glm::vec3 f(cam.forward[0], cam.forward[1], cam.forward[2]), r(cam.right[0], cam.right[1], cam.right[2]),
        u(cam.up[0], cam.up[1], cam.up[2]);
    return glm::normalize(f + sx * r + sy * u);
  }
  template <typename Surface>  // Surface(x, y) -> {z plane distance, normal}
  std::vector<GBufferTexel> gbuffer(Surface s) const {
    std::vector<GBufferTexel> g(w * h);
    for (unsigned y = 0; y < h; ++y)
      for (unsigned x = 0; x < w; ++x) {
        auto [zplane, n] = s(x, y);
        const glm::vec3 d = dir(x, y);
        const float t = zplane / d.z;
        GBufferTexel& t0 = g[y * w + x];
        t0 = GBufferTexel{};
        for (int k = 0; k < 3; ++k) {
          t0.pos[k] = t * d[k];
          t0.normal[k] = n[k];
        }
        t0.depth = t;
        t0.material_class = PX_CLASS_DIFFUSE;
      }
    return g;
  }
};

struct FilterRun {
  SyntheticView view;
  SvgfDenoiser den;
  cl::Buffer gbuf, prev_gbuf, color, albedo;
  explicit FilterRun(SvgfDenoiser::Options o = {}) : den(one_device(), 0, view.w, view.h, o) {}
  // One frame: returns the denoised radiance. The demodulation albedo is `a`, or 0.5
  // everywhere when `a` is empty.
  std::vector<cl_float4> frame(const std::vector<GBufferTexel>& g, const std::vector<cl_float4>& c,
                               std::vector<cl_float4> a = {}) {
    prev_gbuf = gbuf.get() ? gbuf : upload(g);
    gbuf = upload(g);
    color = upload(c);
    if (a.empty()) a.assign(g.size(), cl_float4{{0.5f, 0.5f, 0.5f, 1.0f}});
    albedo = upload(a);
    const RowRange all{0, view.h};
    den.guide(gbuf, all);
    den.temporal(color, albedo, gbuf, prev_gbuf, view.cam, view.cam, all, all);
    den.variance(all, all);
    for (unsigned i = 0; i < den.options().iterations; ++i) den.atrous(i, all, all);
    den.remodulate(color, albedo, all, all);  // in place, as the pipeline does (w: sample count)
    den.antialias(color, gbuf, view.cam, view.cam, all, all);
    auto result = download<cl_float4>(color, view.w * view.h);
    den.end_frame();
    return result;
  }
  std::vector<cl_float4> moments() { return download<cl_float4>(den.moments(), view.w * view.h); }
};

std::vector<cl_float4> noisy(const SyntheticView& v, std::mt19937& rng, float (*truth)(unsigned, unsigned),
                             float sigma) {
  std::normal_distribution<float> noise(0.0f, sigma);
  std::vector<cl_float4> c(v.w * v.h);
  for (unsigned y = 0; y < v.h; ++y)
    for (unsigned x = 0; x < v.w; ++x) {
      const float t = truth(x, y) + noise(rng);
      c[y * v.w + x] = {{t, t, t, 1.0f}};
    }
  return c;
}

double rmse(const SyntheticView& v, const std::vector<cl_float4>& img, float (*truth)(unsigned, unsigned)) {
  double s = 0;
  for (unsigned y = 0; y < v.h; ++y)
    for (unsigned x = 0; x < v.w; ++x) {
      const double d = img[y * v.w + x].s[0] - truth(x, y);
      s += d * d;
    }
  return std::sqrt(s / (v.w * v.h));
}

auto flat = [](unsigned, unsigned) { return std::pair<float, glm::vec3>{5.0f, glm::vec3(0, 0, -1)}; };

TEST(Svgf, ConstantNoisyInputConvergesToTheConstant) {
  FilterRun run;
  std::mt19937 rng(1);
  auto truth = [](unsigned, unsigned) { return 0.5f; };
  const auto g = run.view.gbuffer(flat);
  double first = 0, last = 0;
  for (int f = 0; f < 10; ++f) {
    auto out = run.frame(g, noisy(run.view, rng, truth, 0.2f));
    const double e = rmse(run.view, out, truth);
    if (f == 0) first = e;
    last = e;
  }
  EXPECT_LT(first, 0.2 * 0.5) << "one frame of filtering should already halve the noise";
  EXPECT_LT(last, 0.02) << "after 10 frames the output should be close to the constant";
  EXPECT_LT(last, 0.5 * first) << "history should keep reducing the error";
}

TEST(Svgf, NormalAndDepthStepsAreNotBlurred) {
  std::mt19937 rng(2);
  for (int kind = 0; kind < 2; ++kind) {
    FilterRun run;
    // Left half: one surface, right half: another (different normal, or much farther away).
    auto surface = [kind](unsigned x, unsigned) {
      if (x < 32) return std::pair<float, glm::vec3>{5.0f, glm::vec3(0, 0, -1)};
      return kind == 0 ? std::pair<float, glm::vec3>{5.0f, glm::normalize(glm::vec3(-1, 0, -0.2f))}
                       : std::pair<float, glm::vec3>{15.0f, glm::vec3(0, 0, -1)};
    };
    auto truth = [](unsigned x, unsigned) { return x < 32 ? 1.0f : 0.1f; };
    const auto g = run.view.gbuffer(surface);
    std::vector<cl_float4> out;
    for (int f = 0; f < 4; ++f) out = run.frame(g, noisy(run.view, rng, truth, 0.1f));
    // The columns right beside the edge keep their own side's value (a blur would pull them
    // towards the middle, 0.55).
    double left = 0, right = 0;
    for (unsigned y = 4; y < run.view.h - 4; ++y) {
      left += out[y * run.view.w + 31].s[0];
      right += out[y * run.view.w + 32].s[0];
    }
    left /= run.view.h - 8;
    right /= run.view.h - 8;
    EXPECT_NEAR(left, 1.0, 0.08) << (kind == 0 ? "normal" : "depth") << " step";
    EXPECT_NEAR(right, 0.1, 0.08) << (kind == 0 ? "normal" : "depth") << " step";
  }
}

TEST(Svgf, FlatRegionVarianceFallsAsHistoryGrows) {
  FilterRun run;
  std::mt19937 rng(3);
  auto truth = [](unsigned x, unsigned y) { return 0.3f + 0.002f * (x + y); };
  const auto g = run.view.gbuffer(flat);
  std::vector<double> errors, history;
  for (int f = 0; f < 8; ++f) {
    auto out = run.frame(g, noisy(run.view, rng, truth, 0.15f));
    errors.push_back(rmse(run.view, out, truth));
    history.push_back(run.moments()[run.view.w * 20 + 30].s[2]);
  }
  EXPECT_EQ(history.front(), 1.0f);
  EXPECT_EQ(history.back(), 8.0f) << "history length counts frames on a static flat region";
  EXPECT_LT(errors.back(), 0.6 * errors.front());
}

TEST(Svgf, DisocclusionResetsHistory) {
  FilterRun run;
  std::mt19937 rng(5);
  auto truth = [](unsigned, unsigned) { return 0.5f; };
  // Frames 0-2: an object covers the left half (at depth 2); frame 3: it is gone, the wall
  // behind (depth 5) shows.
  auto with_object = [](unsigned x, unsigned) {
    return x < 32 ? std::pair<float, glm::vec3>{2.0f, glm::vec3(0, 0, -1)}
                  : std::pair<float, glm::vec3>{5.0f, glm::vec3(0, 0, -1)};
  };
  for (int f = 0; f < 3; ++f) run.frame(run.view.gbuffer(with_object), noisy(run.view, rng, truth, 0.1f));
  run.frame(run.view.gbuffer(flat), noisy(run.view, rng, truth, 0.1f));
  auto m = run.moments();
  for (unsigned y = 2; y < run.view.h - 2; ++y) {
    EXPECT_EQ(m[y * run.view.w + 10].s[2], 1.0f) << "disoccluded pixel keeps stale history, row " << y;
    EXPECT_EQ(m[y * run.view.w + 50].s[2], 4.0f) << "static pixel lost its history, row " << y;
  }
}

TEST(Svgf, PixelsWhoseNormalNoNeighbourSharesAreStillFiltered) {
  // Foliage-like surface: every pixel's normal is tilted at random (as alpha-cut leaf cards
  // are), at the same depth. The truth is 1 everywhere; each pixel's one sample is 0 (a path
  // that found no light) or 1 / 0.6 — mean 1. A pixel no neighbour matches under the strict
  // normal exponent must not keep its lone black sample.
  FilterRun run;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto g = run.view.gbuffer([](unsigned, unsigned) { return std::pair{3.0f, glm::vec3(0, 0, -1)}; });
  for (auto& t : g) {
    const glm::vec3 n = glm::normalize(glm::vec3(u(rng) - 0.5f, u(rng) - 0.5f, -0.6f));
    for (int k = 0; k < 3; ++k) t.normal[k] = n[k];
  }
  std::vector<cl_float4> c(g.size());
  int black_in = 0;
  for (auto& v : c) {
    const float s = u(rng) < 0.6f ? 1.0f / 0.6f : 0.0f;
    black_in += s == 0.0f;
    v = {{0.5f * s, 0.5f * s, 0.5f * s, 1.0f}};  // albedo 0.5 (FilterRun's default): illumination s
  }
  auto out = run.frame(g, c);
  int black_out = 0;
  double sum = 0.0;
  for (const auto& v : out) {
    black_out += lum(v) < 0.05f * 0.5f;
    sum += lum(v);
  }
  std::printf("[ measure  ] black pixels: %d of %zu in, %d out; mean %.3f (truth 0.5)\n", black_in, out.size(),
              black_out, sum / out.size());
  EXPECT_GT(black_in, 1000);
  EXPECT_LT(black_out, 0.002 * out.size());
  EXPECT_NEAR(sum / out.size(), 0.5, 0.05);
}

// A silhouette against the sky: pixels whose centre ray sees the sky (the G-buffer calls them
// background) while their one jittered sample hit the surface and, like a third of samples
// here, found no light. Passed through as background pixels they stayed black: a dotted
// outline along every silhouette. Their albedo's w (the share of samples on a filtered
// surface) says the sample hit the surface: they are filtered with a neighbour's geometry, and
// the surface takes its expected share of such a pixel at 1 spp, 1/3, the sky around it the
// rest. Pixels whose sample saw the sky still pass through untouched.
TEST(Svgf, SilhouettePixelsWhoseSamplesHitTheSurfaceAreFilteredNotPassedThrough) {
  FilterRun run;
  const auto& v = run.view;
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto g = v.gbuffer([](unsigned, unsigned) { return std::pair{3.0f, glm::vec3(0, 0, -1)}; });
  std::vector<cl_float4> c(g.size()), a(g.size(), cl_float4{{0.5f, 0.5f, 0.5f, 1.0f}});
  const cl_float4 sky{{0.1f, 0.2f, 0.6f, 1.0f}};
  const unsigned edge = 40;  // columns >= edge: the sky at the pixel centre
  for (unsigned y = 0; y < v.h; ++y)
    for (unsigned x = 0; x < v.w; ++x) {
      const std::size_t i = y * v.w + x;
      const float s = u(rng) < 0.7f ? 1.0f / 0.7f : 0.0f;  // illumination: mean 1
      c[i] = {{0.5f * s, 0.5f * s, 0.5f * s, 1.0f}};
      if (x < edge) continue;
      g[i].material_class = PX_CLASS_MISS;
      g[i].depth = 0.0f;
      if (x == edge && y % 2 == 0) {
        c[i] = {{0.0f, 0.0f, 0.0f, 1.0f}};  // the sample hit the surface and found no light
      } else {
        c[i] = sky;  // the sample saw the sky
        a[i] = {{1.0f, 1.0f, 1.0f, 0.0f}};
      }
    }
  const auto out = run.frame(g, c, a);
  int lifted = 0;
  for (unsigned y = 0; y < v.h; ++y)
    for (unsigned x = edge; x < v.w; ++x) {
      const std::size_t i = y * v.w + x;
      if (x == edge && y % 2 == 0) {
        // out = (2/3) sky + (1/3) grey surface (filtered: about 0.5, the truth here)
        float grey[3];
        for (int k = 0; k < 3; ++k) grey[k] = 3.0f * (out[i].s[k] - (2.0f / 3.0f) * sky.s[k]);
        EXPECT_NEAR(grey[0], grey[2], 1e-4f) << "silhouette pixel " << x << "," << y;
        EXPECT_NEAR(grey[1], grey[2], 1e-4f) << "silhouette pixel " << x << "," << y;
        EXPECT_NEAR(grey[0], 0.5f, 0.2f) << "silhouette pixel " << x << "," << y;
        lifted += grey[0] > 0.25f;
      } else {
        for (int k = 0; k < 3; ++k) ASSERT_EQ(out[i].s[k], sky.s[k]) << "sky pixel " << x << "," << y;
      }
    }
  EXPECT_EQ(lifted, static_cast<int>(v.h + 1) / 2);
}

// The environment is not filtered, but at 1 spp each of its pixels is one jittered sample (a
// horizon's step shows as a crawling sawtooth), so its colour is accumulated over frames, its
// history found by direction. It converges to the mean; it starts over where the previous frame
// saw a surface there; the first frame passes through untouched.
TEST(Svgf, EnvironmentPixelsAccumulateOverFramesByDirection) {
  // SVGF's own accumulation of the environment, without the anti-aliasing pass after it (which
  // blends every pixel with its own history and would hide what this checks).
  SvgfDenoiser::Options no_antialias;
  no_antialias.taa_alpha = 1.0f;
  FilterRun run(no_antialias);
  const auto& v = run.view;
  auto sky_gbuffer = [&v](bool surface_rows) {
    auto g = v.gbuffer([](unsigned, unsigned) { return std::pair{3.0f, glm::vec3(0, 0, -1)}; });
    for (unsigned y = 0; y < v.h; ++y)
      for (unsigned x = 0; x < v.w; ++x) {
        if (surface_rows && y < v.h / 2) continue;
        GBufferTexel& t = g[y * v.w + x];
        const glm::vec3 d = v.dir(x, y);
        for (int k = 0; k < 3; ++k) t.pos[k] = d[k];
        t.depth = 0.0f;
        t.material_class = PX_CLASS_MISS;
      }
    return g;
  };
  std::mt19937 rng(23);
  auto truth = [](unsigned, unsigned) { return 0.4f; };
  const auto all_sky = sky_gbuffer(false);
  std::vector<cl_float4> sky_albedo(all_sky.size(), cl_float4{{1.0f, 1.0f, 1.0f, 0.0f}});
  // Frame 0 has no history: passed through bit for bit.
  auto c0 = noisy(v, rng, truth, 0.2f);
  auto out0 = run.frame(all_sky, c0, sky_albedo);
  for (std::size_t i = 0; i < out0.size(); ++i)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(out0[i].s[k], c0[i].s[k]) << "pixel " << i;
  const double first = rmse(v, out0, truth);
  double last = first;
  for (int f = 1; f < 12; ++f) last = rmse(v, run.frame(all_sky, noisy(v, rng, truth, 0.2f), sky_albedo), truth);
  std::printf("[ measure  ] environment RMSE: frame 0 %.4f, frame 11 %.4f\n", first, last);
  EXPECT_LT(last, 0.45 * first) << "12 frames with alpha 0.2 should cut the noise by more than half";

  // The top half turns into a surface for a frame, then back into sky: that sky has no history
  // (it was not the environment the frame before) and passes through again.
  run.frame(sky_gbuffer(true), noisy(v, rng, truth, 0.2f), sky_albedo);
  auto c2 = noisy(v, rng, truth, 0.2f);
  auto out2 = run.frame(all_sky, c2, sky_albedo);
  int fresh_equal = 0, kept_differ = 0;
  for (unsigned y = 0; y < v.h; ++y)
    for (unsigned x = 0; x < v.w; ++x) {
      const std::size_t i = y * v.w + x;
      const bool same = out2[i].s[0] == c2[i].s[0];
      // rows v.h/2 - 1 and v.h/2 straddle the change: bilinear taps may reach either side
      if (y + 1 < v.h / 2)
        fresh_equal += same;
      else if (y > v.h / 2)
        kept_differ += !same;
    }
  EXPECT_EQ(fresh_equal, static_cast<int>((v.h / 2 - 1) * v.w));
  EXPECT_GT(kept_differ, static_cast<int>((v.h / 2 - 1) * v.w * 9 / 10));
}

TEST(Svgf, RareBrightSamplesKeepTheirEnergy) {
  // One-sample paths are heavy-tailed: most find little light, a few find a lot (a bounce
  // that reaches the sun). Here 5% of the pixels hold 20 and the rest 0, on one flat surface.
  // Luminance edge-stopping must not take those samples for edges and drop them: the filtered
  // mean stays the input's. (The spatial variance estimate is what scales that test; weighted
  // by luminance itself, as it once was, it ignored the bright samples, judged the dark pixels
  // noise-free, and 79% of the energy vanished.)
  FilterRun run;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  auto g = run.view.gbuffer([](unsigned, unsigned) { return std::pair{3.0f, glm::vec3(0, 0, -1)}; });
  std::vector<cl_float4> c(g.size());
  double in = 0.0;
  for (auto& v : c) {
    const float s = u(rng) < 0.05f ? 20.0f : 0.0f;
    v = {{0.5f * s, 0.5f * s, 0.5f * s, 1.0f}};
    in += lum(v);
  }
  auto out = run.frame(g, c);
  double sum = 0.0;
  for (const auto& v : out) sum += lum(v);
  std::printf("[ measure  ] mean in %.4f, out %.4f\n", in / c.size(), sum / out.size());
  EXPECT_NEAR(sum / in, 1.0, 0.1);
}

// The filter keeps energy: a flat lit surface (albedo 0.5), a still camera, 16 frames whose
// every pixel is one heavy-tailed sample, each frame's mean exactly the surface's. Every pass
// (temporal blend, variance, five a-trous steps, remodulation, anti-aliasing) then has an
// exactly known mean to keep: whatever it loses is bias, not noise. Two distributions of the
// sample: exponential (a diffusely lit surface's one-bounce estimate) and the harder 10% of
// pixels at 10x the mean, 90% at 0 (a light, or the sun, found by one sample in ten).
// The bias measured, and with the SVGF paper's luminance test (svgf_luma and PX_ATROUS_TAP_SUM
// say why not): docs/measurements.md, SVGF exact-mean bias.
double filtered_mean_of_exact_mean_noise(bool rare_bright) {
  FilterRun run;
  const auto g = run.view.gbuffer(flat);
  const std::size_t n = g.size();
  std::mt19937 rng(11);
  // Exact means: the rare-bright frame is a shuffle of n/10 tens and zeros; the exponential
  // frame is the quantiles of Exp(1) at (k + 0.5) / n, shuffled, rescaled to mean 1.
  std::vector<float> values(n);
  for (std::size_t k = 0; k < n; ++k)
    values[k] = rare_bright ? (k < n / 10 ? 10.0f : 0.0f)
                            : static_cast<float>(-std::log(1.0 - (k + 0.5) / static_cast<double>(n)));
  double total = 0.0;
  for (float v : values) total += v;
  for (float& v : values) v = static_cast<float>(v * n / total);
  double mean = 0.0;
  for (int f = 0; f < 16; ++f) {
    std::shuffle(values.begin(), values.end(), rng);
    std::vector<cl_float4> c(n);
    for (std::size_t i = 0; i < n; ++i) c[i] = {{0.5f * values[i], 0.5f * values[i], 0.5f * values[i], 1.0f}};
    const auto out = run.frame(g, c);
    mean = 0.0;
    for (const auto& v : out) mean += lum(v);
    mean /= static_cast<double>(n);
  }
  return mean / 0.5;
}

TEST(Svgf, FilterKeepsTheMeanOfANoisyImageOfKnownMean) {
  const double exponential = filtered_mean_of_exact_mean_noise(false);
  const double rare_bright = filtered_mean_of_exact_mean_noise(true);
  std::printf("[ measure  ] filtered mean / exact mean after 16 frames: exponential %.4f, rare bright %.4f\n",
              exponential, rare_bright);
  EXPECT_NEAR(exponential, 1.0, 0.005);
  EXPECT_NEAR(rare_bright, 1.0, 0.01);
}

// ---- distributed ----

struct DenoisedRun {
  std::vector<std::array<ImageRGB, 2>> frames;
};

// What the pipeline runs below share: `kind`, 1 spp, 3 bounces, `seams`.
StereoPipeline::Options pipeline_options(PipelineKind kind, SeamMode seams = SeamMode::Halo) {
  StereoPipeline::Options opt;
  opt.pipeline = kind;
  opt.trace.spp = 1;
  opt.trace.bounces = 3;
  opt.denoise->seams = seams;
  return opt;
}

DenoisedRun run_pipeline(const LoadedScene& loaded, int devices, SeamMode seams, unsigned frames, unsigned w,
                         unsigned h, unsigned iterations = 5, bool denoise = true) {
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  StereoPipeline::Options opt = pipeline_options(PipelineKind::Proposed, seams);
  opt.denoise->svgf.iterations = iterations;
  if (!denoise) opt.denoise.reset();
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  DenoisedRun r;
  for (unsigned f = 0; f < frames; ++f) {
    p.render(f, 0.25f * f);  // a fast camera: vertical and horizontal motion between frames
    r.frames.push_back(p.radiance());
  }
  return r;
}

const LoadedScene& cornell() {
  static LoadedScene s = load_and_build("cornell-glossy", true);
  return s;
}

// A sphere and a box under an analytic sky, the camera moving: the environment (accumulated by
// direction) and silhouettes against it (pixels that borrow a neighbour's geometry) are what
// cornell's closed room never shows.
const LoadedScene& sphere_under_sky() {
  static LoadedScene loaded = [] {
    Scene s;
    s.name = "sphere under sky";
    Material m;
    m.diffuse = glm::vec3(0.7f, 0.6f, 0.5f);
    s.materials = {m};
    append_icosphere(s.triangles, {0.0f, 0.0f, 0.0f}, 1.0f, 3, 0);
    append_box(s.triangles, {1.3f, -1.0f, -0.5f}, {2.0f, 0.2f, 0.3f}, 0);
    s.sky.enabled = true;
    s.sky.zenith = {0.3f, 0.5f, 1.0f};
    s.sky.horizon = {0.8f, 0.85f, 0.9f};
    s.sky.ground = {0.2f, 0.2f, 0.2f};
    s.camera.position = {0.0f, 0.3f, 4.0f};
    s.camera.target = {0.3f, 0.0f, 0.0f};
    s.camera.vfov_deg = 50.0f;
    s.camera_path = {{0.0f, {0.0f, 0.3f, 4.0f}, {0.3f, 0.0f, 0.0f}}, {1.0f, {0.8f, 0.6f, 3.6f}, {0.3f, 0.1f, 0.0f}}};
    return LoadedScene{s, build_bvh(s.triangles), {}};
  }();
  return loaded;
}

bool same_bits(const ImageRGB& a, const ImageRGB& b) {
  return a.rgb.size() == b.rgb.size() && std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)) == 0;
}

TEST(SvgfDistributed, HaloSeamsAreBitIdenticalForOneToEightDevices) {
  // 41 rows: no device count divides it. Beyond the machine's compute units the devices are
  // queues on one device (6 and 8 on a 2-core machine): the counts that aborted inside PoCL.
  const unsigned w = 48, h = 41;
  for (const LoadedScene* scene : {&cornell(), &sphere_under_sky()}) {
    auto one = run_pipeline(*scene, 1, SeamMode::Halo, 3, w, h);
    for (int n : {2, 3, 4, 6, 8}) {
      auto many = run_pipeline(*scene, n, SeamMode::Halo, 3, w, h);
      for (unsigned f = 0; f < 3; ++f)
        for (int e = 0; e < 2; ++e)
          EXPECT_TRUE(same_bits(one.frames[f][e], many.frames[f][e]))
              << scene->scene.name << ": " << n << " devices, frame " << f << ", eye " << e;
    }
  }
}

TEST(SvgfDistributed, SideQueueGivesTheSameImages) {
  // The left eye's denoising, tonemapping and transfer on a side queue per device (overlapping
  // the right eye's reprojection and hole filling) against one queue per device: same bits,
  // for every pipeline, two seam modes and 1 and 3 devices, over frames with history.
  const unsigned w = 40, h = 29;
  const LoadedScene& loaded = cornell();
  for (auto kind : {PipelineKind::Proposed, PipelineKind::Baseline, PipelineKind::Mono})
    for (SeamMode seams : {SeamMode::Halo, SeamMode::Bilateral})
      for (int devices : {1, 3}) {
        std::array<std::vector<std::array<ImageRGB, 2>>, 2> frames;
        std::array<std::vector<std::array<std::vector<std::uint8_t>, 2>>, 2> pngs;
        for (int overlap = 0; overlap < 2; ++overlap) {
          DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
          DeviceScene ds(set, loaded.scene, loaded.bvh);
          StereoPipeline::Options opt = pipeline_options(kind, seams);
          opt.overlap = overlap == 1 ? Overlap::On : Overlap::Off;  // On: also on these CPU devices
          StereoPipeline p(set, ds, loaded.scene, w, h, opt);
          for (unsigned f = 0; f < 3; ++f) {
            p.render(f, 0.25f * f);
            frames[overlap].push_back(p.radiance());
            pngs[overlap].push_back(p.rgba8());
          }
        }
        const std::string what =
            std::string(to_string(kind)) + " " + to_string(seams) + " " + std::to_string(devices) + " devices";
        for (unsigned f = 0; f < 3; ++f)
          for (int e = 0; e < 2; ++e)
            EXPECT_TRUE(same_bits(frames[0][f][e], frames[1][f][e])) << what << ", frame " << f << ", eye " << e;
        EXPECT_EQ(pngs[0], pngs[1]) << what;
      }
}

// Three frames (with history: the first a-trous iterate feeds the next) of the proposed pipeline
// on 2 devices, 41x29, with SVGF's options set by `svgf`.
std::vector<std::array<ImageRGB, 2>> three_denoised_frames(const LoadedScene& scene,
                                                           const std::function<void(SvgfDenoiser::Options&)>& svgf) {
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, scene.scene, scene.bvh);
  StereoPipeline::Options opt = pipeline_options(PipelineKind::Proposed);
  svgf(opt.denoise->svgf);
  StereoPipeline p(set, ds, scene.scene, 41, 29, opt);
  std::vector<std::array<ImageRGB, 2>> frames;
  for (unsigned f = 0; f < 3; ++f) {
    p.render(f, 0.25f * f);
    frames.push_back(p.radiance());
  }
  return frames;
}

TEST(SvgfDistributed, EightPixelAtrousKernelGivesTheSameImagesToRounding) {
  // svgf_atrous8 (what CPU devices run) against svgf_atrous through the whole pipeline, over
  // frames with history: the same filter, so pixels differ by float rounding only (the two
  // kernels contract multiply-adds differently, and the luminance test's square root per tap
  // may round differently in its float8 form; history carries the differences into later
  // frames; docs/measurements.md, a-trous lanes).
  for (const LoadedScene* scene : {&cornell(), &sphere_under_sky()}) {
    std::array<std::vector<std::array<ImageRGB, 2>>, 2> frames;
    for (int k = 0; k < 2; ++k)
      frames[k] = three_denoised_frames(*scene, [&](SvgfDenoiser::Options& o) { o.atrous_lanes = k == 0 ? 1 : 8; });
    std::size_t identical = 0, values = 0;
    double worst = 0.0;
    for (unsigned f = 0; f < 3; ++f)
      for (int e = 0; e < 2; ++e)
        for (std::size_t i = 0; i < frames[0][f][e].rgb.size(); ++i) {
          const float a = frames[0][f][e].rgb[i], b = frames[1][f][e].rgb[i];
          ++values;
          identical += a == b;
          worst = std::max(worst, std::abs(double(a) - b) / (std::abs(double(a)) + 1e-3));
        }
    std::printf("[ measure  ] %zu of %zu values bit-identical, worst relative difference %.3g\n", identical, values,
                worst);
    EXPECT_LT(worst, 3e-4);
    EXPECT_GT(identical, values / 4) << "rounding differences should leave most values exact";
  }
}

TEST(SvgfDistributed, TiledAtrousKernelGivesTheSameImages) {
  // svgf_atrous_tiled (GPUs, steps 1-4) against svgf_atrous through the whole pipeline: 2 devices
  // (tiles that straddle a strip's readable rows), 5 iterations (steps 8 and 16 fall back to
  // svgf_atrous), frames with history. The tap sum is the same code reading the same texels
  // from local memory instead of global, so the images are the same to the bit.
  for (const LoadedScene* scene : {&cornell(), &sphere_under_sky()}) {
    std::array<std::vector<std::array<ImageRGB, 2>>, 2> frames;
    for (int k = 0; k < 2; ++k)
      frames[k] = three_denoised_frames(*scene, [&](SvgfDenoiser::Options& o) {
        o.atrous_lanes = 1;
        o.atrous_tiles = k;
        o.iterations = 5;
      });
    for (unsigned f = 0; f < 3; ++f)
      for (int e = 0; e < 2; ++e)
        EXPECT_TRUE(same_bits(frames[0][f][e], frames[1][f][e]))
            << scene->scene.name << ", frame " << f << ", eye " << e;
  }
}

TEST(SvgfDistributed, IndependentSeamsDifferOnlyNearSeams) {
  // One frame (no history: the anti-aliasing pass passes it through), 2 a-trous iterations: a
  // pixel reads at most 3 (variance) + (2 + 1) + (4 + 1) (a-trous taps and their luminance
  // guide's 3x3) rows away, plus 1 for the depth gradient: differences stay within 13 rows.
  const unsigned w = 48, h = 40;
  auto one = run_pipeline(cornell(), 1, SeamMode::Halo, 1, w, h, 2);
  auto two = run_pipeline(cornell(), 2, SeamMode::Independent, 1, w, h, 2);
  const unsigned seam = 20;
  int differing = 0;
  for (int e = 0; e < 2; ++e)
    for (unsigned y = 0; y < h; ++y)
      for (unsigned x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          const std::size_t i = (y * w + x) * 3 + c;
          if (one.frames[0][e].rgb[i] != two.frames[0][e].rgb[i]) {
            ++differing;
            EXPECT_LT(std::abs(static_cast<int>(y) - static_cast<int>(seam)), 13)
                << "row " << y << " differs, far from the seam";
          }
        }
  EXPECT_GT(differing, 0) << "filtering strips alone should change something at the seam";
}

// Mean luminance of rows [row0, height) of `image`.
double mean_luminance(const ImageRGB& image, int row0 = 0) {
  double sum = 0.0;
  const std::size_t begin = static_cast<std::size_t>(row0) * image.width * 3;
  for (std::size_t i = begin; i < image.rgb.size(); i += 3)
    sum += 0.2126 * image.rgb[i] + 0.7152 * image.rgb[i + 1] + 0.0722 * image.rgb[i + 2];
  return sum / static_cast<double>((image.rgb.size() - begin) / 3);
}

TEST(SvgfDistributed, DenoisingBringsCornellCloserToTheReference) {
  // The diffuse Cornell box, 96x72, 1 spp, 3 bounces, the camera moving; frame 3 (history
  // from frames 0-2) of the proposed pipeline on 2 devices with halo seams, noisy and denoised,
  // against a reference independent of the pipeline: render_reference (what `parallax
  // reference` runs: every sample jittered, its own seed), 1024 spp at the same 3 bounces, whose
  // own noise is far below the margins (docs/measurements.md, SVGF against a reference).
  //
  // Two regions: the whole image, and the rows below the emitter, where the error is the
  // denoiser's. At 1 spp each pixel's one sample goes through the frame's jitter position, the
  // same in every pixel (CameraParams::jitter), so in one frame a pixel on the light's edge is
  // all emitter or none; over frames the anti-aliasing pass averages the positions.
  //
  // The images are deterministic (seeded; 1 and 2 devices give the same bits), so the floors
  // sit close to the values measured now, with a margin for another CPU's float rounding. The
  // values measured, before the jitter, and with broken weights (what the floors catch):
  // docs/measurements.md, SVGF against a reference.
  const unsigned w = 96, h = 72, frames = 4;
  static LoadedScene loaded = load_and_build("cornell", true);
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  PathTracer tracer(set, ds, loaded.scene);
  ReferenceOptions ref_opt;
  ref_opt.spp = 1024;
  ref_opt.bounces = 3;
  const auto reference = render_reference(tracer, 0.25f * (frames - 1), frames - 1, w, h, ref_opt);
  auto noisy = run_pipeline(loaded, 2, SeamMode::Halo, frames, w, h, 5, false);
  auto denoised = run_pipeline(loaded, 2, SeamMode::Halo, frames, w, h, 5, true);
  const double floor_whole[2] = {29.3, 29.8}, gain_whole[2] = {5.0, 4.3};
  const double floor_surfaces[2] = {38.2, 38.5}, gain_surfaces[2] = {10.4, 9.2};
  for (int e = 0; e < 2; ++e) {
    SCOPED_TRACE(e == 0 ? "left eye" : "right eye");
    const ImageRGB& ref = reference[e];
    const ImageRGB& n = noisy.frames.back()[e];
    const ImageRGB& d = denoised.frames.back()[e];
    // The emitter's rows: those with a pixel brighter than 1 in the reference (rows 8-11 here).
    int below = 0;
    for (int y = 0; y < ref.height; ++y)
      for (int x = 0; x < ref.width; ++x) {
        const std::size_t i = (static_cast<std::size_t>(y) * ref.width + x) * 3;
        if (0.2126 * ref.rgb[i] + 0.7152 * ref.rgb[i + 1] + 0.0722 * ref.rgb[i + 2] > 1.0) below = y + 1;
      }
    ASSERT_GT(below, 0) << "no emitter in the reference";
    ASSERT_LT(below, static_cast<int>(h) / 2) << "the emitter should be in the top rows";
    const double before = compare_images(n, ref).psnr_db, after = compare_images(d, ref).psnr_db;
    const double before_s = compare_images(n, ref, below).psnr_db, after_s = compare_images(d, ref, below).psnr_db;
    // Energy below the emitter is measured from 2 rows further down: anti-aliasing blends each
    // pixel with its reprojected history within its 3x3 neighbourhood's range, and under the
    // moving camera that carries some of the light's anti-aliased rim a row down.
    const int guard = below + 2;
    const double energy_ref = mean_luminance(d, guard) / mean_luminance(ref, guard);
    const double energy_ref_whole = mean_luminance(d) / mean_luminance(ref);
    const double energy_noisy = mean_luminance(d) / mean_luminance(n);
    const double energy_noisy_s = mean_luminance(d, guard) / mean_luminance(n, guard);
    std::printf(
        "[ measure  ] eye %d: whole image 1 spp %.2f dB -> SVGF %.2f dB; rows %d+ %.2f -> %.2f dB; "
        "mean luminance rows %d+ denoised / reference %.4f, denoised / noisy %.4f; whole image denoised / "
        "reference %.4f, denoised / noisy %.4f\n",
        e, before, after, below, before_s, after_s, guard, energy_ref, energy_noisy_s, energy_ref_whole, energy_noisy);
    EXPECT_GT(after, floor_whole[e]);
    EXPECT_GT(after - before, gain_whole[e]) << "noisy " << before << " dB, denoised " << after << " dB";
    EXPECT_GT(after_s, floor_surfaces[e]) << "rows " << below << "+";
    EXPECT_GT(after_s - before_s, gain_surfaces[e]) << "rows " << below << "+: noisy " << before_s << " dB";
    EXPECT_NEAR(energy_ref, 1.0, 0.04) << "rows " << guard << "+: the denoised image against the reference";
    EXPECT_NEAR(energy_noisy_s, 1.0, 0.025) << "rows " << guard << "+: the denoiser should neither add nor lose energy";
    EXPECT_NEAR(energy_noisy, 1.0, 0.01) << "whole image: the denoiser should neither add nor lose energy";
  }
}

TEST(SvgfDistributed, BilateralSeamsSoftenTheSeamWithinTheBandAndChangeNothingElse) {
  // --seams bilateral (DenoiseStage; seam_bilateral.cl): the strips are denoised as
  // with independent seams, then the rows within seam_band (4) of each seam pass through a 5x5
  // cross-bilateral filter reading the neighbour's rows across the seam. 2 devices, 64x48 (the
  // seam at row 24), 3 frames, 2 a-trous iterations; the 1-device image (= halo seams) is the
  // seamless one. Summed over frames and eyes (figures: docs/measurements.md, bilateral seams):
  //   - independent seams leave a step: the mean |row 24 - row 23| is several times the
  //     1-device image's;
  //   - bilateral brings the band's rows closer to the 1-device image and lowers the step,
  //     without removing it: it softens the seam, it does not make it seamless;
  //   - every row outside the band is bit-identical to independent's in every frame (the
  //     filter works on the finished radiance; the history comes from the first a-trous
  //     iterate, which it never touches). Inside the band the kernel's test |y - seam| < band,
  //     with the seam the lower strip's first row, touches rows 21-27: 3 rows above the seam
  //     and 4 below.
  const unsigned w = 64, h = 48, frames = 3, seam = 24, band = 4;
  const auto one = run_pipeline(cornell(), 1, SeamMode::Halo, frames, w, h, 2);
  const auto independent = run_pipeline(cornell(), 2, SeamMode::Independent, frames, w, h, 2);
  const auto bilateral = run_pipeline(cornell(), 2, SeamMode::Bilateral, frames, w, h, 2);
  // Mean over a row's values of |a - b|, and of |row y - row y-1| of one image.
  auto row_difference = [&](const ImageRGB& a, const ImageRGB& b, unsigned y) {
    double sum = 0.0;
    for (std::size_t i = y * w * 3; i < (y + 1) * w * 3; ++i) sum += std::abs(a.rgb[i] - b.rgb[i]);
    return sum / (w * 3);
  };
  auto step = [&](const ImageRGB& a, unsigned y) {
    double sum = 0.0;
    for (std::size_t i = y * w * 3; i < (y + 1) * w * 3; ++i) sum += std::abs(a.rgb[i] - a.rgb[i - w * 3]);
    return sum / (w * 3);
  };
  double step_one = 0, step_independent = 0, step_bilateral = 0, band_independent = 0, band_bilateral = 0;
  for (unsigned f = 0; f < frames; ++f)
    for (int e = 0; e < 2; ++e) {
      const ImageRGB &o = one.frames[f][e], &i = independent.frames[f][e], &b = bilateral.frames[f][e];
      step_one += step(o, seam);
      step_independent += step(i, seam);
      step_bilateral += step(b, seam);
      for (unsigned y = 0; y < h; ++y) {
        const bool in_band = y + band >= seam && y < seam + band;
        const double changed = row_difference(b, i, y);
        if (in_band) {
          band_independent += row_difference(i, o, y);
          band_bilateral += row_difference(b, o, y);
        } else {
          EXPECT_EQ(changed, 0.0) << "frame " << f << ", eye " << e << ": row " << y << " is outside the band";
        }
      }
      // The filter reads across the seam on both sides.
      EXPECT_GT(row_difference(b, i, seam - 1), 0.0) << "frame " << f << ", eye " << e << ": the row above the seam";
      EXPECT_GT(row_difference(b, i, seam), 0.0) << "frame " << f << ", eye " << e << ": the row below the seam";
    }
  std::printf(
      "[ measure  ] step across the seam: 1 device %.4f, independent %.4f, bilateral %.4f; band's difference "
      "from 1 device: independent %.4f, bilateral %.4f\n",
      step_one, step_independent, step_bilateral, band_independent, band_bilateral);
  EXPECT_GT(step_independent, 4.0 * step_one) << "independent seams should leave a visible step";
  EXPECT_LT(step_bilateral, 0.8 * step_independent) << "the bilateral filter should lower the step";
  EXPECT_LT(band_bilateral, 0.92 * band_independent) << "the band should come closer to the seamless image";
  EXPECT_GT(step_bilateral, 2.5 * step_one) << "measured: bilateral softens the seam but does not remove it";
}

TEST(SvgfDistributed, QualityChangesBetweenFramesKeepHaloSeamsBitIdentical) {
  // What the control loop does: spp, bounces and SVGF iterations change from frame to frame.
  // The N-device image must still equal the 1-device image, and a quality outside what the
  // pipeline was built for is refused.
  const auto& scene = cornell();
  const FrameQuality schedule[] = {{1, 3, 5}, {2, 2, 3}, {1, 4, 1}, {3, 3, 4}};
  std::vector<std::array<ImageRGB, 2>> images[2];
  const int device_counts[2] = {1, 3};
  for (int run = 0; run < 2; ++run) {
    DeviceSet set = DeviceSet::create({device_counts[run], DeviceMode::Auto, "", std::nullopt});
    DeviceScene ds(set, scene.scene, scene.bvh);
    StereoPipeline::Options opt;
    opt.denoise->svgf.iterations = 5;
    StereoPipeline p(set, ds, scene.scene, 40, 31, opt);
    EXPECT_THROW(p.set_quality({1, 3, 6}), std::invalid_argument);
    EXPECT_THROW(p.set_quality({0, 3, 2}), std::invalid_argument);
    for (unsigned f = 0; f < 4; ++f) {
      p.set_quality(schedule[f]);
      EXPECT_EQ(p.quality(), schedule[f]);
      p.render(f, 0.25f * f);
      images[run].push_back(p.radiance());
    }
  }
  for (unsigned f = 0; f < 4; ++f)
    for (int e = 0; e < 2; ++e)
      EXPECT_EQ(std::memcmp(images[0][f][e].rgb.data(), images[1][f][e].rgb.data(),
                            images[0][f][e].rgb.size() * sizeof(float)),
                0)
          << "frame " << f << " eye " << e;
}

// A quad filling the view, textured with a checker much finer than a pixel, lit by a white
// sky: every pixel mixes two albedos. `a` and `b` are the checker's colours.
LoadedScene fine_checker_quad(glm::vec3 a, glm::vec3 b) {
  Scene s;
  Texture t;
  t.path = "checker";
  t.width = t.height = 256;
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x) {
      const glm::vec3 c = ((x + y) % 2) ? a : b;
      t.rgba.insert(t.rgba.end(), {c.x, c.y, c.z, 1.0f});
    }
  s.textures.push_back(t);
  Material m;
  m.diffuse = glm::vec3(1.0f);
  m.diffuse_texture = 0;
  s.materials = {m};
  append_quad_facing(s.triangles, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, {0, 0, 1}, 0);
  s.sky.enabled = true;
  s.sky.zenith = s.sky.horizon = s.sky.ground = glm::vec3(1.0f);
  s.camera.position = {0.0f, 0.0f, 3.0f};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 40.0f;
  return LoadedScene{s, build_bvh(s.triangles), {}};
}

TEST(SvgfDistributed, RemodulationKeepsEveryChannelsMeanForNearZeroAndSaturatedAlbedos) {
  // Demodulation divides by the albedo and remodulation multiplies it back. Where the albedo
  // varies inside a pixel and one channel is near zero (a foliage texture with blue ~2/255),
  // dividing by the pixel centre's albedo instead of the albedo behind the pixel's samples
  // scaled that channel by up to 1/albedo, and the filter spread it: saturated colours. The
  // denoised image must keep each channel's mean over the surface (the noisy image's, within
  // noise).
  struct Case {
    const char* name;
    glm::vec3 a, b;
  };
  for (const Case& c : {Case{"near-zero blue", {0.35f, 0.45f, 2.0f / 255.0f}, {0.05f, 0.25f, 0.2f / 255.0f}},
                        Case{"saturated", {0.9f, 0.02f, 0.01f}, {0.01f, 0.8f, 0.02f}}}) {
    const LoadedScene loaded = fine_checker_quad(c.a, c.b);
    const unsigned w = 48, h = 36, frames = 3;
    auto noisy = run_pipeline(loaded, 1, SeamMode::Halo, frames, w, h, 5, false);
    auto denoised = run_pipeline(loaded, 1, SeamMode::Halo, frames, w, h, 5, true);
    for (int e = 0; e < 2; ++e)
      for (int ch = 0; ch < 3; ++ch) {
        double before = 0.0, after = 0.0;
        const auto& n = noisy.frames.back()[e];
        const auto& d = denoised.frames.back()[e];
        for (std::size_t i = ch; i < n.rgb.size(); i += 3) {
          before += n.rgb[i];
          after += d.rgb[i];
        }
        EXPECT_NEAR(after / before, 1.0, 0.05) << c.name << ", eye " << e << ", channel " << ch << ": noisy mean "
                                               << before / (w * h) << ", denoised " << after / (w * h);
      }
  }
}

// Dynamic load balancing: strip boundaries that move every frame, by more rows than the
// G-buffer margin (so last frame's G-buffer of the rows taken over must travel too), must
// not change a bit of the image. History (colour, moments, history length) moves with its
// rows to the new owner.
std::vector<std::array<ImageRGB, 2>> run_with_strips(const LoadedScene& loaded, PipelineKind kind, int devices,
                                                     const std::vector<std::vector<RowRange>>& strips_per_frame,
                                                     unsigned w, unsigned h) {
  DeviceSet set = DeviceSet::create({devices, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  StereoPipeline::Options opt = pipeline_options(kind);
  opt.denoise->svgf.iterations = 2;  // G-buffer margin 18 rows: the moves below go past it
  StereoPipeline p(set, ds, loaded.scene, w, h, opt);
  std::vector<std::array<ImageRGB, 2>> frames;
  for (unsigned f = 0; f < strips_per_frame.size(); ++f) {
    if (!strips_per_frame[f].empty()) {
      p.set_strips(strips_per_frame[f]);
      EXPECT_EQ(p.strips(), strips_per_frame[f]);
    }
    p.render(f, 0.25f * f);
    frames.push_back(p.radiance());
  }
  return frames;
}

TEST(SvgfDistributed, StripsMovingEveryFrameKeepImagesBitIdentical) {
  const unsigned w = 40, h = 97;
  const std::vector<std::vector<RowRange>> two = {
      {{0, 48}, {48, 97}}, {{0, 20}, {20, 97}}, {{0, 75}, {75, 97}}, {{0, 74}, {74, 97}}, {{0, 3}, {3, 97}}};
  const std::vector<std::vector<RowRange>> three = {{{0, 32}, {32, 65}, {65, 97}},
                                                    {{0, 60}, {60, 70}, {70, 97}},
                                                    {{0, 5}, {5, 90}, {90, 97}},
                                                    {{0, 40}, {40, 41}, {41, 97}},
                                                    {{0, 41}, {41, 60}, {60, 97}}};
  const std::vector<std::vector<RowRange>> one_device(two.size());
  // Where the CPU has fewer compute units than devices (3 on a 2-core machine), the devices are
  // queues on one OpenCL device, and PoCL 3.1 aborts (pocl_release_dlhandle_cache) when such
  // queues launch one kernel at growing sizes, as growing strips do, unless PoclLaunchGuard
  // orders those launches (pocl_launch_guard.h). With the guard switched off
  // (PARALLAX_POCL_LAUNCH_GUARD=off) this test cannot run there.
  {
    const DeviceSet three = DeviceSet::create({3, DeviceMode::Auto, "", std::nullopt});
    if (three.mode() == DeviceMode::SharedQueues && !three.guards_launches() &&
        three.platform_name().find("Portable Computing Language") != std::string::npos)
      GTEST_SKIP()
          << "3 devices are PoCL queues on one device here and PARALLAX_POCL_LAUNCH_GUARD=off: PoCL 3.1 would abort";
  }
  for (PipelineKind kind : {PipelineKind::Proposed, PipelineKind::Mono}) {
    const auto reference = run_with_strips(cornell(), kind, 1, one_device, w, h);
    for (const auto* strips : {&two, &three}) {
      const int n = static_cast<int>(strips->front().size());
      const auto moved = run_with_strips(cornell(), kind, n, *strips, w, h);
      for (std::size_t f = 0; f < reference.size(); ++f)
        for (int e = 0; e < 2; ++e)
          EXPECT_TRUE(same_bits(reference[f][e], moved[f][e]))
              << to_string(kind) << ", " << n << " devices, frame " << f << ", eye " << e;
    }
  }
}

TEST(SvgfDistributed, StripsThatCannotMoveAreRefused) {
  const auto& scene = cornell();
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, scene.scene, scene.bvh);
  StereoPipeline::Options opt;
  StereoPipeline p(set, ds, scene.scene, 16, 20, opt);
  EXPECT_THROW(p.set_strips({{0, 10}}), std::invalid_argument);            // one strip for two devices
  EXPECT_THROW(p.set_strips({{0, 10}, {11, 20}}), std::invalid_argument);  // a gap
  EXPECT_THROW(p.set_strips({{0, 0}, {0, 20}}), std::invalid_argument);    // an empty strip
  EXPECT_THROW(p.set_strips({{0, 12}, {12, 21}}), std::invalid_argument);  // past the image
  EXPECT_EQ(p.strips(), (std::vector<RowRange>{{0, 10}, {10, 20}}));       // unchanged
  opt.pipeline = PipelineKind::Baseline;
  StereoPipeline baseline(set, ds, scene.scene, 16, 20, opt);
  EXPECT_THROW(baseline.set_strips({{0, 8}, {8, 20}}), std::invalid_argument);
}

// The a-trous step count is honoured: on the first frame (no history: the spatial filter alone)
// five steps come closer to a converged reference than one, by a wide margin (each step doubles
// the filter's reach: one leaves blotches), and the images differ. A denoiser that ran one step
// whatever was asked (or always five) gives the same error for both and fails.
// A still view at several spp: every sample goes along the G-buffer's ray (PX_GBUFFER_RAY_EVERY),
// so the denoised error falls with spp. With samples spread over the pixel, a pixel on the lamp's
// rim held lamp samples under a ceiling texel, which the filter darkened: the error rose with spp
// (docs/measurements.md, "Every sample along the G-buffer's ray"). Against render_reference,
// independent of the pipeline.
TEST(SvgfDistributed, AStillViewAtSeveralSppKeepsItsLightAndLosesError) {
  const unsigned w = 96, h = 72, frames = 8;
  static LoadedScene loaded = load_and_build("cornell", true);
  DeviceSet set = DeviceSet::create({2, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, loaded.scene, loaded.bvh);
  auto run = [&](unsigned spp) {
    StereoPipeline::Options opt = pipeline_options(PipelineKind::Proposed);
    opt.trace.spp = spp;
    StereoPipeline p(set, ds, loaded.scene, w, h, opt);
    for (unsigned f = 0; f + 1 < frames; ++f) p.render(f, 0.0f);  // the camera never moves
    p.render(frames - 1, 0.0f);
    return p.radiance();
  };
  const auto one = run(1), four = run(4), sixteen = run(16);
  PathTracer tracer(set, ds, loaded.scene);
  ReferenceOptions ref_opt;
  ref_opt.spp = 1024;
  ref_opt.bounces = 3;
  const auto reference = render_reference(tracer, 0.0f, frames - 1, w, h, ref_opt);
  for (int e = 0; e < 2; ++e) {
    SCOPED_TRACE(e == 0 ? "left eye" : "right eye");
    const double e1 = compare_images(one[e], reference[e]).rel_mse;
    const double e4 = compare_images(four[e], reference[e]).rel_mse;
    const double e16 = compare_images(sixteen[e], reference[e]).rel_mse;
    const double l1 = mean_luminance(one[e]) / mean_luminance(reference[e]);
    const double l4 = mean_luminance(four[e]) / mean_luminance(reference[e]);
    const double l16 = mean_luminance(sixteen[e]) / mean_luminance(reference[e]);
    std::printf("[ measure  ] eye %d: denoised relMSE 1 / 4 / 16 spp %.3g / %.3g / %.3g, light %.4f / %.4f / %.4f\n", e,
                e1, e4, e16, l1, l4, l16);
    // Spread samples measured 0.016 at 4 spp and 0.024 at 16 against 0.0047 at 1; now 0.0044 and
    // 0.0043. What light the lamp's rim still loses (1% here) is the anti-aliasing's clip, which
    // tightens as the frames get less noisy; the bound is issue 49's 2%.
    EXPECT_LT(e4, 0.95 * e1) << "more samples, more error";
    EXPECT_LT(e16, 1.05 * e4) << "more samples, more error";
    EXPECT_NEAR(l4, 1.0, 0.02);
    EXPECT_NEAR(l16, 1.0, 0.02);
  }
}

TEST(SvgfDistributed, FiveAtrousStepsFilterMoreThanOne) {
  const unsigned w = 96, h = 72;
  auto run = [&](unsigned iterations) { return run_pipeline(cornell(), 1, SeamMode::Halo, 1, w, h, iterations); };
  const DenoisedRun one = run(1), five = run(5);
  DeviceSet set = DeviceSet::create({1, DeviceMode::Auto, "", std::nullopt});
  DeviceScene ds(set, cornell().scene, cornell().bvh);
  PathTracer tracer(set, ds, cornell().scene);
  ReferenceOptions ref_opt;
  ref_opt.spp = 256;
  ref_opt.bounces = 3;
  const auto reference = render_reference(tracer, 0.0f, 0, w, h, ref_opt);
  for (int e = 0; e < 2; ++e) {
    // Below the emitter (the emitter's edge is the jitter's, not the filter's), relative error.
    const double e1 = compare_images(one.frames[0][e], reference[e], int(h) / 4).rel_mse;
    const double e5 = compare_images(five.frames[0][e], reference[e], int(h) / 4).rel_mse;
    std::printf("[ measure  ] eye %d: relMSE after 1 a-trous step %.3g, after 5 %.3g (x%.2f)\n", e, e1, e5, e5 / e1);
    EXPECT_LT(e5, 0.7 * e1) << "eye " << e;
    EXPECT_NE(one.frames[0][e].rgb, five.frames[0][e].rgb) << "eye " << e;
  }
}

}  // namespace
}  // namespace px

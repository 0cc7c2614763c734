/* SVGF's spatial passes (svgf_common.h): before each a-trous step its luminance guide
 * (svgf_luma); the step in three variants that give the same result, svgf_atrous (one pixel per
 * work-item), svgf_atrous_tiled (GPUs: taps from local memory) and svgf_atrous8 (CPUs: eight
 * pixels per work-item); and last svgf_remodulate, back from illumination to radiance. */
#include "denoise/svgf_common.h"

/* What the next a-trous step's luminance test compares, for rows [p.row0, p.row0 + p.rows): per
 * pixel, (luminance, variance) prefiltered over its 3x3 neighbourhood with the 3x3 Gaussian's
 * weights. The luminance of a filtered pixel is averaged with its neighbours' on the same
 * surface (filtered, normals and depths close: PX_SVGF_LUMA_*); any other pixel keeps its own.
 * The variance is averaged over the filtered neighbours (the pixel's own if there are none), as
 * the SVGF paper prefilters it.
 *
 * Why not the pixel's own luminance, as the paper compares: that makes the filter lose
 * energy. At 1 spp most samples are dark and a few bright; a tap's weight falls with its
 * luminance's distance from the centre's, so every dark centre turns the rare bright taps away,
 * while a bright centre, unlike any neighbour, keeps mostly itself. A weighted mean normalised
 * per centre then spreads less of each bright sample than it removes from it: on flat noise
 * with rare bright samples the filter lost energy, and atrium's denoised frame came out darker
 * than its own noisy input (docs/measurements.md, SVGF luminance guide).
 * Compared through a prefilter, a tap's weight hardly depends on its own sample (a ninth of
 * the average at most), so the weights stop sorting samples by brightness. Edges of light and
 * shadow still stop the filter, one pixel softer. The variance travels with it because the
 * test's scale is the pair's (see PX_ATROUS_TAP_SUM). */
kernel void svgf_luma(global float2* luma, const global float4* illum, const global float4* guide, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  const float4 gc = guide[i];
  const float4 c = illum[i];
  const int filtered = px_guide_filtered(gc);
  float lsum = 0.0f, lw = 0.0f, vsum = 0.0f, vw = 0.0f;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      const int tx = x + dx, ty = y + dy;
      if (!px_pixel_readable(tx, ty, &p)) continue;
      const uint j = (uint)ty * p.width + (uint)tx;
      const float4 g = guide[j];
      if (!px_guide_filtered(g)) continue;
      const float k = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
      const float4 t = illum[j];
      vsum += k * t.w;
      vw += k;
      if (filtered && dot(g.xyz, gc.xyz) >= PX_SVGF_LUMA_MIN_COS && fabs(g.w - gc.w) <= PX_SVGF_LUMA_REL_DEPTH * gc.w) {
        lsum += k * px_luminance(t.xyz);
        lw += k;
      }
    }
  /* A filtered centre always counts itself: lw >= 0.25. */
  luma[i] = (float2)(filtered ? lsum / lw : px_luminance(c.xyz), vw > 0.0f ? vsum / vw : c.w);
}

/* The centre of an a-trous tap sum at pixel i = (x, y): its edge-stopping geometry (its own, or a
 * borrowing pixel's lender's), prefiltered luminance and variance (svgf_luma). Returns 0 for a pixel the pass leaves as
 * it is (not filtered, and not borrowing), having written it to out_illum. */
inline int px_atrous_centre(global float4* out_illum, const global float4* illum, const global float4* guide,
                            const global float4* moments, const global float2* luma, int x, int y, const SvgfParams* p,
                            FilterCentre* fc, float* var) {
  const uint i = (uint)y * p->width + (uint)x;
  const float4 c = illum[i];
  int borrowed = -1;
  if (!px_guide_filtered(guide[i])) {
    if (moments[i].w == PX_SVGF_BORROWED) borrowed = px_borrowed_centre(guide, x, y, p);
    if (borrowed < 0) {
      out_illum[i] = c;
      return 0;
    }
  }
  *fc = px_filter_centre_at(guide, x, y, borrowed, c.xyz, p);
  /* The prefiltered luminance and variance (svgf_luma). */
  const float2 lv = luma[i];
  fc->l = lv.x;
  *var = fmax(0.0f, lv.y);
  return 1;
}

/* The luminance edge-stopping exponent between a centre (prefiltered luminance l, variance v)
 * and a tap's svgf_luma texel t: symmetric in the two. */
inline float px_luminance_term(float l, float v, float2 t, const SvgfParams* p) {
  return fabs(l - t.x) / (p->sigma_l * sqrt(0.5f * (v + fmax(0.0f, t.y))) + 1e-6f);
}

/* B3-spline a-trous weights of taps -2..2. */
__constant float px_atrous_h[5] = {1.0f / 16.0f, 1.0f / 4.0f, 3.0f / 8.0f, 1.0f / 4.0f, 1.0f / 16.0f};

/* The a-trous tap sum of pixel (x, y) (index i) around centre `fc`, written to out_illum[i]: the
 * body of svgf_atrous and svgf_atrous_tiled, which differ only in where a tap's texels come
 * from: GUIDE_AT(tx, ty), ILLUM_AT(tx, ty) and LUMA_AT(tx, ty) are the guide and illumination
 * texels and the prefiltered luminance (svgf_luma) of pixel (tx, ty), read only for taps inside
 * the image and the readable rows.
 *
 * The luminance test's scale is the pair's: sigma_l times the square root of the mean of the
 * centre's and the tap's prefiltered variances, so that a tap weighs on its centre as the
 * centre weighs on it. Scaled by the centre's variance alone, as in the SVGF paper, a bright
 * and noisy centre beside a dark and quiet one took in the dark tap more readily than the dark
 * one took in the bright: at every boundary of sunlight and shade, light flowed out and not
 * back in (docs/measurements.md, SVGF luminance guide).
 *
 * Every tap's weight twice: .x with the normal exponent sigma_n, .y with a loose one. A pixel
 * whose normal no neighbour shares closely — alpha-cut foliage cards, curved surfaces seen at
 * grazing angles, silhouettes — gets no weight from anyone under the strict test and keeps its
 * lone sample, at 1 spp often black. Such an isolated pixel takes the loose weights, which still
 * stop at creases, depth steps and luminance edges; every other pixel is filtered exactly as
 * before.
 *
 * The taps go in point-symmetric pairs, (kx, ky) with (-kx, -ky), and both take the lesser of
 * the pair's normal weights (PX_ATROUS_PAIRS) once the pixel has a history
 * (px_atrous_pair_share), where both lie inside the image and the readable rows. Where the kernel reaches a crease or a
 * depth step on one side only, the paper's filter keeps the other side's taps: a one-sided average, which moves light
 * along any gradient towards the edge. Every concave corner darkens towards its crease (the walls hide part of the sky
 * of lamps from each other), so every corner came out brighter than the reference, a band a few pixels wide along each
 * crease; on a many-lights scene that band was a third of the denoised error that remained (docs/measurements.md, SVGF
 * symmetric taps). A point-symmetric kernel passes a linear gradient unchanged, however much of it the creases cut
 * away. Only the normal weights pair: a crease rejects a tap outright, while the depth and luminance tests weigh taps
 * partly, and a pair at the lesser of two partial weights would give the far side of a depth step as much weight as the
 * near side (a blur). The image's own edges are not creases: a tap beyond them leaves its mirror as it is, so a pixel
 * near the border keeps the paper's one-sided kernel. */
/* How far a pixel's tap pairs go to the lesser weight, 0 (each tap its own weight, the paper's
 * filter) to 1, from its history length in frames (moments.z): 0 on a pixel's first frame,
 * full from 1 + PX_ATROUS_PAIR_FRAMES. The symmetric kernel trades noise for bias: near an edge
 * it averages fewer taps. Where the history is short the noise is what shows, and the paper's
 * wider one-sided kernel is the better choice; as the history grows the noise falls and the
 * bias is what remains. */
inline float px_atrous_pair_share(float history) {
  return clamp((history - 1.0f) * (1.0f / PX_ATROUS_PAIR_FRAMES), 0.0f, 1.0f);
}

/* One tap (KX, KY) of the a-trous sum at pixel (x, y): its normal weights N (strict, loose), the
 * rest of its weight R (the B3 spline's, the depth and the luminance tests'). The sum reads the
 * texel only where the weight is above 0 (fewer live registers on GPUs).
 * N is -1 outside the image or the readable rows (R 0 there): no tap, and none to pair with;
 * N is 0 on an unfiltered pixel other than the centre. */
#define PX_ATROUS_TAP(GUIDE_AT, LUMA_AT, KX, KY, N, R)                                                     \
  do {                                                                                                     \
    const int tx_ = x + (KX)*step_, ty_ = y + (KY)*step_;                                                  \
    N = (float2)(-1.0f, -1.0f);                                                                            \
    R = 0.0f;                                                                                              \
    if (ty_ >= 0 && ty_ < (int)p.height && px_row_readable(ty_, &p) && tx_ >= 0 && tx_ < (int)p.width) {   \
      const float4 g_ = GUIDE_AT(tx_, ty_);                                                                \
      N = (float2)(1.0f, 1.0f);                                                                            \
      R = px_atrous_h[(KX) + 2] * px_atrous_h[(KY) + 2];                                                   \
      if ((KX) != 0 || (KY) != 0) {                                                                        \
        if (px_guide_filtered(g_)) {                                                                       \
          N = px_normal_weights(dot(fc.n, g_.xyz), p.sigma_n, fmin(p.sigma_n, PX_SVGF_LOOSE_SIGMA_N));     \
          R *= px_exp(-(px_depth_term(g_.w, fc.z, fc.grad, (float)((KX)*step_), (float)((KY)*step_), &p) + \
                        px_luminance_term(fc.l, centre_var, LUMA_AT(tx_, ty_), &p)));                      \
        } else {                                                                                           \
          N = (float2)(0.0f, 0.0f);                                                                        \
        }                                                                                                  \
      }                                                                                                    \
    }                                                                                                      \
  } while (0)

#define PX_ATROUS_TAP_SUM(GUIDE_AT, ILLUM_AT, LUMA_AT)                                                 \
  do {                                                                                                 \
    const int step_ = (int)p.step;                                                                     \
    const float share_ = px_atrous_pair_share(moments[i].z);                                           \
    float2 wsum = (float2)(0.0f, 0.0f), vsum = (float2)(0.0f, 0.0f);                                   \
    float3 csum_strict = (float3)(0.0f, 0.0f, 0.0f), csum_loose = csum_strict;                         \
    for (int k = 0; k <= PX_ATROUS_PAIRS; ++k) {                                                       \
      const int kx = k % 5 - 2, ky = k / 5 - 2;                                                        \
      float2 n[2];                                                                                     \
      float r[2];                                                                                      \
      PX_ATROUS_TAP(GUIDE_AT, LUMA_AT, kx, ky, n[0], r[0]);                                            \
      if (k < PX_ATROUS_PAIRS) {                                                                       \
        PX_ATROUS_TAP(GUIDE_AT, LUMA_AT, -kx, -ky, n[1], r[1]);                                        \
        if (n[0].x >= 0.0f && n[1].x >= 0.0f) {                                                        \
          const float2 lesser = fmin(n[0], n[1]);                                                      \
          n[0] += share_ * (lesser - n[0]);                                                            \
          n[1] += share_ * (lesser - n[1]);                                                            \
        }                                                                                              \
      }                                                                                                \
      for (int s = 0; s < (k < PX_ATROUS_PAIRS ? 2 : 1); ++s) {                                        \
        const float2 w = fmax(n[s], 0.0f) * r[s];                                                      \
        if (w.x > 0.0f || w.y > 0.0f) { /* a tap: inside, filtered or the centre */                    \
          const float4 t = ILLUM_AT(x + (s == 0 ? kx : -kx) * step_, y + (s == 0 ? ky : -ky) * step_); \
          wsum += w;                                                                                   \
          vsum += w * w * t.w;                                                                         \
          csum_strict += w.x * t.xyz;                                                                  \
          csum_loose += w.y * t.xyz;                                                                   \
        }                                                                                              \
      }                                                                                                \
    }                                                                                                  \
    const float centre = px_atrous_h[2] * px_atrous_h[2];                                              \
    if (wsum.x - centre < PX_SVGF_ISOLATED * centre)                                                   \
      out_illum[i] = (float4)(csum_loose / wsum.y, vsum.y / (wsum.y * wsum.y));                        \
    else                                                                                               \
      out_illum[i] = (float4)(csum_strict / wsum.x, vsum.x / (wsum.x * wsum.x));                       \
  } while (0)

#define PX_GLOBAL_GUIDE(tx, ty) guide[(uint)(ty)*p.width + (uint)(tx)]
#define PX_GLOBAL_ILLUM(tx, ty) illum[(uint)(ty)*p.width + (uint)(tx)]
#define PX_GLOBAL_LUMA(tx, ty) luma[(uint)(ty)*p.width + (uint)(tx)]

kernel void svgf_atrous(global float4* out_illum, const global float4* illum, const global float4* guide,
                        const global float4* moments, const global float2* luma, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const int x = (int)(i % p.width), y = (int)(i / p.width);
  FilterCentre fc;
  float centre_var;
  if (!px_atrous_centre(out_illum, illum, guide, moments, luma, x, y, &p, &fc, &centre_var)) return;
  PX_ATROUS_TAP_SUM(PX_GLOBAL_GUIDE, PX_GLOBAL_ILLUM, PX_GLOBAL_LUMA);
}

/* The same a-trous step for GPUs, its taps read from local memory: a work-group filters a tile of
 * PX_ATROUS_TILE x PX_ATROUS_TILE pixels and first loads the guide, illumination and luminance
 * guide texels of the tile and its apron (2 x step pixels on each side) once, where
 * svgf_atrous's 25 taps per pixel each go to global memory (to the caches, at best). For steps up
 * to PX_ATROUS_TILE_MAX_STEP (1, 2 and 4: 144, 256 and 576 texels for 64 pixels, 22.5 KiB of
 * local memory at step 4); larger steps touch too few texels twice to gain, and run
 * svgf_atrous. The centre's work (borrowing) reads global memory as in svgf_atrous, and the tap sum is the same code
 * (PX_ATROUS_TAP_SUM). Items: PX_LOCAL_SIZE per tile, tiles row by row over the strip. */
#define PX_ATROUS_TILE_SPAN (PX_ATROUS_TILE + 4 * PX_ATROUS_TILE_MAX_STEP)
#if PX_ATROUS_TILE * PX_ATROUS_TILE != PX_LOCAL_SIZE
#error "svgf_atrous_tiled: a work-group is one tile"
#endif
__attribute__((reqd_work_group_size(PX_LOCAL_SIZE, 1, 1))) kernel void svgf_atrous_tiled(
    global float4* out_illum, const global float4* illum, const global float4* guide, const global float4* moments,
    const global float2* luma, SvgfParams p) {
  local float4 tile_guide[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  local float4 tile_illum[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  local float2 tile_luma[PX_ATROUS_TILE_SPAN * PX_ATROUS_TILE_SPAN];
  const uint tiles_x = (p.width + PX_ATROUS_TILE - 1u) / PX_ATROUS_TILE;
  const uint group = get_group_id(0), lid = get_local_id(0);
  const int apron = 2 * (int)min(p.step, (uint)PX_ATROUS_TILE_MAX_STEP), span = PX_ATROUS_TILE + 2 * apron;
  const int x0 = (int)((group % tiles_x) * PX_ATROUS_TILE), y0 = (int)(p.row0 + (group / tiles_x) * PX_ATROUS_TILE);
  const int ox = x0 - apron, oy = y0 - apron;
  /* Texels outside the image or the readable rows are not loaded: the tap sum skips them. */
  for (int k = (int)lid; k < span * span; k += PX_LOCAL_SIZE) {
    const int tx = ox + k % span, ty = oy + k / span;
    if (tx >= 0 && tx < (int)p.width && ty >= 0 && ty < (int)p.height && px_row_readable(ty, &p)) {
      tile_guide[k] = PX_GLOBAL_GUIDE(tx, ty);
      tile_illum[k] = PX_GLOBAL_ILLUM(tx, ty);
      tile_luma[k] = PX_GLOBAL_LUMA(tx, ty);
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int x = x0 + (int)(lid % PX_ATROUS_TILE), y = y0 + (int)(lid / PX_ATROUS_TILE);
  if (x >= (int)p.width || y >= (int)(p.row0 + p.rows) || p.step > PX_ATROUS_TILE_MAX_STEP) return;
  const uint i = (uint)y * p.width + (uint)x;
  FilterCentre fc;
  float centre_var;
  if (!px_atrous_centre(out_illum, illum, guide, moments, luma, x, y, &p, &fc, &centre_var)) return;
#define PX_TILE_GUIDE(tx, ty) tile_guide[((ty)-oy) * span + (tx)-ox]
#define PX_TILE_ILLUM(tx, ty) tile_illum[((ty)-oy) * span + (tx)-ox]
#define PX_TILE_LUMA(tx, ty) tile_luma[((ty)-oy) * span + (tx)-ox]
  PX_ATROUS_TAP_SUM(PX_TILE_GUIDE, PX_TILE_ILLUM, PX_TILE_LUMA);
#undef PX_TILE_GUIDE
#undef PX_TILE_ILLUM
#undef PX_TILE_LUMA
}

/* (c^e1, c^e2) for eight cosines at once (negative: 0), as px_normal_weights lane by lane. */
inline void px_normal_weights8(float8 c, float e1, float e2, float8* w1, float8* w2) {
  c = fmax(0.0f, c);
  if (px_integer_exponent(e1) && px_integer_exponent(e2)) {
    uint k1 = (uint)e1, k2 = (uint)e2;
    float8 a = (float8)(1.0f), b = (float8)(1.0f);
    while ((k1 | k2) != 0u) {
      if (k1 & 1u) a *= c;
      if (k2 & 1u) b *= c;
      c = select(c * c, (float8)(0.0f), c < 1e-10f);
      k1 >>= 1;
      k2 >>= 1;
    }
    *w1 = a;
    *w2 = b;
  } else {
    *w1 = pow(c, (float8)(e1));
    *w2 = pow(c, (float8)(e2));
  }
}

/* Eight consecutive float4 texels from `first` as four float8 planes (x, y, z, w). Loaded as
 * float8s, not float16s: PoCL's vload16 returns a float16, which an AVX2 CPU without AVX-512
 * passes in a way clang warns about at every build ("AVX vector return ... changes the ABI"). */
inline void px_load8_planes(const global float4* first, float8* x, float8* y, float8* z, float8* w) {
  const global float* f = (const global float*)first;
  const float8 a = vload8(0, f), b = vload8(1, f), c = vload8(2, f), d = vload8(3, f);
  *x = (float8)(a.s04, b.s04, c.s04, d.s04);
  *y = (float8)(a.s15, b.s15, c.s15, d.s15);
  *z = (float8)(a.s26, b.s26, c.s26, d.s26);
  *w = (float8)(a.s37, b.s37, c.s37, d.s37);
}

/* The same a-trous step for eight horizontally adjacent pixels per work-item, written for CPU
 * devices. PoCL runs each work-item of svgf_atrous as scalar code (its vectorizer gives up on
 * the tap loop), so a tap cost ~100 scalar instructions there. Here the lanes are explicit:
 * each tap's weights for the eight pixels are float8 arithmetic, one AVX register per quantity,
 * and the tap's eight texels are two 64-byte loads (and the luminance guide's one). The per-pixel
 * centre work (borrowing) stays scalar. Same filter, same operations per lane as svgf_atrous (test_svgf
 * checks both against the host implementation); a GPU, where each work-item is already a SIMD
 * lane, runs svgf_atrous. Items: rows x ceil(width / 8). */
#define PX_ATROUS_LANES 8
/* The centre of svgf_atrous8's eight pixels, lane by lane, and one tap's weights and texels. */
typedef struct Atrous8Centre {
  float8 nx, ny, nz, z, gx, gy, lum, var;
} Atrous8Centre;
typedef struct Atrous8Weights {
  float8 n1, n2, rest; /* normal weights (strict, loose; -1 outside), the rest of the weight */
} Atrous8Weights;

/* The weights of tap (kx, ky) of svgf_atrous8's eight pixels, as PX_ATROUS_TAP: normal weights
 * (-1 where the tap lies outside the image or the readable rows, 0 on an unfiltered pixel) and the
 * rest of the weight (0 in both cases). The texels are read by px_atrous8_texels once the pair's
 * weights are known (fewer live registers). */
__attribute__((always_inline)) inline Atrous8Weights px_atrous8_weights(const global float4* guide,
                                                                        const global float2* luma, const SvgfParams* p,
                                                                        const Atrous8Centre* ce, int x0, int y, int kx,
                                                                        int ky, int step) {
  Atrous8Weights out;
  const int ty = y + ky * step;
  if (ty < 0 || ty >= (int)p->height || !px_row_readable(ty, p)) {
    out.rest = (float8)(0.0f);
    out.n1 = out.n2 = (float8)(-1.0f);
    return out;
  }
  const uint row = (uint)ty * p->width;
  const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
  const int tx0 = x0 + kx * step;
  const int8 tx = (int8)(tx0) + lane;
  const int8 inside = tx >= 0 && tx < (int)p->width;
  float8 tnx, tny, tnz, tw, tl, tlv;
  if (tx0 >= 0 && tx0 + PX_ATROUS_LANES <= (int)p->width) {
    px_load8_planes(guide + row + (uint)tx0, &tnx, &tny, &tnz, &tw);
    const float8 l0 = vload8(0, (const global float*)(luma + row + (uint)tx0));
    const float8 l1 = vload8(1, (const global float*)(luma + row + (uint)tx0));
    tl = (float8)(l0.even, l1.even);
    tlv = (float8)(l0.odd, l1.odd);
  } else {
    /* At the image's left and right edges: lane by lane, clamped (outside lanes weigh 0). */
    float a[6][PX_ATROUS_LANES];
    for (int l = 0; l < PX_ATROUS_LANES; ++l) {
      const uint j = row + (uint)clamp(tx0 + l, 0, (int)p->width - 1);
      const float4 g = guide[j];
      a[0][l] = g.x;
      a[1][l] = g.y;
      a[2][l] = g.z;
      a[3][l] = g.w;
      const float2 lv = luma[j];
      a[4][l] = lv.x;
      a[5][l] = lv.y;
    }
    tnx = vload8(0, a[0]);
    tny = vload8(0, a[1]);
    tnz = vload8(0, a[2]);
    tw = vload8(0, a[3]);
    tl = vload8(0, a[4]);
    tlv = vload8(0, a[5]);
  }
  const float h = px_atrous_h[kx + 2] * px_atrous_h[ky + 2];
  float8 rest = (float8)(h), n1 = (float8)(1.0f), n2 = n1;
  int8 use = inside;
  if (kx != 0 || ky != 0) {
    /* Unfiltered pixels are never taps (the centre always is). Same terms as PX_ATROUS_TAP, in
     * the same order. */
    use = use && tw > 0.0f;
    const float8 extra = fabs(ce->lum - tl) / (p->sigma_l * sqrt(0.5f * (ce->var + fmax(tlv, 0.0f))) + 1e-6f);
    const float dx = (float)(kx * step), dy = (float)(ky * step);
    const float8 depth_term = fabs(ce->z - tw) / (p->sigma_z * fabs(ce->gx * dx + ce->gy * dy) + 1e-3f * ce->z + 1e-6f);
    rest *= px_exp8(-(depth_term + extra));
    px_normal_weights8(ce->nx * tnx + ce->ny * tny + ce->nz * tnz, p->sigma_n, fmin(p->sigma_n, PX_SVGF_LOOSE_SIGMA_N),
                       &n1, &n2);
  }
  const float8 none = select((float8)(-1.0f), (float8)(0.0f), inside);
  out.n1 = select(none, n1, use);
  out.n2 = select(none, n2, use);
  out.rest = select((float8)(0.0f), rest, use);
  return out;
}

/* The illumination texels of tap (kx, ky) of svgf_atrous8's eight pixels, in a readable row (the
 * caller's weights are 0 elsewhere), as four planes; lanes past the image's edges clamped. */
__attribute__((always_inline)) inline void px_atrous8_texels(const global float4* illum, const SvgfParams* p, int ty,
                                                             int tx0, float8* r, float8* g, float8* b, float8* v) {
  const uint row = (uint)ty * p->width;
  if (tx0 >= 0 && tx0 + PX_ATROUS_LANES <= (int)p->width) {
    px_load8_planes(illum + row + (uint)tx0, r, g, b, v);
    return;
  }
  float a[4][PX_ATROUS_LANES];
  for (int l = 0; l < PX_ATROUS_LANES; ++l) {
    const float4 t = illum[row + (uint)clamp(tx0 + l, 0, (int)p->width - 1)];
    a[0][l] = t.x;
    a[1][l] = t.y;
    a[2][l] = t.z;
    a[3][l] = t.w;
  }
  *r = vload8(0, a[0]);
  *g = vload8(0, a[1]);
  *b = vload8(0, a[2]);
  *v = vload8(0, a[3]);
}

kernel void svgf_atrous8(global float4* out_illum, const global float4* illum, const global float4* guide,
                         const global float4* moments, const global float2* luma, SvgfParams p) {
  const uint per_row = (p.width + PX_ATROUS_LANES - 1u) / PX_ATROUS_LANES;
  const uint gid = get_global_id(0);
  if (gid >= p.rows * per_row) return;
  const int y = (int)(p.row0 + gid / per_row);
  const int x0 = (int)(gid % per_row) * PX_ATROUS_LANES;
  /* The centres, lane by lane. A lane past the image's right edge or left unfiltered is off. */
  float cnx[PX_ATROUS_LANES], cny[PX_ATROUS_LANES], cnz[PX_ATROUS_LANES], cz[PX_ATROUS_LANES];
  float cgx[PX_ATROUS_LANES], cgy[PX_ATROUS_LANES], cl[PX_ATROUS_LANES], cvar[PX_ATROUS_LANES];
  float cshare[PX_ATROUS_LANES];
  int on[PX_ATROUS_LANES];
  int any_on = 0;
  for (int l = 0; l < PX_ATROUS_LANES; ++l) {
    FilterCentre fc;
    float var = 0.0f;
    on[l] = x0 + l < (int)p.width && px_atrous_centre(out_illum, illum, guide, moments, luma, x0 + l, y, &p, &fc, &var);
    if (!on[l]) fc = (FilterCentre){(float3)(0.0f, 0.0f, 1.0f), 1.0f, (float2)(0.0f, 0.0f), 0.0f};
    cnx[l] = fc.n.x;
    cny[l] = fc.n.y;
    cnz[l] = fc.n.z;
    cz[l] = fc.z;
    cgx[l] = fc.grad.x;
    cgy[l] = fc.grad.y;
    cl[l] = fc.l;
    cvar[l] = var;
    cshare[l] = on[l] ? px_atrous_pair_share(moments[(uint)y * p.width + (uint)(x0 + l)].z) : 0.0f;
    any_on |= on[l];
  }
  if (!any_on) return;
  const float8 nx = vload8(0, cnx), ny = vload8(0, cny), nz = vload8(0, cnz), z = vload8(0, cz);
  const float8 gx = vload8(0, cgx), gy = vload8(0, cgy), lum = vload8(0, cl), centre_var = vload8(0, cvar);
  const Atrous8Centre ce = {nx, ny, nz, z, gx, gy, lum, centre_var};
  const float8 share = vload8(0, cshare);
  const int step = (int)p.step;
  /* As svgf_atrous: .x strict, .y loose normal weights (the isolated-pixel fallback), and the
   * taps in point-symmetric pairs, each pair at the lesser of its two weights (the centre last). */
  float8 wsum_x = (float8)(0.0f), wsum_y = wsum_x, vsum_x = wsum_x, vsum_y = wsum_x;
  float8 cs_r = wsum_x, cs_g = wsum_x, cs_b = wsum_x, cl_r = wsum_x, cl_g = wsum_x, cl_b = wsum_x;
#define PX_ATROUS8_ADD(W, KX, KY)                                                          \
  do {                                                                                     \
    const float8 wx_ = fmax((W).n1, 0.0f) * (W).rest, wy_ = fmax((W).n2, 0.0f) * (W).rest; \
    if (any(wx_ > 0.0f || wy_ > 0.0f)) {                                                   \
      float8 r_, g_, b_, v_;                                                               \
      px_atrous8_texels(illum, &p, y + (KY)*step, x0 + (KX)*step, &r_, &g_, &b_, &v_);     \
      wsum_x += wx_;                                                                       \
      wsum_y += wy_;                                                                       \
      vsum_x += wx_ * wx_ * v_;                                                            \
      vsum_y += wy_ * wy_ * v_;                                                            \
      cs_r += wx_ * r_;                                                                    \
      cs_g += wx_ * g_;                                                                    \
      cs_b += wx_ * b_;                                                                    \
      cl_r += wy_ * r_;                                                                    \
      cl_g += wy_ * g_;                                                                    \
      cl_b += wy_ * b_;                                                                    \
    }                                                                                      \
  } while (0)
  for (int k = 0; k < PX_ATROUS_PAIRS; ++k) {
    const int kx = k % 5 - 2, ky = k / 5 - 2;
    Atrous8Weights ta = px_atrous8_weights(guide, luma, &p, &ce, x0, y, kx, ky, step);
    Atrous8Weights tb = px_atrous8_weights(guide, luma, &p, &ce, x0, y, -kx, -ky, step);
    /* Pairs whose taps both lie inside (PX_ATROUS_TAP_SUM). */
    const float8 f = select((float8)(0.0f), share, ta.n1 >= 0.0f && tb.n1 >= 0.0f);
    const float8 lesser1 = fmin(ta.n1, tb.n1), lesser2 = fmin(ta.n2, tb.n2);
    ta.n1 += f * (lesser1 - ta.n1);
    tb.n1 += f * (lesser1 - tb.n1);
    ta.n2 += f * (lesser2 - ta.n2);
    tb.n2 += f * (lesser2 - tb.n2);
    PX_ATROUS8_ADD(ta, kx, ky);
    PX_ATROUS8_ADD(tb, -kx, -ky);
  }
  const Atrous8Weights tc = px_atrous8_weights(guide, luma, &p, &ce, x0, y, 0, 0, step);
  PX_ATROUS8_ADD(tc, 0, 0);
#undef PX_ATROUS8_ADD
  const float centre = px_atrous_h[2] * px_atrous_h[2];
  float ws[PX_ATROUS_LANES], wl[PX_ATROUS_LANES], vs[PX_ATROUS_LANES], vl[PX_ATROUS_LANES];
  float sr[PX_ATROUS_LANES], sg[PX_ATROUS_LANES], sb[PX_ATROUS_LANES];
  float lr[PX_ATROUS_LANES], lg[PX_ATROUS_LANES], lb[PX_ATROUS_LANES];
  vstore8(wsum_x, 0, ws);
  vstore8(wsum_y, 0, wl);
  vstore8(vsum_x, 0, vs);
  vstore8(vsum_y, 0, vl);
  vstore8(cs_r, 0, sr);
  vstore8(cs_g, 0, sg);
  vstore8(cs_b, 0, sb);
  vstore8(cl_r, 0, lr);
  vstore8(cl_g, 0, lg);
  vstore8(cl_b, 0, lb);
  for (int l = 0; l < PX_ATROUS_LANES; ++l) {
    if (!on[l]) continue;
    const uint i = (uint)y * p.width + (uint)(x0 + l);
    if (ws[l] - centre < PX_SVGF_ISOLATED * centre)
      out_illum[i] = (float4)((float3)(lr[l], lg[l], lb[l]) / wl[l], vl[l] / (wl[l] * wl[l]));
    else
      out_illum[i] = (float4)((float3)(sr[l], sg[l], sb[l]) / ws[l], vs[l] / (ws[l] * ws[l]));
  }
}

/* Back from illumination to radiance: multiply the albedo that demodulation divided out, so
 * that an unfiltered pixel comes back exactly as it went in.
 * Unfiltered pixels (background, emitters) already hold their colour; borrowing ones
 * (PX_SVGF_BORROWED) take their own samples' albedo back, as filtered ones do. */
/* A borrowing pixel's centre sees the environment while all its n samples hit the surface: the
 * surface covers only part of it. If a straight edge crosses the pixel at a uniformly random
 * place, the coverage is uniform on [0, 1/2] given the centre outside, and all n samples land
 * inside with probability coverage^n: the expected coverage is (1/2)(n + 1)/(n + 2), 1/3 at
 * 1 spp. The filtered surface colour takes that share, the environment next to the pixel (its
 * environment 8-neighbours' accumulated colour) the rest. Given the whole pixel, the surface
 * grew a pixel of full surface colour wherever a sample crossed the silhouette. Reads rows
 * y - 1 .. y + 1 of illum, moments and guide, all exchanged after svgf_temporal (the
 * environment's colour does not change in the spatial passes). */
inline float3 px_borrowed_blend(float3 surface, float samples, const global float4* illum, const global float4* moments,
                                const global float4* guide, int x, int y, const SvgfParams* p) {
  float3 env = (float3)(0.0f, 0.0f, 0.0f);
  float count = 0.0f;
  for (int k = 0; k < 8; ++k) {
    const int j = px_neighbour8(x, y, k, p);
    /* the environment: not filtered, not borrowing, depth 0 (emitters have a depth) */
    if (j < 0 || moments[j].w != 0.0f || guide[j].w != 0.0f) continue;
    env += illum[j].xyz;
    count += 1.0f;
  }
  if (count == 0.0f) return surface;
  const float n = fmax(samples, 1.0f);
  return mix(env / count, surface, 0.5f * (n + 1.0f) / (n + 2.0f));
}

/* `out_color` holds the pixel's radiance (w: its finite sample count) and is overwritten. */
kernel void svgf_remodulate(global float4* out_color, const global float4* illum, const global float4* moments,
                            const global float4* albedo, const global float4* guide, SvgfParams p) {
  const uint gid = get_global_id(0);
  if (gid >= p.rows * p.width) return;
  const uint i = p.row0 * p.width + gid;
  const float4 c = illum[i];
  const float m = moments[i].w;
  if (m == 0.0f) {
    out_color[i] = (float4)(c.xyz, 1.0f);
    return;
  }
  float3 radiance = c.xyz * px_demod_albedo(albedo, i);
  if (m == PX_SVGF_BORROWED)
    radiance =
        px_borrowed_blend(radiance, out_color[i].w, illum, moments, guide, (int)(i % p.width), (int)(i / p.width), &p);
  out_color[i] = (float4)(radiance, 1.0f);
}

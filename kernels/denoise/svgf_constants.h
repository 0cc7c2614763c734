/* The SVGF denoiser's tuning constants (kernels/denoise/svgf_*.cl, seam_bilateral.cl), shared
 * with its host side (host/pipeline/stages: the launch sizes and the rows a pass reads), which
 * includes this header as it includes shared/types.h. Plain macros: C++ and OpenCL C alike. */
#ifndef PARALLAX_SVGF_CONSTANTS_H
#define PARALLAX_SVGF_CONSTANTS_H

/* svgf_atrous_tiled (kernels/denoise/svgf_atrous.cl): a work-group filters a PX_ATROUS_TILE-square
 * tile of pixels, for a-trous steps up to PX_ATROUS_TILE_MAX_STEP (the host launches it only
 * for those, PX_LOCAL_SIZE items per tile). */
#define PX_ATROUS_TILE 8
#define PX_ATROUS_TILE_MAX_STEP 4
/* The a-trous 5 x 5 taps less the centre, in point-symmetric pairs: pair k (0 .. 11) is tap
 * (k % 5 - 2, k / 5 - 2) with its mirror image through the centre, and both take the lesser of
 * their normal weights; k = 12 is the centre alone (kernels/denoise/svgf_atrous.cl,
 * PX_ATROUS_TAP_SUM). */
#define PX_ATROUS_PAIRS 12
/* Frames of history over which a pixel's pairs go from their own weights to the lesser one
 * (px_atrous_pair_share). */
#define PX_ATROUS_PAIR_FRAMES 4.0f

/* SVGF: a pixel is isolated when its neighbours' total weight under the normal exponent
 * sigma_n is below PX_SVGF_ISOLATED x its own; it is then filtered with the normal exponent
 * PX_SVGF_LOOSE_SIGMA_N instead (the stereo paper's sigma_n). */
#define PX_SVGF_ISOLATED 0.25f
#define PX_SVGF_LOOSE_SIGMA_N 4.0f
/* SVGF's luminance guide (svgf_luma): a pixel's luminance is averaged with those of its 3x3
 * neighbours on the same surface, told by normals within PX_SVGF_LUMA_MIN_COS and depths within
 * PX_SVGF_LUMA_REL_DEPTH x the pixel's. */
#define PX_SVGF_LUMA_MIN_COS 0.9f
#define PX_SVGF_LUMA_REL_DEPTH 0.1f
/* SVGF moments.w: how the filter treats a pixel. 0: not filtered (environment, emitters),
 * 1: filtered, PX_SVGF_BORROWED: a silhouette pixel whose centre ray misses every filtered
 * surface while all its own samples hit one (albedo.w, the share of such samples, at least
 * PX_SVGF_BORROW_COVERAGE: n * (1 / n) may round just below 1). It is filtered as a receiver
 * only, with the normal and depth of its nearest filtered 8-neighbour, and never serves as a
 * tap or as history: passed through, its lone surface sample (at 1 spp often black) stood out
 * along every silhouette against the sky. A pixel with samples on both sides keeps passing
 * through: its mean already mixes them, and filtering it as surface dimmed the edges of
 * cornell's light (docs/measurements.md, SVGF borrowing pixels). */
#define PX_SVGF_BORROWED 2.0f
#define PX_SVGF_BORROW_COVERAGE 0.999f
/* SVGF's history beside a moving object (svgf_temporal): a still surface within
 * PX_SVGF_NEAR_MOTION_REACH pixels (rows and columns) of a point whose object moved blends its
 * history with at least PX_SVGF_NEAR_MOTION_ALPHA, since the object's contact shadow and its
 * light reflected onto it move with the object. The motion pass covers that many rows beyond
 * the strip. */
#define PX_SVGF_NEAR_MOTION_REACH 4
#define PX_SVGF_NEAR_MOTION_ALPHA 0.5f
/* Temporal anti-aliasing (svgf_antialias): the history is clipped to the neighbourhood's mean
 * +- PX_TAA_CLIP_SIGMA standard deviations, and a pixel that moved by d pixels blends the current
 * frame in with at least min(PX_TAA_MOTION_ALPHA_MAX, PX_TAA_MOTION_ALPHA x d). */
#define PX_TAA_CLIP_SIGMA 1.25f
#define PX_TAA_MOTION_ALPHA 1.0f
#define PX_TAA_MOTION_ALPHA_MAX 0.5f

/* Temporal gradients (A-SVGF; denoise/temporal_gradient.cl): the image is cut into strata of
 * PX_GRADIENT_STRATUM x PX_GRADIENT_STRATUM pixels; each frame one pixel per stratum is shaded a
 * second time (its surface point, this frame's scene) with the random numbers it had, and the
 * change becomes the stratum's gradient. PX_GRADIENT_STEPS a-trous steps (spacing 1, 2, 4
 * strata, 3x3 taps) spread it, so a stratum reads PX_GRADIENT_REACH strata each way; what is
 * shaded reaches one stratum farther than the strip, PX_GRADIENT_ROWS rows each way in all.
 * PX_GRADIENT_SAMPLE: the sample index of the re-shaded paths' stream, far above any sample a
 * pixel traces for the image (spp <= 2^20, plus its motion-edge samples). */
#define PX_GRADIENT_STRATUM 3
#define PX_GRADIENT_STEPS 3
#define PX_GRADIENT_REACH 7
#define PX_GRADIENT_ROWS (PX_GRADIENT_STRATUM * (PX_GRADIENT_REACH + 1))
#define PX_GRADIENT_SAMPLE 0xFFFFFF00u
/* The gradient filter's edge stopping between two strata (their centre pixels' G-buffer texels):
 * normals as cos^PX_GRADIENT_SIGMA_N, depths within PX_GRADIENT_REL_DEPTH x the nearer one. */
#define PX_GRADIENT_SIGMA_N 32.0f
#define PX_GRADIENT_REL_DEPTH 0.1f
/* The history follows the light's change by the ratio of the strata's shades (now / last frame)
 * where both sums are at least PX_GRADIENT_MIN_SHADE of the larger shades' and the ratio lies
 * within [PX_GRADIENT_MIN_RATIO, 1 / PX_GRADIENT_MIN_RATIO]. The anti-aliasing, whose history is
 * twice as long (alpha 0.1 against 0.2), drops PX_GRADIENT_TAA_GAIN x lambda of it. The values
 * were chosen on the moving-panel scene (docs/measurements.md, Temporal gradients). */
/* The re-shaded paths' bounces at most (the image's own at most): the change of the light a surface
 * sees shows in its first bounces, at a fraction of a full path's cost. */
#define PX_GRADIENT_MAX_BOUNCES 1
#define PX_GRADIENT_MIN_SHADE 0.1f
#define PX_GRADIENT_MIN_RATIO 0.5f
#define PX_GRADIENT_TAA_GAIN 2.0f

#endif /* PARALLAX_SVGF_CONSTANTS_H */

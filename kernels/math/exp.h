/* e^x in plain float arithmetic, for the per-tap weights of the SVGF filters.
 *
 * Why not the built-in exp: on PoCL's CPU devices it is a long dependent chain of scalar
 * operations with its own range handling, and the filters evaluate it for each of 25 taps per
 * pixel and pass; this version makes the a-trous pass markedly cheaper there
 * (docs/measurements.md, "Denoiser: cost on a CPU"). On GPUs both are a handful of instructions.
 *
 * Method: e^x = 2^n e^r with n = round(x / ln 2) and r = x - n ln 2, where ln 2 is split into
 * a high part with 11 significant bits (n times it is exact in float, Cody and Waite) and a low
 * part, so that r is accurate. |r| <= ln(2)/2, where the degree-6 Taylor polynomial's
 * truncation error is below 2e-7 relative; it is evaluated in Estrin's form (three short
 * dependent chains instead of one long one). 2^n is built from its exponent bits. No branches:
 * a kernel calling it stays free of data-dependent control flow.
 *
 * Accuracy (test_svgf checks it against double-precision exp): within 4e-7 relative for x in
 * [-87, 88]. Below -87 it returns 0 (the exact value is < 2e-38, a weight that cannot change any
 * sum it joins); above 88, +inf; NaN stays NaN. */
#ifndef PX_MATH_EXP_H
#define PX_MATH_EXP_H

/* One body for float (px_exp) and float8 (px_exp8, eight filter taps at once on CPUs): the same
 * operations lane by lane. SFX is the vector width's suffix of convert_int / as_float. */
#define PX_DEFINE_EXP(NAME, F, I, SFX)                                                     \
  inline F NAME(F x) {                                                                     \
    const F xc = fmin(fmax(x, -87.0f), 88.0f);                                             \
    const F t = xc * 1.44269504f; /* log2(e) */                                            \
    /* round to nearest; in [-126, 127] */                                                 \
    const I ni = convert_int##SFX(t + select((F)(0.5f), (F)(-0.5f), t < 0.0f));            \
    const F n = convert_float##SFX(ni);                                                    \
    const F r = (xc - n * 0.693145751953125f) - n * 1.428606765330187e-6f;                 \
    const F r2 = r * r;                                                                    \
    const F p = ((1.0f + r) + r2 * (0.5f + r * (1.0f / 6.0f))) +                           \
                (r2 * r2) * ((1.0f / 24.0f + r * (1.0f / 120.0f)) + r2 * (1.0f / 720.0f)); \
    F e = p * as_float##SFX((ni + 127) << 23);                                             \
    e = select(e, (F)(0.0f), x < -87.0f);                                                  \
    e = select(e, (F)(INFINITY), x > 88.0f);                                               \
    return select(e, x, x != x);                                                           \
  }

PX_DEFINE_EXP(px_exp, float, int, )
PX_DEFINE_EXP(px_exp8, float8, int8, 8)

#endif

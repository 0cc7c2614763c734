/* ReSTIR DI's launch constants and bounds (restir/restir_di.cl), shared with its host side
 * (host/pipeline/stages/direct_light_stage.*), which includes this header as it includes
 * shared/types.h. */
#ifndef PARALLAX_RESTIR_PARAMS_H
#define PARALLAX_RESTIR_PARAMS_H

#include "shared/types.h"

#ifndef __OPENCL_C_VERSION__
namespace px {
#endif

/* ReSTIR DI launch constants (restir/restir_di.cl), 64 bytes, passed by value to both passes.
 *
 *   0..3 width  4..7 height  8..11 row0  12..15 rows (rows a row launch covers; a list launch
 *  ignores them)  16..19 lo_row  20..23 hi_row (rows whose reservoirs the pass may read: the
 *  strip and the margin this device computed, or fetched last frame's)  24..27 candidates
 *  28..31 neighbours  32..35 radius (spatial reuse, pixels)  36..39 temporal (0/1)
 *  40..43 max_history (cap of a reused reservoir's confidence M, in units of candidates)
 *  44..47 tag (this frame's reservoirs: frame + 1)  48..51 prev_tag (last frame's)
 *  52..55 temporal_rows (largest vertical offset of last frame's pixel)  56..63 padding */
typedef struct RestirParams {
  uint width;
  uint height;
  uint row0;
  uint rows;
  uint lo_row;
  uint hi_row;
  uint candidates;
  uint neighbours;
  uint radius;
  uint temporal;
  float max_history;
  uint tag;
  uint prev_tag;
  uint temporal_rows;
  uint pad[2];
} RestirParams;

/* Bounds of ReSTIR DI's private arrays and loops (RestirParams::candidates, ::neighbours). */
#define PX_RESTIR_MAX_CANDIDATES 64u
#define PX_RESTIR_MAX_NEIGHBOURS 4u
/* A reservoir is reused only between surfaces whose shading normals are within ~25 degrees and
 * whose planes are within 5% of the viewing distance: reuse across an edge would be unbiased too
 * (the weights see to that) but brings samples that mostly miss. */
#define PX_RESTIR_MIN_NORMAL_COS 0.9f
#define PX_RESTIR_MAX_PLANE_DISTANCE 0.05f

#ifndef __OPENCL_C_VERSION__
} /* namespace px */
#endif

#endif

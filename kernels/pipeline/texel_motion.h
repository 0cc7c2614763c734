/* Whether a G-buffer texel's surface moved since the last frame, for the passes that treat
 * moving objects apart (the motion pass, the extra samples at moving edges, the denoiser's
 * anti-aliasing on last frame's texels). */
#ifndef PARALLAX_TEXEL_MOTION_H
#define PARALLAX_TEXEL_MOTION_H

#include "shared/types.h"

/* Scene triangle g->prim moved (tri_motion: per triangle its vertices now, 0..2, and in the
 * previous frame, 3..5; DeviceSceneBuffers::motion), or the instance g->inst whose mesh holds it
 * (its matrix changed). A miss or a texel without a hit did not. */
inline int px_texel_moved(const global float4* tri_motion, const global SceneInstances* instances,
                          const global GBufferTexel* g) {
  if (g->material_class == PX_CLASS_MISS || g->prim == PX_NO_HIT) return 0;
  if (instances && g->inst != PX_NO_INSTANCE && g->inst < instances->count) {
    const global SceneInstance* in =
        (const global SceneInstance*)((const global uchar*)instances + 16 * (size_t)instances->records) + g->inst;
    for (int k = 0; k < 12; ++k)
      if (in->object_to_world[k] != in->previous_object_to_world[k]) return 1;
    return 0;
  }
  const global float4* v = tri_motion + 6 * (size_t)g->prim;
  return any(v[0] != v[3]) || any(v[1] != v[4]) || any(v[2] != v[5]);
}

#endif

/* Primary rays of one eye's pinhole camera (layout and conventions: CameraParams in
 * shared/types.h). (jx, jy) in [0,1)^2 is the position inside the pixel; 0.5 is the centre. */
#ifndef PARALLAX_CAMERA_H
#define PARALLAX_CAMERA_H

#include "shared/types.h"

inline float3 px_camera_dir(const CameraParams* cam, uint x, uint y, float jx, float jy) {
  const float sx = (((float)x + jx) / (float)cam->width * 2.0f - 1.0f) * cam->tan_half_fov_y * cam->aspect;
  const float sy = (1.0f - ((float)y + jy) / (float)cam->height * 2.0f) * cam->tan_half_fov_y;
  const float3 f = (float3)(cam->forward[0], cam->forward[1], cam->forward[2]);
  const float3 r = (float3)(cam->right[0], cam->right[1], cam->right[2]);
  const float3 u = (float3)(cam->up[0], cam->up[1], cam->up[2]);
  return normalize(f + sx * r + sy * u);
}

inline float3 px_camera_origin(const CameraParams* cam) {
  return (float3)(cam->origin[0], cam->origin[1], cam->origin[2]);
}

#endif

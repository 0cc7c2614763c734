// refit_bvh(): an animated scene's tree refitted to its moved triangles (bvh_refit.cpp).
#pragma once

#include "bvh/flat_bvh.h"
#include "scene/scene.h"

#include <vector>

namespace px {

// Refits `bvh` to `triangles` moved since it was built (same triangles, same order: an animated
// scene posed anew): the leaf triangles take their new vertices, every binary node's child
// boxes are recomputed bottom-up, the wide nodes are dropped (ensure_layout collapses them
// again) and the stats recomputed (a refit tree's SAH cost grows as the pose departs from the
// one it was built for: the caller rebuilds when it has grown too much). The tree must hold
// every scene triangle once (built without spatial splits, whose leaves hold clipped parts):
// throws std::invalid_argument otherwise. Returns the time taken in ms.
double refit_bvh(FlatBvh& bvh, const std::vector<SceneTriangle>& triangles);

}  // namespace px

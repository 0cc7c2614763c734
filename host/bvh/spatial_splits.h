// The spatial-split callback of build_bvh's Embree builds (spatial_splits.cpp).
#pragma once

#include <embree3/rtcore.h>  // before rtcore_builder.h, which does not stand alone
#include <embree3/rtcore_builder.h>

namespace px::embree_build {

// Spatial splits. Embree asks: the part of primitive `prim` inside its current box (a fragment
// of one triangle, possibly already split several times), cut by the plane x[dim] = pos — what
// are the boxes of the two pieces? We answer exactly: clip the triangle to the fragment's box
// (a convex polygon), cut the polygon at the plane and take each side's bounds. Embree's own
// triangle splitter cuts the unclipped triangle and intersects with the box, which can leave a
// box larger than the fragment; exact boxes are tighter and so give lower SAH.
// RTCBuildArguments::splitPrimitive; `user` is the build's BuildContext (embree_build_tree.h).
// Counts its calls against BuildContext::split_budget and, once over it, cancels the build by
// throwing (rtcBuildBVH reports an error; BuildContext::over_budget tells why).
void split_primitive(const RTCBuildPrimitive* primitive, unsigned int dim, float pos, RTCBounds* left, RTCBounds* right,
                     void* user);

}  // namespace px::embree_build

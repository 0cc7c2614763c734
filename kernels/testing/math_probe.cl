/* Exposes the kernels' own math routines to the test suite, which checks them against the
 * host's double-precision library. */
#include "math/exp.h"

kernel void probe_exp(global float* out, const global float* in, uint n) {
  const uint i = get_global_id(0);
  if (i < n) out[i] = px_exp(in[i]);
}

/* px_exp8 on eight values per work-item (n a multiple of 8). */
kernel void probe_exp8(global float* out, const global float* in, uint n) {
  const uint i = get_global_id(0);
  if (8u * i + 7u < n) vstore8(px_exp8(vload8(i, in)), i, out);
}

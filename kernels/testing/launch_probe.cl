/* Kernels for the launch-order tests (tests/test_launch_guard.cpp): each work-item spends a
 * while on an integer recurrence (so that launches on several queues overlap) and writes its
 * value, which the host recomputes. Two kernels of one body: PoCL keeps its work-group functions
 * per kernel, so each test meets a kernel that is new to the process. */
uint px_probe_busy(uint s, uint steps) {
  for (uint j = 0; j < steps; ++j) s = s * 1664525u + 1013904223u;
  return s;
}

kernel void probe_busy(global uint* out, uint offset, uint n, uint steps) {
  const uint i = get_global_id(0);
  if (i < n) out[offset + i] = px_probe_busy(offset + i, steps);
}

kernel void probe_busy_strips(global uint* out, uint offset, uint n, uint steps) {
  const uint i = get_global_id(0);
  if (i < n) out[offset + i] = px_probe_busy(offset + i, steps);
}

/* The frame's kernel files built for the scene's features (DeviceScene::kernel_options), as one
 * program: the path tracer, the G-buffer pass and the temporal gradients' shading share most of
 * their code, which one program parses and links once (DeviceSet::program serves the three files
 * from it; see pipeline/frame_kernels.cl for why fewer builds matter). */
#include "pathtrace/path_trace.cl"
#include "pipeline/gbuffer.cl"
#include "denoise/temporal_gradient.cl"

/* The frame's kernels that take no scene options (reprojection, the denoiser, tonemapping), as
 * one program: PoCL builds a program (its front end, then a link with its built-in library) under
 * a lock it also holds to make each kernel's work-group function, so a first run that built these
 * nine files one by one waited on each build in turn (DeviceSet::program serves every file below
 * from this one). Each file is included once; none defines a name another does. */
#include "pipeline/reproject.cl"
#include "pipeline/tonemap.cl"
#include "pipeline/motion.cl"
#include "pipeline/motion_edges.cl"
#include "denoise/svgf_temporal.cl"
#include "denoise/svgf_atrous.cl"
#include "denoise/svgf_antialias.cl"
#include "denoise/gradient_filter.cl"
#include "denoise/seam_bilateral.cl"

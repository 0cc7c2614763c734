#include "render/preview_renderer.h"

#include "cl/launch.h"

namespace px {

std::array<ImageRGB, 2> PreviewRenderer::render(const Scene& scene, float time_s, unsigned width, unsigned height) {
  const Camera centre = evaluate_camera(scene, time_s);
  std::array<ImageRGB, 2> images;
  const int n = devices_.size();
  std::vector<cl::Buffer> keep;  // outputs stay alive until every queue finished
  for (int e = 0; e < 2; ++e) {
    const Eye eye = static_cast<Eye>(e);
    const CameraParams cam = make_eye_camera(centre, eye, scene.ipd_units(), width, height);
    ImageRGB& img = images[e];
    img.width = static_cast<int>(width);
    img.height = static_cast<int>(height);
    img.rgb.assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
    for (int d = 0; d < n; ++d) {
      const unsigned row0 = height * d / n, row1 = height * (d + 1) / n;
      if (row1 == row0) continue;
      auto& dev = devices_.devices()[d];
      const std::size_t pixels = static_cast<std::size_t>(row1 - row0) * width;
      cl::Buffer out(devices_.context(), CL_MEM_WRITE_ONLY, pixels * 3 * sizeof(float));
      const auto& b = scene_.on(d);
      cl::Kernel k(devices_.program("render/primary_preview.cl", scene_.kernel_options()), "primary_preview");
      k.setArg(0, out);
      k.setArg(1, static_cast<cl_uint>(row0));
      k.setArg(2, static_cast<cl_uint>(row1 - row0));
      k.setArg(3, cam);
      b.bind(k, 4);
      launch_1d(dev.queue, k, pixels);
      dev.queue.enqueueReadBuffer(out, CL_FALSE, 0, pixels * 3 * sizeof(float),
                                  img.rgb.data() + static_cast<std::size_t>(row0) * width * 3);
      keep.push_back(out);
    }
  }
  devices_.finish_all();
  return images;
}

}  // namespace px

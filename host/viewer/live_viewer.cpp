#include "viewer/live_viewer.h"

#include "app/cli_enums.h"
#include "app/commands.h"
#include "app/frame_loop.h"
#include "app/render_setup.h"
#include "image/image_io.h"
#include "io/interrupt.h"
#include "render/fly_camera.h"
#include "render/scene_animator.h"
#include "render/stereo_camera.h"

// libepoxy resolves the GL entry points (buffer objects, framebuffer blits) at run time; it
// must come before GLFW so that GLFW includes no GL header of its own.
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace px {

namespace {

using clock_type = std::chrono::steady_clock;

double seconds_between(clock_type::time_point a, clock_type::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// What the render thread hands to the window after each frame.
struct FrameInfo {
  unsigned index = 0;    // frame number (0-based)
  double wall_ms = 0.0;  // the frame's host time, first enqueue to last command
  double hz = 0.0;       // frames finished per second, smoothed
  unsigned spp = 0, bounces = 0;
  std::string slowest;  // "path trace left 12.3 ms"
  Camera camera;        // the centre camera it was rendered with
};

// Everything the two threads share, under one mutex.
struct Shared {
  std::mutex mutex;
  // window -> render thread
  bool quit = false;
  bool flying = false;  // steering: render with fly_camera instead of the camera path
  Camera fly_camera;
  // render thread -> window
  std::vector<std::uint8_t> left, right;  // the newest finished eyes (RGBA8, rows top down)
  bool fresh = false;                     // not yet uploaded
  FrameInfo info;
  bool have_info = false;
  bool finished = false;  // the render thread has stopped (frame limit or error)
  std::exception_ptr error;
};

// The render thread: frame after frame until told to quit or --frames are done.
void render_loop(const ViewCommand& cmd, RenderSession& session, SceneAnimator& animator,
                 std::optional<FrameTimeController>& controller, Shared& shared) {
  StereoPipeline& pipeline = session.pipeline;
  const Scene& scene = session.loaded.scene;
  const float duration = camera_path_duration(scene);
  const bool scripted = cmd.frames > 0;  // --frames: frame f on `render`'s clock (f / fps)
  const FrameClock& frame_clock = cmd.render.clock;
  double path_time = 0.0;  // interactive: seconds of camera path played so far
  double hz = 0.0;
  auto last_done = clock_type::now();
  try {
    for (unsigned f = 0; !scripted || f < cmd.frames; ++f) {
      bool flying;
      Camera fly;
      {
        std::lock_guard lock(shared.mutex);
        if (shared.quit) break;
        flying = shared.flying;
        fly = shared.fly_camera;
      }
      const float t = scripted ? frame_clock.camera_time_s(f)
                               : (duration > 0.0f ? static_cast<float>(std::fmod(path_time, double(duration))) : 0.0f);
      // The animation plays on the same clock, unbounded (each clip loops over its own length).
      animator.update(scripted ? frame_clock.time_s(f) : path_time, session.devices, session.device_scene);
      const Camera camera = flying ? fly : evaluate_camera(scene, t);
      const FrameQuality quality = pipeline.quality();
      // The cache files the next start reads are written beside the first frame (scene_setup.h).
      if (f == 0) session.first_frame_on_its_way();
      const FrameStats st = pipeline.render(f, camera);
      // Frame 0 compiles the kernels (seconds on PoCL): it says nothing about the frame time.
      if (controller && f > 0) pipeline.set_quality(controller->update(quality, StereoPipeline::frame_cost(st)));
      auto eyes = pipeline.rgba8();
      const auto now = clock_type::now();
      const double interval = seconds_between(last_done, now);
      last_done = now;
      if (f == 1)
        hz = 1.0 / interval;
      else if (f > 1)
        hz = 0.8 * hz + 0.2 / interval;
      // The path plays in real time while not steered; the first frame's kernel compilation
      // and any long stall move it by at most a quarter second.
      if (!flying) path_time += std::min(interval, 0.25);
      FrameInfo info;
      info.index = f;
      info.wall_ms = st.wall_ms;
      info.hz = hz;
      info.spp = quality.spp;
      info.bounces = quality.bounces;
      if (const auto slow = slowest_stage(st)) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%s %.1f ms", stage_name(slow->first), slow->second);
        info.slowest = buf;
      }
      info.camera = camera;
      std::lock_guard lock(shared.mutex);
      shared.left.swap(eyes[0]);
      shared.right.swap(eyes[1]);
      shared.fresh = true;
      shared.info = std::move(info);
      shared.have_info = true;
    }
  } catch (...) {
    std::lock_guard lock(shared.mutex);
    shared.error = std::current_exception();
  }
  std::lock_guard lock(shared.mutex);
  shared.finished = true;
}

// GLFW's last error message, for the exceptions below.
std::string& glfw_error_text() {
  static std::string text;
  return text;
}

void on_glfw_error(int code, const char* description) {
  glfw_error_text() = description ? description : ("GLFW error " + std::to_string(code));
}

// Terminates GLFW (and with it any window) however run_view leaves.
struct GlfwSession {
  GlfwSession() {
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit()) {
      const char* display = std::getenv("DISPLAY");
      const char* wayland = std::getenv("WAYLAND_DISPLAY");
      throw std::runtime_error(
          "view: cannot open a window (" + glfw_error_text() + ")" +
          ((!display || !*display) && (!wayland || !*wayland)
               ? ": no display (DISPLAY and WAYLAND_DISPLAY are unset). Run it on a desktop, or under a virtual "
                 "X server: xvfb-run -a parallax view ... (Debian package xvfb)"
               : ""));
    }
  }
  ~GlfwSession() { glfwTerminate(); }
  GlfwSession(const GlfwSession&) = delete;
  GlfwSession& operator=(const GlfwSession&) = delete;
};

// The stereo image on the GPU: one RGBA8 texture of 2w x h (left eye in the left half), filled
// from two pixel buffer objects in turn, shown with a framebuffer blit.
class StereoSurface {
 public:
  StereoSurface(unsigned width, unsigned height) : width_(width), height_(height) {
    glGenTextures(1, &texture_);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 2 * width, height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    glGenBuffers(2, pbo_);
    glGenFramebuffers(1, &fbo_);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture_, 0);
    if (glCheckFramebufferStatus(GL_READ_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("view: the OpenGL driver cannot read from an RGBA8 texture framebuffer");
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  }
  ~StereoSurface() {
    glDeleteFramebuffers(1, &fbo_);
    glDeleteBuffers(2, pbo_);
    glDeleteTextures(1, &texture_);
  }
  StereoSurface(const StereoSurface&) = delete;
  StereoSurface& operator=(const StereoSurface&) = delete;

  // Copies both eyes into the next PBO (orphaned first, so the driver never waits for the
  // previous upload) and has the GL copy it into the texture from there asynchronously.
  void upload(const std::vector<std::uint8_t>& left, const std::vector<std::uint8_t>& right) {
    const std::size_t eye_bytes = std::size_t(width_) * height_ * 4;
    if (left.size() != eye_bytes || right.size() != eye_bytes) return;
    next_ = 1 - next_;
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_[next_]);
    glBufferData(GL_PIXEL_UNPACK_BUFFER, GLsizeiptr(2 * eye_bytes), nullptr, GL_STREAM_DRAW);
    void* p = glMapBufferRange(GL_PIXEL_UNPACK_BUFFER, 0, GLsizeiptr(2 * eye_bytes),
                               GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT);
    if (p) {
      std::memcpy(p, left.data(), eye_bytes);
      std::memcpy(static_cast<std::uint8_t*>(p) + eye_bytes, right.data(), eye_bytes);
      glUnmapBuffer(GL_PIXEL_UNPACK_BUFFER);
      glBindTexture(GL_TEXTURE_2D, texture_);
      glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
      glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
      // Offsets into the bound PBO, not host pointers.
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, GLsizei(width_), GLsizei(height_), GL_RGBA, GL_UNSIGNED_BYTE,
                      reinterpret_cast<const void*>(std::uintptr_t{0}));
      glTexSubImage2D(GL_TEXTURE_2D, 0, GLint(width_), 0, GLsizei(width_), GLsizei(height_), GL_RGBA, GL_UNSIGNED_BYTE,
                      reinterpret_cast<const void*>(std::uintptr_t{eye_bytes}));
      has_image_ = true;
    }
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
  }

  // Draws the stereo image into the default framebuffer of fb_w x fb_h, as large as fits with
  // its aspect ratio kept (dark bars around it otherwise); texture row 0 is the image's top.
  void draw(int fb_w, int fb_h) {
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glViewport(0, 0, fb_w, fb_h);
    glClearColor(0.1f, 0.1f, 0.1f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    if (!has_image_) return;  // before the first frame (kernels compiling): the texture is undefined
    const double src_w = 2.0 * width_, src_h = height_;
    const double scale = std::min(fb_w / src_w, fb_h / src_h);
    const int w = int(std::lround(src_w * scale)), h = int(std::lround(src_h * scale));
    const int x0 = (fb_w - w) / 2, y0 = (fb_h - h) / 2;
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glBlitFramebuffer(0, 0, GLint(src_w), GLint(src_h), x0, y0 + h, x0 + w, y0, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  }

 private:
  unsigned width_, height_;
  GLuint texture_ = 0, fbo_ = 0;
  GLuint pbo_[2] = {0, 0};
  int next_ = 0;
  bool has_image_ = false;
};

// The back buffer (just drawn, not yet swapped) as a PNG: rows flipped to top-down.
void save_screenshot(const std::string& path, int fb_w, int fb_h) {
  std::vector<std::uint8_t> pixels(std::size_t(fb_w) * fb_h * 4);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, fb_w, fb_h, GL_RGBA, GL_UNSIGNED_BYTE, pixels.data());
  std::vector<std::uint8_t> top_down(pixels.size());
  const std::size_t row = std::size_t(fb_w) * 4;
  for (int y = 0; y < fb_h; ++y)
    std::memcpy(top_down.data() + std::size_t(fb_h - 1 - y) * row, pixels.data() + std::size_t(y) * row, row);
  // The window's alpha channel means nothing: the screenshot is opaque.
  for (std::size_t i = 3; i < top_down.size(); i += 4) top_down[i] = 255;
  write_png(path, fb_w, fb_h, top_down);
}

// The diagonal of the scene's bounds as loaded (the triangles themselves are released once
// uploaded: SceneOnDevices).
float scene_size(const LoadedScene& loaded) {
  const float size = loaded.triangle_count == 0 ? 1.0f : glm::length(loaded.bounds_hi - loaded.bounds_lo);
  return std::isfinite(size) && size > 0.0f ? size : 1.0f;
}

}  // namespace

int run_view(const ViewCommand& cmd) {
  // Bad flags fail before any window opens or scene loads.
  PipelineConfig config = make_pipeline_config(cmd.render);
  for (const auto& w : config.warnings) std::fprintf(stderr, "view: %s\n", w.c_str());
  if (!cmd.screenshot.empty()) {
    const std::string ext = cmd.screenshot.size() >= 4 ? cmd.screenshot.substr(cmd.screenshot.size() - 4) : "";
    if (ext != ".png" && ext != ".PNG") throw std::invalid_argument("--screenshot must name a .png file");
    const std::filesystem::path parent = std::filesystem::path(cmd.screenshot).parent_path();
    if (!parent.empty() && !std::filesystem::is_directory(parent))
      throw std::invalid_argument("--screenshot " + cmd.screenshot + ": folder " + parent.string() + " does not exist");
  }
  GlfwSession glfw;
  install_interrupt_handlers();
  RenderSession session(cmd.render, config.options);
  SceneAnimator animator(session.loaded.scene, cmd.render.scene.animation);
  if (animator.moves()) std::fprintf(stderr, "[view] animation: %s\n", animator.describe().c_str());
  const unsigned w = cmd.render.size.width, h = cmd.render.size.height;
  std::fprintf(stderr, "[view] %ux%u per eye, %u spp, %u bounces, pipeline %s, denoise %s%s\n", w, h,
               config.options.trace.spp, config.options.trace.bounces, cli_word(config.options.pipeline).c_str(),
               config.options.denoise ? ("SVGF, seams " + cli_word(config.options.denoise->seams)).c_str() : "off",
               cmd.frames ? (", " + std::to_string(cmd.frames) + " frame(s)").c_str() : "");

  // A plain OpenGL context (compatibility profile): buffer objects and framebuffer blits are GL 3.0.
  glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
  glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_FALSE);
  const std::string base_title = "parallax view: " + session.loaded.scene.name;
  GLFWwindow* window =
      glfwCreateWindow(int(2 * w), int(h), (base_title + " (compiling kernels...)").c_str(), nullptr, nullptr);
  if (!window) throw std::runtime_error("view: cannot create an OpenGL window (" + glfw_error_text() + ")");
  glfwMakeContextCurrent(window);
  glfwSwapInterval(1);
  if (epoxy_gl_version() < 30 && !epoxy_has_gl_extension("GL_ARB_framebuffer_object"))
    throw std::runtime_error("view: needs OpenGL 3.0 (pixel buffer objects, framebuffer blits); this driver offers " +
                             std::to_string(epoxy_gl_version() / 10) + "." + std::to_string(epoxy_gl_version() % 10));

  std::optional<StereoSurface> surface(std::in_place, w, h);
  Shared shared;
  std::thread renderer(render_loop, std::cref(cmd), std::ref(session), std::ref(animator), std::ref(config.controller),
                       std::ref(shared));
  // However this function leaves, the render thread is told to stop and joined first.
  struct Joiner {
    Shared& shared;
    std::thread& thread;
    ~Joiner() {
      {
        std::lock_guard lock(shared.mutex);
        shared.quit = true;
      }
      if (thread.joinable()) thread.join();
    }
  } joiner{shared, renderer};

  const float speed = cmd.move_speed > 0.0f ? cmd.move_speed : 0.25f * scene_size(session.loaded);
  std::optional<FlyCamera> fly;  // set while steering
  bool dragging = false;
  double drag_x = 0.0, drag_y = 0.0;
  bool dirty = true;
  unsigned shown = 0;  // frames displayed
  FrameInfo info;
  Camera last_camera = session.loaded.scene.camera;
  std::vector<std::uint8_t> left, right;
  auto last_tick = clock_type::now();
  bool stop = false;
  std::exception_ptr error;

  while (!stop) {
    // Wait for input, but wake often enough to pick up finished frames and to move smoothly.
    glfwWaitEventsTimeout(0.01);
    const auto now = clock_type::now();
    const float dt = static_cast<float>(std::min(seconds_between(last_tick, now), 0.1));
    last_tick = now;
    if (glfwWindowShouldClose(window) || glfwGetKey(window, GLFW_KEY_ESCAPE) == GLFW_PRESS || interrupted()) break;

    // Steering: keys move, a left-button drag turns; Space hands the camera back to the path.
    const auto key = [&](int k) { return glfwGetKey(window, k) == GLFW_PRESS ? 1.0f : 0.0f; };
    const float fwd = key(GLFW_KEY_W) - key(GLFW_KEY_S), side = key(GLFW_KEY_D) - key(GLFW_KEY_A),
                rise = key(GLFW_KEY_E) - key(GLFW_KEY_Q);
    const float boost = glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 4.0f : 1.0f;
    double mx, my;
    glfwGetCursorPos(window, &mx, &my);
    const bool button = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    bool steered = false;
    if (fwd != 0.0f || side != 0.0f || rise != 0.0f) {
      if (!fly) fly.emplace(last_camera);
      const float step = speed * boost * dt;
      fly->move(fwd * step, side * step, rise * step);
      steered = true;
    }
    if (button && dragging && (mx != drag_x || my != drag_y)) {
      if (!fly) fly.emplace(last_camera);
      // A window-height drag turns by the vertical field of view.
      int win_w, win_h;
      glfwGetWindowSize(window, &win_w, &win_h);
      const float per_pixel = glm::radians(last_camera.vfov_deg) / float(std::max(win_h, 1));
      fly->turn(-float(mx - drag_x) * per_pixel, -float(my - drag_y) * per_pixel);
      steered = true;
    }
    dragging = button;
    drag_x = mx;
    drag_y = my;
    const bool back_to_path = fly && glfwGetKey(window, GLFW_KEY_SPACE) == GLFW_PRESS;
    if (back_to_path) fly.reset();

    bool finished = false;
    {
      std::lock_guard lock(shared.mutex);
      if (steered) {
        shared.flying = true;
        shared.fly_camera = fly->camera();
      } else if (back_to_path) {
        shared.flying = false;
      }
      if (shared.fresh) {
        left.swap(shared.left);
        right.swap(shared.right);
        shared.fresh = false;
        info = shared.info;
        dirty = true;
      }
      finished = shared.finished;
      error = shared.error;
    }
    if (error) break;

    int fb_w, fb_h;
    glfwGetFramebufferSize(window, &fb_w, &fb_h);
    if (!left.empty()) {
      surface->upload(left, right);
      left.clear();
      right.clear();
      ++shown;
      if (!fly) last_camera = info.camera;
      char title[320];
      std::snprintf(title, sizeof title, "%s | %.1f Hz | %.0f ms/frame | %u spp, %u bounces | slowest: %s | %s",
                    base_title.c_str(), info.hz, info.wall_ms, info.spp, info.bounces, info.slowest.c_str(),
                    fly ? "flying (Space: camera path)" : "camera path (WASD/QE, drag: fly)");
      glfwSetWindowTitle(window, title);
    }
    // The last of --frames frames is in: draw it, save it if asked, and stop.
    // (The render thread publishes its last frame before it says it finished, and both were
    // read under one lock above, so nothing is pending once `finished` is seen.)
    const bool last = cmd.frames > 0 && finished && shown > 0;
    if (dirty || last) {
      surface->draw(fb_w, fb_h);
      if (last && !cmd.screenshot.empty()) {
        save_screenshot(cmd.screenshot, fb_w, fb_h);
        std::printf("wrote %s (%dx%d: left and right eye of frame %u side by side)\n", cmd.screenshot.c_str(), fb_w,
                    fb_h, info.index);
      }
      glfwSwapBuffers(window);
      dirty = false;
    }
    if (last) stop = true;
  }

  // A screenshot asked for without --frames: the window content when the viewer is closed.
  if (!error && !stop && !cmd.screenshot.empty() && shown > 0) {
    int fb_w, fb_h;
    glfwGetFramebufferSize(window, &fb_w, &fb_h);
    surface->draw(fb_w, fb_h);
    save_screenshot(cmd.screenshot, fb_w, fb_h);
    std::printf("wrote %s (%dx%d, the last frame shown)\n", cmd.screenshot.c_str(), fb_w, fb_h);
  }
  surface.reset();
  glfwDestroyWindow(window);
  {
    std::lock_guard lock(shared.mutex);
    shared.quit = true;
  }
  renderer.join();
  if (!error) error = shared.error;
  if (error) std::rethrow_exception(error);
  std::fprintf(stderr, "[view] %u frame(s) shown\n", shown);
  if (interrupted()) return interrupt_exit_code();
  return 0;
}

}  // namespace px

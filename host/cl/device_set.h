// The devices a frame is split across. `DeviceSet::create({.count = N})` always yields N
// ComputeDevices, whatever the hardware: sub-devices of one CPU (clCreateSubDevices) while
// there are enough compute units, else N devices of the platform (several GPUs, or PoCL's
// POCL_DEVICES list), else N in-order queues on one device. Nothing downstream knows which:
// every stage sees a context, a device and its own in-order, profiling-enabled queue.
#pragma once

#include "cl/cl_error.h"
#include "cl/kernel_build.h"

#include <CL/opencl.hpp>

#include <future>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace px {

enum class BvhLayout;  // bvh/bvh_layout.h

enum class DeviceMode { Auto, SubDevices, PlatformDevices, SharedQueues };

const char* to_string(DeviceMode mode);

struct DeviceOptions {
  int count = 1;
  DeviceMode mode = DeviceMode::Auto;
  // Substring of the platform name to use ("" = first platform that has a GPU, else the first
  // with any device). When empty, PARALLAX_PLATFORM
  // (io/environment.h).
  std::string platform;
  // The BVH node layout the set's kernels traverse; nullopt: the default for its device type
  // (bvh_layout.h: bvh_layout_for).
  std::optional<BvhLayout> bvh_layout;
  // Optimised or quick builds of every program of the set (cl/kernel_build.h); Auto decides by
  // `work`, what the command will render (none: optimised).
  KernelBuild kernel_build = KernelBuild::Optimized;
  std::optional<KernelWork> work = std::nullopt;
};

struct ComputeDevice {
  int index = 0;            // 0 = the owner (root of the dependency tree)
  cl::Device device;        // a sub-device, a platform device, or a shared device
  cl::CommandQueue queue;   // in-order, CL_QUEUE_PROFILING_ENABLE
  std::string description;  // for logs: "pthread-haswell (sub-device 1 of 2, 1 CU)"
  int compute_units = 0;
  cl_device_type type = 0;  // CL_DEVICE_TYPE, read once when the set is made

  // What kind of device it is: stages pick their kernel variant by it (e.g. SVGF's a-trous pass,
  // hole filling's work-items, the G-buffer pass's rays a work-item, the side queue).
  bool is_gpu() const { return (type & CL_DEVICE_TYPE_GPU) != 0; }
  bool is_cpu() const { return (type & CL_DEVICE_TYPE_CPU) != 0; }
};

class DeviceSet {
 public:
  static DeviceSet create(const DeviceOptions& options);

  const cl::Context& context() const { return context_; }
  std::vector<ComputeDevice>& devices() { return devices_; }
  const std::vector<ComputeDevice>& devices() const { return devices_; }
  int size() const { return static_cast<int>(devices_.size()); }
  DeviceMode mode() const { return mode_; }  // the mode actually used (never Auto)
  const std::string& platform_name() const { return platform_name_; }
  // The BVH node layout this set's kernels are built for and DeviceScene uploads to it: the one
  // requested (DeviceOptions::bvh_layout), else the default for its device type
  // (bvh_layout.h: bvh_layout_for).
  BvhLayout bvh_layout() const;
  // Whether that layout was requested rather than the device type's default.
  bool bvh_layout_requested() const { return requested_layout_.has_value(); }
  // Whether the set's programs are built with optimisation off, and why (cl/kernel_build.h).
  const KernelBuildDecision& kernel_build() const { return kernel_build_; }

  // The two programs that include the frame's kernel files (program()): the scene's kernels,
  // built with the scene's options, and the rest.
  static constexpr const char* kSceneKernels = "pathtrace/scene_kernels.cl";
  static constexpr const char* kFrameKernels = "pipeline/frame_kernels.cl";
  // Builds kernels/<path> (with its includes) for every device in the set; cached per
  // (path, options). A failed build throws ClFailure carrying each device's build log. The
  // frame's kernel files come from kSceneKernels and kFrameKernels, which include them: the same
  // kernels, built in two builds instead of eleven.
  const cl::Program& program(const std::string& path, const std::string& extra_options = "");
  // Starts building what program(path, extra_options) returns on a thread of its own, so that a
  // start builds its kernels beside other work (SceneOnDevices: the scene's layout); program()
  // then waits for that build, or throws its failure. Does nothing for a program built or started
  // already. Prebuilds run one after another in the order asked (PoCL builds one program at a
  // time in a process, so two at once would only race for its lock): the program asked for first
  // is ready first; a failed one does not stop the next. A build nothing asks for is waited for
  // when the set goes. Call from the thread that calls program().
  void prebuild(const std::string& path, const std::string& extra_options = "");
  // Whether program(path, extra_options) is built or being built (prebuild): asking for it
  // starts no build.
  bool has_program(const std::string& path, const std::string& extra_options = "") const;

  // Finishes every queue.
  void finish_all();

  // Whether launches on this set go through PoclLaunchGuard (PoCL CPU devices; pocl_launch_guard.h).
  bool guards_launches() const { return static_cast<bool>(launch_guard_); }

 private:
  cl::Platform platform_;
  cl::Context context_;
  std::vector<cl::Device> unique_devices_;  // what the context and programs were built for
  std::vector<ComputeDevice> devices_;
  DeviceMode mode_ = DeviceMode::Auto;
  std::string platform_name_;
  bool all_gpus_ = false;  // every device a GPU
  std::optional<BvhLayout> requested_layout_;
  KernelBuildDecision kernel_build_;
  std::map<std::string, cl::Program> programs_;
  // Builds prebuild() started, by program key, until program() takes them.
  std::map<std::string, std::shared_future<cl::Program>> prebuilds_;
  std::shared_future<cl::Program> last_prebuild_;  // the next prebuild starts once it has ended
  struct ProgramRequest {
    std::string path;     // the file built: the bundle holding the one asked for, or that one
    std::string key;      // programs_' key
    std::string options;  // the build options
  };
  ProgramRequest program_request(const std::string& path, const std::string& extra_options) const;
  // Registers the set's programs with PoclLaunchGuard and forgets them (and the events it
  // keeps of the set's queues) when the set goes. Declared last: destroyed first, while the
  // context, queues and programs still exist. Null where the set needs no guard.
  struct LaunchGuardRegistration {
    cl_context context = nullptr;
    ~LaunchGuardRegistration();
  };
  std::unique_ptr<LaunchGuardRegistration> launch_guard_;
};

// One line per platform and device with the facts that matter for splitting work
// (type, compute units, memory, partition support). For `parallax devices`.
std::string describe_platforms();

}  // namespace px

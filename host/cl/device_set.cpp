#include "cl/device_set.h"

#include "bvh/bvh_layout.h"
#include "cl/kernel_sources.h"
#include "cl/pocl_launch_guard.h"
#include "io/environment.h"

#include <algorithm>
#include <array>
#include <iterator>
#include <cstdlib>
#include <future>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace px {

const char* to_string(DeviceMode mode) {
  switch (mode) {
    case DeviceMode::Auto: return "auto";
    case DeviceMode::SubDevices: return "subdevices";
    case DeviceMode::PlatformDevices: return "platform";
    case DeviceMode::SharedQueues: return "queues";
  }
  return "?";
}

namespace {

std::vector<cl::Platform> all_platforms() {
  std::vector<cl::Platform> platforms;
  try {
    cl::Platform::get(&platforms);
  } catch (const cl::Error& e) {
    // The ICD loader reports "no platform" as CL_PLATFORM_NOT_FOUND_KHR (-1001).
    if (e.err() == -1001) return {};
    throw;
  }
  return platforms;
}

std::vector<cl::Device> platform_devices(const cl::Platform& p) {
  std::vector<cl::Device> devices;
  try {
    p.getDevices(CL_DEVICE_TYPE_ALL, &devices);
  } catch (const cl::Error& e) {
    if (e.err() == CL_DEVICE_NOT_FOUND) return {};
    throw;
  }
  return devices;
}

bool supports_equal_partition(const cl::Device& d) {
  auto props = d.getInfo<CL_DEVICE_PARTITION_PROPERTIES>();
  return std::find(props.begin(), props.end(), CL_DEVICE_PARTITION_BY_COUNTS) != props.end();
}

cl::Platform choose_platform(const std::string& wanted) {
  auto platforms = all_platforms();
  if (platforms.empty())
    throw ClFailure(
        "no OpenCL platform found: install an OpenCL driver (Debian: pocl-opencl-icd for the "
        "CPU) — scripts/install-deps does this");
  if (!wanted.empty()) {
    for (auto& p : platforms)
      if (p.getInfo<CL_PLATFORM_NAME>().find(wanted) != std::string::npos) return p;
    std::string names;
    for (auto& p : platforms) names += "\n  " + p.getInfo<CL_PLATFORM_NAME>();
    throw ClFailure("no OpenCL platform matches '" + wanted + "'; available:" + names);
  }
  for (auto& p : platforms)
    for (auto& d : platform_devices(p))
      if (d.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) return p;
  for (auto& p : platforms)
    if (!platform_devices(p).empty()) return p;
  throw ClFailure("OpenCL platforms exist but none has a device");
}

// The sub-devices of `root` for a BY_COUNTS partition, made once per process and kept.
//
// Why kept: PoCL 3.1's clReleaseCommandQueue releases the queue's context before it reads
// queue->device (for the driver's free_queue). When that release is the context's last, the
// context releases its devices, and a sub-device whose last reference that was is freed before
// it is read: a use-after-free. The last reference to a context is often not the host's: a
// PoCL worker thread drops its event's queue reference after the host has seen the command
// complete, and so can free a finished set's context moments later, while the host is already
// building the next set (bench_seams, or any process that makes device sets one after another,
// crashed in POclReleaseEvent in about 1 run in 4 under load; a root device is never freed, so
// one device never crashed). Keeping a reference to every sub-device for the life of the
// process makes that last release harmless; later sets of the same partition reuse them.
std::vector<cl::Device> sub_devices(cl::Device root, const std::vector<cl_device_partition_property>& props) {
  static std::mutex mutex;
  // Never destroyed: at exit the OpenCL runtime may be gone before static destructors run.
  static auto* kept =
      new std::map<std::pair<cl_device_id, std::vector<cl_device_partition_property>>, std::vector<cl::Device>>;
  std::lock_guard<std::mutex> lock(mutex);
  auto& subs = (*kept)[{root(), props}];
  if (subs.empty()) root.createSubDevices(props.data(), &subs);
  return subs;
}

}  // namespace

DeviceSet DeviceSet::create(const DeviceOptions& options) {
  if (options.count < 1) throw std::invalid_argument("device count must be at least 1");
  std::string wanted = options.platform;
  if (wanted.empty()) wanted = environment().platform;

  DeviceSet set;
  set.requested_layout_ = options.bvh_layout;
  set.platform_ = choose_platform(wanted);
  set.platform_name_ = set.platform_.getInfo<CL_PLATFORM_NAME>();
  auto devices = platform_devices(set.platform_);
  // GPUs first: a platform that mixes types should put the work where it is fastest.
  std::stable_sort(devices.begin(), devices.end(), [](const cl::Device& a, const cl::Device& b) {
    return (a.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU) > (b.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_GPU);
  });
  const int n = options.count;
  cl::Device first = devices.front();
  const int first_cus = static_cast<int>(first.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());

  DeviceMode mode = options.mode;
  if (mode == DeviceMode::Auto) {
    if (n == 1)
      mode = DeviceMode::PlatformDevices;
    else if (supports_equal_partition(first) && first_cus >= n)
      mode = DeviceMode::SubDevices;
    else if (static_cast<int>(devices.size()) >= n)
      mode = DeviceMode::PlatformDevices;
    else
      mode = DeviceMode::SharedQueues;
  }

  std::vector<cl::Device> chosen;  // one per ComputeDevice
  std::vector<std::string> notes;
  switch (mode) {
    case DeviceMode::SubDevices: {
      if (!supports_equal_partition(first))
        throw ClFailure(first.getInfo<CL_DEVICE_NAME>() + " cannot be partitioned into sub-devices");
      if (first_cus < n)
        throw ClFailure("cannot make " + std::to_string(n) + " sub-devices from " + std::to_string(first_cus) +
                        " compute units");
      // BY_COUNTS so that any n works: the first (cus % n) sub-devices get one extra unit.
      std::vector<cl_device_partition_property> props{CL_DEVICE_PARTITION_BY_COUNTS};
      for (int i = 0; i < n; ++i) props.push_back(first_cus / n + (i < first_cus % n ? 1 : 0));
      props.push_back(CL_DEVICE_PARTITION_BY_COUNTS_LIST_END);
      props.push_back(0);
      std::vector<cl::Device> subs = sub_devices(first, props);
      if (static_cast<int>(subs.size()) != n)
        throw ClFailure("clCreateSubDevices returned " + std::to_string(subs.size()) + " sub-devices, asked for " +
                        std::to_string(n));
      chosen = subs;
      for (int i = 0; i < n; ++i) notes.push_back("sub-device " + std::to_string(i + 1) + " of " + std::to_string(n));
      set.unique_devices_ = subs;
      break;
    }
    case DeviceMode::PlatformDevices: {
      if (static_cast<int>(devices.size()) < n)
        throw ClFailure("platform '" + set.platform_name_ + "' has " + std::to_string(devices.size()) +
                        " devices, asked for " + std::to_string(n) +
                        " (on PoCL, POCL_DEVICES=\"pthread pthread\" lists more)");
      chosen.assign(devices.begin(), devices.begin() + n);
      for (int i = 0; i < n; ++i) notes.push_back("platform device " + std::to_string(i));
      set.unique_devices_ = chosen;
      break;
    }
    case DeviceMode::SharedQueues: {
      chosen.assign(n, first);
      for (int i = 0; i < n; ++i)
        notes.push_back("queue " + std::to_string(i + 1) + " of " + std::to_string(n) + " on one device");
      set.unique_devices_ = {first};
      break;
    }
    case DeviceMode::Auto: break;
  }
  set.mode_ = mode;
  set.context_ = cl::Context(set.unique_devices_);
  for (int i = 0; i < n; ++i) {
    ComputeDevice cd;
    cd.index = i;
    cd.device = chosen[i];
    cd.queue = cl::CommandQueue(set.context_, chosen[i], CL_QUEUE_PROFILING_ENABLE);
    cd.compute_units = static_cast<int>(chosen[i].getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
    cd.type = chosen[i].getInfo<CL_DEVICE_TYPE>();
    cd.description =
        chosen[i].getInfo<CL_DEVICE_NAME>() + " (" + notes[i] + ", " + std::to_string(cd.compute_units) + " CU)";
    set.devices_.push_back(std::move(cd));
  }
  set.all_gpus_ =
      std::all_of(set.devices_.begin(), set.devices_.end(), [](const ComputeDevice& d) { return d.is_gpu(); });
  const bool all_cpus =
      std::all_of(set.devices_.begin(), set.devices_.end(), [](const ComputeDevice& d) { return d.is_cpu(); });
  // Queues that share one device share its units: count each device once.
  int compute_units = 0;
  for (const cl::Device& d : set.unique_devices_)
    compute_units += static_cast<int>(d.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>());
  set.kernel_build_ = decide_kernel_build(options.kernel_build, options.work, all_cpus, compute_units);
  // PoCL's CPU drivers share one work-group-function cache per process, which miscounts when
  // launches of one kernel at different global sizes overlap on several queues (any mode:
  // queues, sub-devices, POCL_DEVICES entries); the guard orders such launches.
  const bool pocl_cpu =
      set.platform_name_.find("Portable Computing Language") != std::string::npos &&
      std::any_of(set.devices_.begin(), set.devices_.end(), [](const ComputeDevice& d) { return d.is_cpu(); });
  if (pocl_cpu && PoclLaunchGuard::enabled()) {
    set.launch_guard_ = std::make_unique<LaunchGuardRegistration>();
    set.launch_guard_->context = set.context_();
  }
  return set;
}

BvhLayout DeviceSet::bvh_layout() const { return requested_layout_.value_or(bvh_layout_for(all_gpus_)); }

namespace {

// The frame's kernel files come from two programs, each including its files once:
// kernels/pathtrace/scene_kernels.cl, built for the scene's features (the path tracer, the
// G-buffer pass, the temporal gradients' shading), and kernels/pipeline/frame_kernels.cl, the
// files that take no scene options. PoCL builds a program (its front end, then a link with PoCL's
// built-in library) under the lock it also holds to make each kernel's work-group function at
// its first launch, so a first run waited on each of eleven such builds in turn
// (docs/measurements.md, "A first run, and the BVH step's single-thread passes"). The kernels
// are the same; a kernel file outside both is built on its own. A bundle's members are the files
// its source includes.
const char* bundle_of(const std::string& path, const std::string& extra_options) {
  struct Bundle {
    const char* file;
    bool takes_options;  // built with the caller's options; else only for a file asked without any
  };
  static const Bundle bundles[] = {{DeviceSet::kSceneKernels, true}, {DeviceSet::kFrameKernels, false}};
  static const auto members = [] {
    std::array<std::vector<std::string>, std::size(bundles)> files;
    for (std::size_t b = 0; b < files.size(); ++b) files[b] = quoted_includes(bundles[b].file);
    return files;
  }();
  for (std::size_t b = 0; b < std::size(bundles); ++b) {
    if (!bundles[b].takes_options && !extra_options.empty()) continue;
    if (std::find(members[b].begin(), members[b].end(), path) != members[b].end()) return bundles[b].file;
  }
  return nullptr;
}

}  // namespace

namespace {

// kernels/<path> built for `devices` with `opts`; a failed build throws ClFailure carrying each
// device's build log.
cl::Program build_program(const cl::Context& context, const std::vector<cl::Device>& devices, const std::string& path,
                          const std::string& opts) {
  const std::string source = resolve_kernel_source(path);
  cl::Program program(context, source);
  try {
    program.build(devices, opts.c_str());
  } catch (const cl::Error& e) {
    std::ostringstream msg;
    msg << "OpenCL build of kernels/" << path << " failed (" << cl_status_name(e.err()) << ")";
    for (auto& d : devices) {
      auto log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(d);
      msg << "\n--- build log, " << d.getInfo<CL_DEVICE_NAME>() << " ---\n" << log;
    }
    throw ClFailure(msg.str());
  }
  return program;
}

}  // namespace

DeviceSet::ProgramRequest DeviceSet::program_request(const std::string& requested_path,
                                                     const std::string& extra_options) const {
  const char* bundle = bundle_of(requested_path, extra_options);
  ProgramRequest r;
  r.path = bundle ? bundle : requested_path;
  // Every kernel is built for the BVH layout DeviceScene uploads (bvh_layout()), unless the
  // caller names one (DeviceScene::kernel_options()).
  const bool names_layout = extra_options.find("-DPX_BVH_WIDTH=") != std::string::npos;
  const std::string layout_define =
      names_layout ? "" : "-DPX_BVH_WIDTH=" + std::to_string(bvh_layout_width(bvh_layout()));
  r.key = r.path + "|" + layout_define + "|" + extra_options;
  // No fast-relaxed-math: the box test relies on IEEE infinities and the watertight triangle
  // test on exact signs. Single-precision constants guard against a stray unsuffixed literal.
  // A quick build (kernel_build.h) is the same source with the optimiser off: its own PoCL
  // cache entry, the same images.
  r.options = "-cl-std=CL1.2 -cl-single-precision-constant " + layout_define + " " + extra_options +
              (kernel_build_.quick ? " -cl-opt-disable" : "");
  return r;
}

void DeviceSet::prebuild(const std::string& path, const std::string& extra_options) {
  ProgramRequest r = program_request(path, extra_options);
  if (programs_.count(r.key) || prebuilds_.count(r.key)) return;
  // The task holds copies of the context and devices (reference counted), not the set, which
  // may move before it ends; a failure is kept in the future for program() to throw.
  std::shared_future<cl::Program> build =
      std::async(std::launch::async, [context = context_, devices = unique_devices_, path = r.path, options = r.options,
                                      before = last_prebuild_] {
        if (before.valid()) before.wait();  // its failure is its own program()'s to throw
        return build_program(context, devices, path, options);
      }).share();
  prebuilds_.emplace(r.key, build);
  last_prebuild_ = std::move(build);
}

bool DeviceSet::has_program(const std::string& path, const std::string& extra_options) const {
  const ProgramRequest r = program_request(path, extra_options);
  return programs_.count(r.key) != 0 || prebuilds_.count(r.key) != 0;
}

const cl::Program& DeviceSet::program(const std::string& requested_path, const std::string& extra_options) {
  const ProgramRequest r = program_request(requested_path, extra_options);
  auto it = programs_.find(r.key);
  if (it != programs_.end()) return it->second;
  cl::Program program;
  auto pending = prebuilds_.find(r.key);
  if (pending != prebuilds_.end()) {
    const std::shared_future<cl::Program> build = pending->second;
    prebuilds_.erase(pending);
    program = build.get();  // waits for the build; rethrows its failure
  } else {
    program = build_program(context_, unique_devices_, r.path, r.options);
  }
  // PoCL's build hash covers the source (named by its path) and the build options exactly (in
  // one process all PoCL CPU devices are the same host CPU).
  if (launch_guard_) PoclLaunchGuard::register_program(context_(), program(), r.path + "|" + r.options);
  return programs_.emplace(r.key, std::move(program)).first->second;
}

DeviceSet::LaunchGuardRegistration::~LaunchGuardRegistration() { PoclLaunchGuard::forget_context(context); }

void DeviceSet::finish_all() {
  for (auto& d : devices_) d.queue.finish();
}

std::string describe_platforms() {
  std::ostringstream out;
  auto platforms = all_platforms();
  if (platforms.empty()) {
    out << "no OpenCL platform found (Debian: apt-get install pocl-opencl-icd)\n";
    return out.str();
  }
  for (std::size_t pi = 0; pi < platforms.size(); ++pi) {
    auto& p = platforms[pi];
    out << "platform " << pi << ": " << p.getInfo<CL_PLATFORM_NAME>() << " (" << p.getInfo<CL_PLATFORM_VERSION>()
        << ")\n";
    auto devices = platform_devices(p);
    for (std::size_t di = 0; di < devices.size(); ++di) {
      auto& d = devices[di];
      auto type = d.getInfo<CL_DEVICE_TYPE>();
      out << "  device " << di << ": " << d.getInfo<CL_DEVICE_NAME>() << "\n"
          << "    type "
          << ((type & CL_DEVICE_TYPE_GPU)   ? "GPU"
              : (type & CL_DEVICE_TYPE_CPU) ? "CPU"
                                            : "other")
          << ", " << d.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>() << " compute units, "
          << (d.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>() >> 20) << " MiB global memory, " << d.getInfo<CL_DEVICE_VERSION>()
          << "\n"
          << "    sub-devices: " << (supports_equal_partition(d) ? "yes (one per compute unit at most)" : "no") << "\n";
    }
  }
  return out.str();
}

}  // namespace px

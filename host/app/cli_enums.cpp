#include "app/cli_enums.h"

#include <stdexcept>

namespace px {
namespace {

template <typename Enum>
const std::string& word_of(const WordTable<Enum>& words, Enum value) {
  for (const auto& [word, v] : words)
    if (v == value) return word;
  // Every value has a word: a value without one is an enum that grew without its table.
  throw std::logic_error("internal error: an enum value has no command-line word");
}

}  // namespace

const WordTable<PipelineKind>& pipeline_words() {
  static const WordTable<PipelineKind> words{
      {"mono", PipelineKind::Mono}, {"proposed", PipelineKind::Proposed}, {"baseline", PipelineKind::Baseline}};
  return words;
}

const WordTable<SeamMode>& seam_mode_words() {
  static const WordTable<SeamMode> words{
      {"halo", SeamMode::Halo}, {"independent", SeamMode::Independent}, {"bilateral", SeamMode::Bilateral}};
  return words;
}

const WordTable<LightSampling>& light_sampling_words() {
  static const WordTable<LightSampling> words{
      {"mis", LightSampling::Mis}, {"nee", LightSampling::Nee}, {"bsdf", LightSampling::Bsdf}};
  return words;
}

const WordTable<DirectLight>& direct_light_words() {
  static const WordTable<DirectLight> words{
      {"power", DirectLight::Power}, {"tree", DirectLight::Tree}, {"restir", DirectLight::Restir}};
  return words;
}

const WordTable<DeviceMode>& device_mode_words() {
  static const WordTable<DeviceMode> words{{"auto", DeviceMode::Auto},
                                           {"subdevices", DeviceMode::SubDevices},
                                           {"platform", DeviceMode::PlatformDevices},
                                           {"queues", DeviceMode::SharedQueues}};
  return words;
}

const WordTable<std::optional<BvhLayout>>& bvh_layout_words() {
  static const WordTable<std::optional<BvhLayout>> words{{"auto", std::nullopt},
                                                         {"binary", BvhLayout::Binary},
                                                         {"wide4", BvhLayout::Wide4},
                                                         {"wide8", BvhLayout::Wide8},
                                                         {"cwbvh", BvhLayout::Compressed8}};
  return words;
}

const WordTable<PathTraceKernel>& path_tracer_words() {
  static const WordTable<PathTraceKernel> words{{"megakernel", PathTraceKernel::Megakernel},
                                                {"wavefront", PathTraceKernel::Wavefront}};
  return words;
}

const WordTable<KernelChoice>& kernel_words() {
  static const WordTable<KernelChoice> words{{"scene", KernelChoice::Scene}, {"general", KernelChoice::General}};
  return words;
}

const WordTable<KernelBuild>& kernel_build_words() {
  static const WordTable<KernelBuild> words{
      {"auto", KernelBuild::Auto}, {"quick", KernelBuild::Quick}, {"optimized", KernelBuild::Optimized}};
  return words;
}

const WordTable<PixelJitter>& jitter_words() {
  static const WordTable<PixelJitter> words{{"halton", PixelJitter::Halton}, {"centre", PixelJitter::Centre}};
  return words;
}

const WordTable<StripBalance>& balance_words() {
  static const WordTable<StripBalance> words{{"static", StripBalance::Static}, {"dynamic", StripBalance::Dynamic}};
  return words;
}

const WordTable<SkyMode>& sky_words() {
  static const WordTable<SkyMode> words{{"auto", SkyMode::kAuto}, {"on", SkyMode::kOn}, {"off", SkyMode::kOff}};
  return words;
}

StereoPipeline::Options::Aovs parse_aov_list(const std::string& list) {
  StereoPipeline::Options::Aovs aovs;
  std::size_t at = 0;
  while (true) {
    const std::size_t comma = list.find(',', at);
    const std::string name = list.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
    bool* flag = name == "albedo" ? &aovs.albedo : name == "normal" ? &aovs.normal : nullptr;
    if (!flag)
      throw std::invalid_argument(name.empty()
                                      ? "empty name in the auxiliary image list '" + list + "' (known: albedo, normal)"
                                      : "unknown auxiliary image '" + name + "' (known: albedo, normal)");
    if (*flag) throw std::invalid_argument("auxiliary image '" + name + "' named twice in '" + list + "'");
    *flag = true;
    if (comma == std::string::npos) break;
    at = comma + 1;
  }
  return aovs;
}

const std::string& cli_word(PipelineKind value) { return word_of(pipeline_words(), value); }
const std::string& cli_word(SeamMode value) { return word_of(seam_mode_words(), value); }
const std::string& cli_word(LightSampling value) { return word_of(light_sampling_words(), value); }
const std::string& cli_word(DirectLight value) { return word_of(direct_light_words(), value); }
const std::string& cli_word(DeviceMode value) { return word_of(device_mode_words(), value); }
const std::string& cli_word(StripBalance value) { return word_of(balance_words(), value); }
const std::string& cli_word(PathTraceKernel value) { return word_of(path_tracer_words(), value); }
const std::string& cli_word(SkyMode value) { return word_of(sky_words(), value); }
const std::string& cli_word(KernelChoice value) { return word_of(kernel_words(), value); }
const std::string& cli_word(KernelBuild value) { return word_of(kernel_build_words(), value); }
const std::string& cli_word(PixelJitter value) { return word_of(jitter_words(), value); }
const std::string& cli_word(std::optional<BvhLayout> value) { return word_of(bvh_layout_words(), value); }

}  // namespace px

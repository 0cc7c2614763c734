// The words the command line accepts for each enum-valued flag, and the word of each value.
// main.cpp turns the words into enums once, as it reads the flags (app/commands.h holds the
// enums); reports and summaries print the same words back. A bench that takes one of these
// flags is to read it with the same tables.
#pragma once

#include "app/commands.h"
#include "bvh/bvh_layout.h"
#include "cl/device_set.h"
#include "pipeline/stereo_pipeline.h"
#include "pipeline/strip_schedule.h"
#include "render/path_tracer.h"
#include "render/wavefront_path_tracer.h"
#include "scene/scene_loader.h"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace px {

// Word -> value, in the order --help lists the words (a std::map would sort them).
template <typename Enum>
using WordTable = std::vector<std::pair<std::string, Enum>>;

const WordTable<PipelineKind>& pipeline_words();                // mono, proposed, baseline
const WordTable<SeamMode>& seam_mode_words();                   // halo, independent, bilateral
const WordTable<LightSampling>& light_sampling_words();         // mis, nee, bsdf
const WordTable<DirectLight>& direct_light_words();             // power, tree, restir
const WordTable<DeviceMode>& device_mode_words();               // auto, subdevices, platform, queues
const WordTable<StripBalance>& balance_words();                 // static, dynamic
const WordTable<SkyMode>& sky_words();                          // auto, on, off
const WordTable<PathTraceKernel>& path_tracer_words();          // megakernel, wavefront
const WordTable<KernelChoice>& kernel_words();                  // scene, general
const WordTable<KernelBuild>& kernel_build_words();             // auto, quick, optimized
const WordTable<PixelJitter>& jitter_words();                   // halton, centre
const WordTable<std::optional<BvhLayout>>& bvh_layout_words();  // auto (nullopt), binary, wide4, wide8, cwbvh

// The word of a value, as the flag takes it (named apart from the libraries' to_string so that
// a call is never ambiguous).
const std::string& cli_word(PipelineKind value);
const std::string& cli_word(SeamMode value);
const std::string& cli_word(LightSampling value);
const std::string& cli_word(DirectLight value);
const std::string& cli_word(DeviceMode value);
const std::string& cli_word(StripBalance value);
const std::string& cli_word(SkyMode value);
const std::string& cli_word(PathTraceKernel value);
const std::string& cli_word(KernelChoice value);
const std::string& cli_word(KernelBuild value);
const std::string& cli_word(PixelJitter value);
const std::string& cli_word(std::optional<BvhLayout> value);

// render --aov: a comma-separated list of auxiliary image names (albedo, normal; each at most
// once). Throws std::invalid_argument naming an unknown or repeated name, or an empty entry.
StereoPipeline::Options::Aovs parse_aov_list(const std::string& list);

}  // namespace px

// --bvh-layout for the benches, with the words of the program's flag (app/cli_enums.h): auto (each
// device type's default), binary, wide4, wide8, cwbvh.
#pragma once

#include "app/cli_enums.h"
#include "bvh/bvh_layout.h"

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace px::bench {

// Adds --bvh-layout to `app`, storing the layout asked for in `layout` (auto: nullopt).
inline CLI::Option* add_bvh_layout_flag(CLI::App& app, std::optional<BvhLayout>& layout) {
  return app
      .add_option_function<std::string>(
          "--bvh-layout",
          [&layout](const std::string& word) {
            for (const auto& [w, value] : bvh_layout_words())
              if (w == word) layout = value;
          },
          "BVH node layout the devices traverse: auto (the device type's default), binary, wide4, wide8, cwbvh")
      ->check(CLI::IsMember(bvh_layout_words()));
}

// --direct-light power|tree|restir (app/cli_enums.h's words), into `mode`.
inline CLI::Option* add_direct_light_flag(CLI::App& app, DirectLight& mode) {
  return app
      .add_option_function<std::string>(
          "--direct-light",
          [&mode](const std::string& word) {
            for (const auto& [w, value] : direct_light_words())
              if (w == word) mode = value;
          },
          "how next-event estimation picks an emissive triangle: power (default), tree (the light tree), restir")
      ->check(CLI::IsMember(direct_light_words()));
}

}  // namespace px::bench

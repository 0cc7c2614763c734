// run_view for a parallax built without GLFW / libepoxy (CMake found neither, or -DPX_VIEWER=OFF).
#include "app/commands.h"

#include <stdexcept>

namespace px {

int run_view(const ViewCommand&) {
  throw std::runtime_error(
      "view: this parallax was built without the live viewer (GLFW and libepoxy were not found). Install the "
      "Debian packages libglfw3-dev and libepoxy-dev (scripts/install-deps does), then rebuild");
}

}  // namespace px

// Helpers shared by the test executables.
#pragma once

#include <filesystem>
#include <string>

namespace px::test {

// ../shared beside the checkout, or "" when absent (a user's machine): tests that need it skip.
std::filesystem::path shared_dir();

// The project's source tree (for scenes/*.json).
std::filesystem::path source_dir();

}  // namespace px::test

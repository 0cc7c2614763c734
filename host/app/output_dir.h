// Output directories are never silently mixed: a new run refuses a non-empty directory unless
// the user says --overwrite, and then says what it replaces.
#pragma once

#include <string>

namespace px {

// Creates `dir` if needed. Throws std::runtime_error if it holds files and !overwrite.
void prepare_output_dir(const std::string& dir, bool overwrite);

}  // namespace px

// Small helpers shared by the benchmark harnesses.
#pragma once

#include "util/statistics.h"

namespace px::bench {

// The program's median (an even count: the mean of the two middle values).
using px::median;

}  // namespace px::bench

// tests/layers/faulty/kernel/clock.h — a kernel header with two faults (check_layers.cmake).
#pragma once

#include <toml++/toml.h>  // fault: the kernel uses the standard library and Boost only

#include <vector>

#include "kernel/time.h"
#include "sim/scenario/scenario.h"  // fault: the application is above the kernel

namespace ncosim::sim {  // fault: the kernel's names belong in ncosim::kernel
inline int clock_ticks() { return 0; }
}  // namespace ncosim::sim

// tests/layers/faulty/sim/analysis/summary.h — a module in a loop with notes (no fault here alone).
#pragma once

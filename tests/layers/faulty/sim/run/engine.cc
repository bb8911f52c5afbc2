// tests/layers/faulty/sim/run/engine.cc — a run-layer file with one fault.
#include "sim/run/engine.h"

#include "sim/present/plot.h"  // fault: the presentation is above the run
#include "sim/scenario/scenario.h"

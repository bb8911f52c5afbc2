// tests/layers/faulty/sim/analysis/notes.h — the other module of the summary/notes loop.
#pragma once

#include "sim/analysis/summary.h"

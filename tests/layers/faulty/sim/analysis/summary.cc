// tests/layers/faulty/sim/analysis/summary.cc — fault: summary uses notes, whose header uses
// summary: a loop between the modules summary and notes (no loop between the files).
#include "sim/analysis/notes.h"
#include "sim/analysis/summary.h"

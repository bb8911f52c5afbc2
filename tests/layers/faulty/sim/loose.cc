// tests/layers/faulty/sim/loose.cc — fault: a file of sim/ outside its sub-layers.
#include "config/config.h"

// tests/layers/faulty/config/table.cc — a configuration file with two faults.
#include <boost/random/mersenne_twister.hpp>

#include "config/config.h"
#include "kernel/time.h"
#include "models/plant.h"  // fault: models are above the configuration layer
#include "ncosim_version.h"  // fault: a generated header of the application

// tests/layers/faulty/network/session.cc — a network-layer file with one fault.
#include "models/channel.h"
#include "sim/run/engine.h"  // fault: the application is above the networks

// tests/layers/faulty/models/queue.h — fault: queue.h and channel.h include each other (a loop
// between files).
#pragma once

#include "models/channel.h"

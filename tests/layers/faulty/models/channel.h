// tests/layers/faulty/models/channel.h — the other file of the queue/channel loop.
#pragma once

#include "models/queue.h"

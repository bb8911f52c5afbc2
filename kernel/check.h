// kernel/check.h — NCOSIM_CHECK: programmer-error checks that abort with a message.
// Bad user input is never checked with this: it is a ScenarioError (config/config.h).
#pragma once

#include <cstdio>
#include <cstdlib>

#define NCOSIM_CHECK(cond)                                                                  \
  do {                                                                                      \
    if (!(cond)) {                                                                          \
      std::fprintf(stderr, "%s:%d: internal error: check failed: %s\n", __FILE__, __LINE__, \
                   #cond);                                                                  \
      std::abort();                                                                         \
    }                                                                                       \
  } while (0)

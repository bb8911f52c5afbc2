// python/py_estimator.h — estimators written in Python (a subclass of ncosim.Estimator) as a kind
// of the estimator registry: each run instantiates the class and calls its hooks from the run's
// worker thread, which takes the GIL for them and keeps it across calls for about 5 ms
// (py_estimator.cc, ThreadGil); runs without a Python estimator never take it.
#pragma once

#include <pybind11/pybind11.h>

#include <string>

namespace ncosim::python {

// Registers the Python class `cls` as estimator kind `name`, or replaces the class of a name it
// registered before (a notebook cell run again). A built-in name raises ValueError.
void register_estimator(const std::string& name, const std::string& help, pybind11::object cls);

// The names registered so far, in order.
pybind11::list registered_estimators();

// Gives up the GIL if this thread still keeps it for its Python estimators' calls (it keeps it
// across calls for a few milliseconds: py_estimator.cc, ThreadGil).
void release_thread_gil();

// While one is alive, this thread is inside Python code that a running command called (an
// estimator's hook or constructor, the progress callback): in_hook() is true there, and the
// package refuses to start another command (it would wait for the one that called it forever).
class HookCall {
 public:
  HookCall();
  ~HookCall();
  HookCall(const HookCall&) = delete;
  HookCall& operator=(const HookCall&) = delete;
};
bool in_hook();

// Binds ncosim's Packet (what on_packet receives) into module `m`.
void bind_packet(pybind11::module_& m);

}  // namespace ncosim::python

// python/module.cc — the extension module ncosim._ncosim, under the Python package ncosim
// (python/ncosim/): the command line run in this process, the registered kinds, and estimators
// written in Python (py_estimator.h). The package's functions (run, check, compare, fit, kinds)
// build a command line from their arguments, so a scenario, an override and an output mean
// exactly what they mean to the ncosim executable.
#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "python/py_estimator.h"
#include "sim/cmd/cli.h"
#include "sim/cmd/list_keys.h"
#include "sim/scenario/scenario.h"

namespace py = pybind11;
using namespace pybind11::literals;  // NOLINT: "name"_a keyword arguments

namespace {

// Swaps a stream's buffer for a string's for the lifetime of the object.
class Capture {
 public:
  explicit Capture(std::ostream& os) : os_(os), old_(os.rdbuf(text_.rdbuf())) {}
  ~Capture() { os_.rdbuf(old_); }
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;
  std::string text() const { return text_.str(); }

 private:
  std::ostream& os_;
  std::ostringstream text_;
  std::streambuf* old_;
};

// `ncosim ARGS...` in this process, the GIL released: (exit status, stdout, stderr). `texts` maps
// a scenario name to the text it stands for (sim::ScenarioText); `progress` (or None) is called
// with (done, total, final) from the progress thread while `run` simulates.
py::tuple cli(const std::vector<std::string>& args, const std::map<std::string, std::string>& texts,
              const py::object& progress, const std::string& worker_executable) {
  // `hooks` holds the last reference to the callback, dropped when this function returns (the
  // GIL held again); the copies inside run_cli share it.
  ncosim::sim::CliHooks hooks;
  hooks.worker_executable = worker_executable;
  hooks.second_signal_aborts = false;  // a notebook's second interrupt must not end the kernel
  if (!progress.is_none()) {
    auto callback = std::make_shared<py::object>(progress);
    hooks.progress = [callback](const ncosim::sim::CampaignProgress::Snapshot& s) {
      py::gil_scoped_acquire gil;
      const ncosim::python::HookCall hook;  // a command called from here is refused (_in_hook)
      try {
        (*callback)(s.done, s.total, s.final);
      } catch (py::error_already_set& e) {
        e.discard_as_unraisable("ncosim progress callback");
      }
    };
  }
  std::vector<std::string> argv_text{"ncosim"};
  argv_text.insert(argv_text.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_text) argv.push_back(a.data());
  int code = 0;
  std::string out, err;
  {
    py::gil_scoped_release release;
    std::vector<std::unique_ptr<ncosim::sim::ScenarioText>> held;
    for (const auto& [name, text] : texts)
      held.push_back(std::make_unique<ncosim::sim::ScenarioText>(name, text));
    const Capture cout_capture(std::cout), cerr_capture(std::cerr);
    code = ncosim::sim::run_cli(static_cast<int>(argv.size()), argv.data(), hooks);
    ncosim::python::release_thread_gil();  // before the GIL is taken back below
    std::cout.flush();
    out = cout_capture.text();
    err = cerr_capture.text();
  }
  return py::make_tuple(code, py::bytes(out), py::bytes(err));
}

// Every registered kind and section with its declared keys: a list of dicts.
py::list kinds() {
  py::list out;
  for (const auto& k : ncosim::sim::all_kinds()) {
    py::list keys;
    for (const auto& key : k.keys->list()) {
      keys.append(py::dict("key"_a = key.name(), "type"_a = key.type_text(),
                           "unit"_a = key.unit_text(), "default"_a = key.default_text(),
                           "range"_a = key.range_text(), "required"_a = key.required(),
                           "help"_a = key.help_text()));
    }
    const std::string section = k.name.substr(0, k.name.find('.'));
    out.append(
        py::dict("section"_a = section, "kind"_a = k.kind, "help"_a = k.help, "keys"_a = keys));
  }
  return out;
}

}  // namespace

PYBIND11_MODULE(_ncosim, m) {
  m.doc() = "ncosim's C++ core (use the package ncosim, not this module)";
  m.attr("_estimator_classes") = py::dict();
  m.def("_cli", &cli, "args"_a, "texts"_a, "progress"_a, "worker_executable"_a);
  m.def("_kinds", &kinds);
  m.def("_register_estimator", &ncosim::python::register_estimator, "name"_a, "help"_a, "cls"_a);
  m.def("_registered_estimators", &ncosim::python::registered_estimators);
  m.def("_in_hook", &ncosim::python::in_hook);
  ncosim::python::bind_packet(m);
}

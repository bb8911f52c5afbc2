// python/py_estimator.cc — estimators written in Python (see py_estimator.h).
#include "python/py_estimator.h"

#include <fmt/format.h>
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "config/config.h"
#include "estimators/estimator.h"
#include "sim/scenario/extensions.h"
#include "sim/scenario/registries.h"

namespace py = pybind11;
using namespace pybind11::literals;  // NOLINT: "name"_a keyword arguments

namespace ncosim::python {

namespace {

using est::Packet;
using est::PeriodInput;

// The registered classes, by kind name: a dict of the extension module (so that the interpreter,
// not a C++ static destroyed after it, owns them).
py::dict classes() {
  return py::module_::import("ncosim._ncosim").attr("_estimator_classes").cast<py::dict>();
}

py::object to_python(const toml::node& node) {
  if (const auto* t = node.as_table()) {
    py::dict d;
    for (const auto& [k, v] : *t) d[py::str(std::string(k.str()))] = to_python(v);
    return d;
  }
  if (const auto* a = node.as_array()) {
    py::list l;
    for (const auto& v : *a) l.append(to_python(v));
    return l;
  }
  if (const auto* v = node.as_integer()) return py::int_(v->get());
  if (const auto* v = node.as_floating_point()) return py::float_(v->get());
  if (const auto* v = node.as_boolean()) return py::bool_(v->get());
  if (const auto* v = node.as_string()) return py::str(v->get());
  // Dates and times: their TOML text.
  std::ostringstream text;
  node.visit([&text](const auto& v) {
    if constexpr (toml::is_date<decltype(v)> || toml::is_time<decltype(v)> ||
                  toml::is_date_time<decltype(v)>)
      text << v;
  });
  return py::str(text.str());
}

// What a Python estimator is told of the scenario (docs/python.md, "The model"): a
// types.SimpleNamespace of NumPy arrays and numbers.
py::object model_to_python(const est::Model& m) {
  const auto ns = py::module_::import("types").attr("SimpleNamespace");
  const auto& p = m.plant;
  py::list sensors;
  Eigen::Index rows = 0;
  for (const auto& s : m.sensors) rows += s.spec.ny();
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(rows, p.n());
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(rows, rows);
  Eigen::Index r = 0;
  for (const auto& s : m.sensors) {
    const Eigen::Index ny = s.spec.ny();
    C.middleRows(r, ny) = s.spec.C;
    R.block(r, r, ny, ny) = s.spec.R;
    py::object pmf = py::none();
    py::object loss = py::none();
    try {  // a link without a design law (a replayed trace) has neither
      constexpr int kPmfPeriods = 30;
      pmf = py::cast(s.delay_pmf(kPmfPeriods));
      loss = py::float_(s.link == nullptr ? 0.0 : s.link->loss_probability());
    } catch (const std::exception&) {
    }
    sensors.append(ns("name"_a = s.spec.name, "C"_a = s.spec.C, "R"_a = s.spec.R,
                      "every"_a = s.spec.every, "buffer"_a = s.spec.buffer,
                      "rows"_a = py::slice(r, r + ny, 1), "loss"_a = loss, "delay_pmf"_a = pmf));
    r += ny;
  }
  return ns("n"_a = p.n(), "nu"_a = p.nu(), "period"_a = m.period, "A"_a = p.A, "Bu"_a = p.Bu,
            "Bw"_a = p.Bw, "W"_a = p.W, "Q"_a = Eigen::MatrixXd(p.Bw * p.W * p.Bw.transpose()),
            "x0"_a = p.x0, "C"_a = C, "R"_a = R, "sensors"_a = sensors);
}

// How many calls into Python code of a command (hooks, constructors) this thread is inside.
thread_local int hook_depth = 0;

}  // namespace

HookCall::HookCall() { ++hook_depth; }
HookCall::~HookCall() { --hook_depth; }
bool in_hook() { return hook_depth > 0; }

namespace {

// The GIL for the Python estimators' calls from a run's worker thread. Handing the GIL from thread
// to thread at every call (three or more per period and estimator) costs more than a small
// filter's update, and with several workers the hand-offs dominate (measured: bench/README.md,
// "Python"). So a worker keeps the GIL across calls, and across the C++ work between them, for up
// to kHoldSeconds (Python's own switch interval), and gives it up when that time has passed, when
// its run's last Python estimator is destroyed, or before anything else may need it. Workers
// whose runs have no Python estimator never take it: they run on meanwhile.
constexpr double kHoldSeconds = 0.005;

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

class ThreadGil {
 public:
  static ThreadGil& get() {
    thread_local ThreadGil g;
    return g;
  }
  void enter() {
    if (held_) return;
    if (state_ == nullptr && PyGILState_GetThisThreadState() == nullptr) {
      // A thread Python has never seen: one thread state for the thread's life.
      gilstate_ = PyGILState_Ensure();
      state_ = PyThreadState_Get();
      owned_ = true;
    } else {
      if (state_ == nullptr) state_ = PyGILState_GetThisThreadState();
      PyEval_RestoreThread(state_);
    }
    held_ = true;
    since_ = now_seconds();
  }
  void leave_if_due() {
    if (held_ && now_seconds() - since_ >= kHoldSeconds) release();
  }
  void release() {
    if (!held_) return;
    PyEval_SaveThread();
    held_ = false;
  }
  int live = 0;  // Python estimators alive on this thread

 private:
  ThreadGil() = default;
  ~ThreadGil() {
    if (!owned_ || !Py_IsInitialized()) return;
    if (!held_) PyEval_RestoreThread(state_);
    PyGILState_Release(gilstate_);  // deletes the thread state and releases the GIL
  }
  PyThreadState* state_ = nullptr;
  PyGILState_STATE gilstate_{};
  bool owned_ = false;
  bool held_ = false;
  double since_ = 0.0;
};

// One call's hold of the GIL (kept past the call while the thread's budget lasts), and the mark
// that this thread is inside a hook (in_hook()).
class Gil {
 public:
  Gil() : g_(ThreadGil::get()) { g_.enter(); }
  ~Gil() { g_.leave_if_due(); }
  Gil(const Gil&) = delete;
  Gil& operator=(const Gil&) = delete;

 private:
  ThreadGil& g_;
  const HookCall hook_;
};

// The longest message of a Python exception kept in a run's status: it is stored with every run
// (runs.sqlite, runs.csv) and printed in the summary table.
constexpr std::size_t kMessageBytes = 400;

// `text` on one line, escaped (config::escape_text: control bytes, DEL and malformed UTF-8 as
// \xNN) and cut to about `limit` bytes, never inside a UTF-8 sequence, saying how much was cut.
std::string one_line(std::string text, std::size_t limit) {
  for (char& c : text) {
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  }
  std::string out = config::escape_text(text);
  if (out.size() <= limit) return out;
  std::size_t cut = limit;
  while (cut > 0 && (static_cast<unsigned char>(out[cut]) & 0xC0) == 0x80) --cut;
  const std::size_t esc = out.rfind("\\x", cut - 1);  // nor inside an escape \xNN
  if (esc != std::string::npos && esc + 4 > cut) cut = esc;
  const std::size_t more = out.size() - cut;
  out.resize(cut);
  return out + fmt::format("... ({} more bytes)", more);
}

// "TypeError: message" of the Python exception being handled, on one line, escaped and capped.
std::string describe(const py::error_already_set& e) {
  std::string text = e.what();
  const auto tb = text.find("\n\nAt:");
  if (tb != std::string::npos) text.resize(tb);
  return one_line(std::move(text), kMessageBytes);
}

// What a returned value is, for a message: "str 'abc'", "an array of complex128, shape (2,)".
std::string what_is(const py::handle& o) {
  if (py::isinstance<py::array>(o)) {
    const auto a = py::reinterpret_borrow<py::array>(o);
    std::string shape;
    for (py::ssize_t i = 0; i < a.ndim(); ++i)
      shape += fmt::format("{}{}", i ? ", " : "", a.shape(i));
    if (a.ndim() == 1) shape += ",";
    return fmt::format("an array of {}, shape ({})", py::str(a.dtype()).cast<std::string>(), shape);
  }
  const std::string type = py::str(py::type::handle_of(o).attr("__name__")).cast<std::string>();
  std::string repr;
  try {
    repr = py::repr(o).cast<std::string>();
  } catch (const py::error_already_set&) {
    repr = "?";
  }
  return fmt::format("{} {}", type, one_line(repr, 60));
}

// A value of the wrong type or shape returned by a hook: the run's status says which and why.
struct BadValue {
  std::string what;
};

// `o` as an array of real numbers (NumPy's bool, integer or float dtypes; lists of numbers): a
// complex, string or object array is refused, never converted.
py::array real_array(const py::handle& o, const std::string& expected) {
  py::array a = py::array::ensure(o);
  const char kind = a ? a.dtype().kind() : 'O';
  if (!a || (kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f'))
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
}

// state(): n real numbers (a 1-D array, or one row or column).
void read_vector(const py::handle& o, Eigen::VectorXd& x) {
  const std::string expected = fmt::format("a vector of {} real numbers", x.size());
  const py::array a = real_array(o, expected);
  const bool vector = a.ndim() == 1 || (a.ndim() == 2 && (a.shape(0) == 1 || a.shape(1) == 1));
  if (!vector || a.size() != x.size())
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  std::copy_n(static_cast<const double*>(a.data()), x.size(), x.data());
}

// covariance(): an n x n matrix of real numbers.
void read_matrix(const py::handle& o, Eigen::MatrixXd& P, Eigen::Index n) {
  const std::string expected = fmt::format("None or a {} x {} matrix of real numbers", n, n);
  const py::array a = real_array(o, expected);
  if (a.ndim() != 2 || a.shape(0) != n || a.shape(1) != n)
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  P.resize(n, n);
  const auto* d = static_cast<const double*>(a.data());  // C order: row by row
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) P(i, j) = d[i * n + j];
  }
}

// An integer (Python's or NumPy's; not a bool, a float or a string) in [lo, hi].
long long read_integer(const py::handle& o, long long lo, long long hi,
                       const std::string& expected) {
  if (PyBool_Check(o.ptr()) || PyFloat_Check(o.ptr()) || !PyIndex_Check(o.ptr()))
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  const py::object i = py::reinterpret_steal<py::object>(PyNumber_Index(o.ptr()));
  if (!i) throw py::error_already_set();
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
  if (overflow != 0 || v < lo || v > hi)
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  return v;
}

class PyEstimator final : public est::Estimator {
 public:
  // Holds the GIL when called.
  PyEstimator(py::object obj, Eigen::Index n, bool has_covariance, bool has_mode)
      : x_(Eigen::VectorXd::Zero(n)) {
    obj_ = std::move(obj);
    on_packet_ = obj_.attr("on_packet");
    on_period_ = obj_.attr("on_period");
    state_ = obj_.attr("state");
    if (has_covariance) covariance_ = obj_.attr("covariance");
    if (has_mode) mode_ = obj_.attr("mode");
    ++ThreadGil::get().live;  // last: a constructor that throws has no destructor to undo it
  }
  // A run whose instance could not be made: its status says why.
  explicit PyEstimator(Eigen::Index n, std::string status) : x_(Eigen::VectorXd::Zero(n)) {
    ++ThreadGil::get().live;
    status_ = std::move(status);
  }
  ~PyEstimator() override {
    if (!Py_IsInitialized()) return;
    ThreadGil& g = ThreadGil::get();
    g.enter();
    on_packet_ = on_period_ = state_ = covariance_ = mode_ = obj_ = py::object();
    if (--g.live <= 0) g.release();  // the run is over: nothing of this thread needs it now
  }
  PyEstimator(const PyEstimator&) = delete;
  PyEstimator& operator=(const PyEstimator&) = delete;

  int on_packet(const Packet& p, std::int64_t k) override {
    if (status_ != "ok") return 0;
    const Gil gil;
    try {
      const py::object used = on_packet_(py::cast(p), k);
      if (used.is_none()) return p.count;
      return static_cast<int>(read_integer(
          used, 0, p.count, fmt::format("None or the number of samples used, 0..{}", p.count)));
    } catch (py::error_already_set& e) {
      fail("on_packet", k, describe(e));
    } catch (const BadValue& e) {
      fail("on_packet", k, e.what);
    }
    ThreadGil::get().release();  // failed: no more calls from this run
    return 0;
  }

  void on_period(std::int64_t k, const PeriodInput& in) override {
    if (status_ != "ok") return;
    const Gil gil;
    const char* hook = "on_period";  // the hook being called or read, for the status
    try {
      on_period_(k, in.u, in.drive);
      hook = "state";
      read_vector(state_(), x_);
      if (covariance_) {
        hook = "covariance";
        const py::object P = covariance_();
        has_P_ = !P.is_none();
        if (has_P_) read_matrix(P, P_, x_.size());
      }
      if (mode_) {
        hook = "mode";
        const py::object m = mode_();
        mode_value_ =
            m.is_none()
                ? std::nullopt
                : std::optional<int>(static_cast<int>(read_integer(
                      m, 0, std::numeric_limits<int>::max(), "None or a mode, an integer from 0")));
      }
    } catch (py::error_already_set& e) {
      fail(hook, k, describe(e));
    } catch (const BadValue& e) {
      fail(hook, k, e.what);
    }
    if (status_ != "ok") ThreadGil::get().release();  // failed: no more calls from this run
  }

  StateView state() const override { return StateView(x_.data(), x_.size()); }
  const Eigen::MatrixXd* covariance() const override { return has_P_ ? &P_ : nullptr; }
  std::optional<int> mode() const override { return mode_value_; }
  std::string status() const override { return status_; }

 private:
  void fail(const char* hook, std::int64_t k, const std::string& what) {
    status_ = fmt::format("python_error: {} (in {} at k = {})", what, hook, k);
  }

  py::object obj_, on_packet_, on_period_, state_, covariance_, mode_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  bool has_P_ = false;
  std::optional<int> mode_value_;
  std::string status_ = "ok";
};

// `flops`: a finite, non-negative real number (FLOPs per period).
double read_flops(const py::handle& o) {
  const std::string expected = "None or a finite number >= 0 (FLOPs per period)";
  if (PyBool_Check(o.ptr()) || !(PyFloat_Check(o.ptr()) || PyIndex_Check(o.ptr())))
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  const double v = py::float_(py::reinterpret_borrow<py::object>(o)).cast<double>();
  if (!std::isfinite(v) || v < 0.0)
    throw BadValue{fmt::format("expected {}, got {}", expected, what_is(o))};
  return v;
}

class PyDesign final : public est::EstimatorDesign {
 public:
  // Holds the GIL when called.
  PyDesign(py::object cls, py::object model, py::object params, Eigen::Index n)
      : cls_(std::move(cls)), model_(std::move(model)), params_(std::move(params)), n_(n) {
    const py::object base = py::module_::import("ncosim").attr("Estimator");
    has_covariance_ = !cls_.attr("covariance").is(base.attr("covariance"));
    has_mode_ = !cls_.attr("mode").is(base.attr("mode"));
    // One instance now: bad parameters are bad input, reported before t = 0.
    const py::object probe = cls_(model_, params_);
    const py::object flops = py::getattr(probe, "flops", py::none());
    if (!flops.is_none()) flops_ = read_flops(flops);
    report_.method = "python";
    report_.extra["class"] =
        fmt::format("{}.{}", py::str(cls_.attr("__module__")).cast<std::string>(),
                    py::str(cls_.attr("__qualname__")).cast<std::string>());
  }
  ~PyDesign() override {
    if (!Py_IsInitialized()) return;
    py::gil_scoped_acquire gil;
    cls_ = model_ = params_ = py::object();
  }
  PyDesign(const PyDesign&) = delete;
  PyDesign& operator=(const PyDesign&) = delete;

  std::unique_ptr<est::Estimator> instantiate() const override {
    const Gil gil;
    try {
      return std::make_unique<PyEstimator>(cls_(model_, params_), n_, has_covariance_, has_mode_);
    } catch (py::error_already_set& e) {
      return std::make_unique<PyEstimator>(
          n_, fmt::format("python_error: {} (in __init__)", describe(e)));
    }
  }
  const est::DesignReport& report() const override { return report_; }
  std::optional<double> flops_per_period() const override { return flops_; }

 private:
  py::object cls_, model_, params_;
  Eigen::Index n_;
  bool has_covariance_ = false, has_mode_ = false;
  std::optional<double> flops_;
  est::DesignReport report_;
};

// The registry's factory of kind `name`: the class registered under it now.
std::unique_ptr<est::EstimatorDesign> make_design(const std::string& name, const config::Table& t,
                                                  const est::Model& model) {
  py::gil_scoped_acquire gil;
  const HookCall hook;  // the class's constructor runs here
  const py::dict params;
  for (const auto& [k, v] : t.raw()) {
    const std::string key(k.str());
    t.allow(key);
    if (key == "kind" || key == "name" || key == "expected_status") continue;
    params[py::str(key)] = to_python(v);
  }
  try {
    const py::dict registered = classes();
    if (!registered.contains(name))
      t.fail("kind", fmt::format("the Python estimator \"{}\" is no longer registered", name));
    return std::make_unique<PyDesign>(registered[py::str(name)], model_to_python(model), params,
                                      model.plant.n());
  } catch (py::error_already_set& e) {
    t.fail("kind",
           fmt::format("the Python estimator \"{}\" refused its table: {}", name, describe(e)));
  } catch (const BadValue& e) {
    t.fail("kind", fmt::format("the Python estimator \"{}\": flops: {}", name, e.what));
  }
}

}  // namespace

void release_thread_gil() { ThreadGil::get().release(); }

void register_estimator(const std::string& name, const std::string& help, py::object cls) {
  py::dict registered = classes();
  if (!registered.contains(name)) {
    if (sim::estimator_registry().find(name) != nullptr)
      throw py::value_error(fmt::format(
          "\"{}\" is a built-in estimator kind: register the Python class under another name",
          name));
    sim::add_extension_now([&](sim::Registries& r) {
      r.estimators.add(
          name, help.empty() ? "(Python)" : help + " (Python)",
          [name](const config::Table& t, const est::Model& m) { return make_design(name, t, m); });
    });
  }
  registered[py::str(name)] = std::move(cls);
}

py::list registered_estimators() { return py::list(classes().attr("keys")()); }

void bind_packet(py::module_& m) {
  py::class_<models::Packet>(m, "Packet",
                             "A packet as delivered to an estimator (on_packet): samples of one "
                             "sensor, each with the period it was taken at.")
      .def_readonly("sensor", &models::Packet::sensor, "index of the sensor (model.sensors)")
      .def_readonly("send_period", &models::Packet::send_period, "the period it was sent at")
      .def_readonly("count", &models::Packet::count, "number of samples")
      .def_readonly("stamps", &models::Packet::stamps,
                    "stamps[i]: the period sample i was taken at")
      .def_property_readonly(
          "values", [](const models::Packet& p) { return Eigen::VectorXd(p.values); },
          "the samples' values: sample i occupies [i*ny, (i+1)*ny)")
      .def_readonly("independent_copy", &models::Packet::independent_copy,
                    "a copy with its own noise (independent-copies links)")
      .def("__repr__", [](const models::Packet& p) {
        return fmt::format("Packet(sensor={}, send_period={}, count={})", p.sensor, p.send_period,
                           p.count);
      });
}

}  // namespace ncosim::python

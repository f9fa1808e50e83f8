// The shield's part of dua_mujoco._core: the brake (brake.h) and the shield (shield.h), each a
// thin class over the native one; dua_mujoco/shield/ checks the arguments a user gives.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "bindings.h"
#include "brake.h"
#include "shield.h"
#include "tables.h"

using nb::literals::operator""_a;

namespace dua {
namespace {

std::vector<int> IntsOf(const In<int64_t>& a) {
  return std::vector<int>(a.data(), a.data() + a.size());
}

// What every failsafe binding shows of the robot it moves: its brake's actuators, DOFs and
// bodies (an Evade owns one brake), bound once for both (Python's Failsafe).
struct PyRobot {
  virtual ~PyRobot() = default;
  virtual const Brake& robot() const = 0;
};

// A failsafe (a Brake or an Evade) and the scratch MjData it reads a state on (the caller's
// data is never written).
template <class F>
struct PyFailsafe : PyRobot {
  const Brake& robot() const override {
    if constexpr (std::is_same_v<F, Brake>) {
      return *failsafe;
    } else {
      return failsafe->brake();
    }
  }
  std::unique_ptr<F> failsafe;
  const mjModel* m = nullptr;
  nb::object model;
  mjData* scratch = nullptr;
  std::vector<double> state;
  ~PyFailsafe() {
    if (scratch) mj_deleteData(scratch);
  }
};
using PyBrake = PyFailsafe<Brake>;
using PyEvade = PyFailsafe<Evade>;

// A shield, the Python objects whose MuJoCo structs it points into, and a Python failsafe if
// one was given (called with the rollout's or the scratch's model and data).
struct PyShield {
  std::unique_ptr<Shield> shield;
  std::unique_ptr<Brake> brake;
  std::unique_ptr<Evade> evade;
  const mjModel* m = nullptr;
  nb::object model, rolled, roll, scratch, view, policy;
  // control() runs every physics step, where the call itself is a good part of the shield's
  // time on a step that decides nothing: the last data object, held (so no other object can
  // take its identity), with its mjData; and a numpy array the controls are written into, whose
  // bound copy() makes each call's fresh array (cheaper than exporting a new buffer).
  nb::object data;
  const mjData* d = nullptr;
  nb::object out, copy_out;
  double* out_data = nullptr;
};

nb::dict Counts(const ShieldCounts& c) {
  nb::dict d;
  d["steps"] = c.steps, d["interventions"] = c.interventions, d["unguaranteed"] = c.unguaranteed;
  d["periods"] = c.periods, d["screened"] = c.screened, d["accepted"] = c.accepted;
  d["rejected"] = c.rejected, d["rollouts"] = c.rollouts, d["rollout_steps"] = c.rollout_steps;
  d["bound_events"] = c.bound_events, d["robot_events"] = c.robot_events;
  d["plan_breaks"] = c.plan_breaks, d["hold_breaks"] = c.hold_breaks;
  d["stop_breaks"] = c.stop_breaks, d["unverified"] = c.unverified, d["unheld"] = c.unheld;
  return d;
}

}  // namespace

void BindShield(nb::module_& m) {
  nb::class_<PyRobot>(m, "Failsafe",
                      "A failsafe's robot: its brake's actuators, DOFs and bodies (Brake, Evade).")
      .def_prop_ro("dofs", [](const PyRobot& s) { return s.robot().dofs(); })
      .def_prop_ro("bodies", [](const PyRobot& s) { return s.robot().bodies(); })
      .def_prop_ro("actuators", [](const PyRobot& s) { return s.robot().actuators(); });

  nb::class_<PyBrake, PyRobot>(m, "Brake", "The shield's brake (brake.h) on a scratch MjData.")
      .def(
          "__init__",
          [](PyBrake* self, nb::object model, const In<int64_t>& actuators, double time_constant) {
            new (self) PyBrake();
            self->m = ModelOf(model);
            self->model = model;
            std::string error;
            self->failsafe = Brake::Make(self->m, IntsOf(actuators), time_constant, &error);
            if (!self->failsafe) Raise("InvalidInputError", error + ".");
            self->scratch = mj_makeData(self->m);
            if (!self->scratch) Raise("NativeLibraryError", "MuJoCo could not allocate an mjData");
            self->state.resize(mj_stateSize(self->m, mjSTATE_INTEGRATION));
          },
          "model"_a, "actuators"_a, "time_constant"_a)
      .def(
          "compute",
          [](PyBrake& self, nb::handle data, nb::object target) {
            const mjData* d = DataOf(data);
            const Brake& b = *self.failsafe;
            std::vector<double> goal;
            if (!target.is_none()) {
              const auto t = nb::cast<In<double>>(target);
              Require(Size(t) == static_cast<int64_t>(b.dofs().size()),
                      "target must have one joint velocity per braked DOF");
              goal.assign(t.data(), t.data() + t.size());
            }
            mj_getState(self.m, d, self.state.data(), mjSTATE_INTEGRATION);
            mj_setState(self.m, self.scratch, self.state.data(), mjSTATE_INTEGRATION);
            Brake::Prepare(self.m, self.scratch);
            std::vector<double> ctrl(self.m->nu);
            self.failsafe->Compute(self.m, self.scratch, goal.empty() ? nullptr : goal.data(),
                                   ctrl.data());
            return Owned(std::move(ctrl), {static_cast<size_t>(self.m->nu)});
          },
          "data"_a, "target"_a = nb::none(),
          "(nu,) controls at data's state: data.ctrl with the robot's actuators braking (or "
          "driving toward target, joint velocities of the braked DOFs).")
      .def_prop_ro("time_constant", [](const PyBrake& s) { return s.failsafe->time_constant(); });

  nb::class_<PyEvade, PyRobot>(m, "Evade", "The evasive failsafe (brake.h) on a scratch MjData.")
      .def(
          "__init__",
          [](PyEvade* self, nb::object model, const In<int64_t>& actuators, double time_constant,
             int x, int y, std::vector<int> obstacles, std::vector<double> radius,
             std::vector<double> room, double gain, double still, bool sideways) {
            new (self) PyEvade();
            self->m = ModelOf(model);
            self->model = model;
            std::string error;
            auto b = Brake::Make(self->m, IntsOf(actuators), time_constant, &error);
            if (!b) Raise("InvalidInputError", error + ".");
            self->failsafe = Evade::Make(self->m, std::move(b), x, y, obstacles, radius, room, gain,
                                         still, sideways, &error);
            if (!self->failsafe) Raise("InvalidInputError", error + ".");
            self->scratch = mj_makeData(self->m);
            if (!self->scratch) Raise("NativeLibraryError", "MuJoCo could not allocate an mjData");
            self->state.resize(mj_stateSize(self->m, mjSTATE_INTEGRATION));
          },
          "model"_a, "actuators"_a, "time_constant"_a, "x"_a, "y"_a, "obstacles"_a, "radius"_a,
          "room"_a, "gain"_a, "still"_a, "sideways"_a)
      .def(
          "compute",
          [](PyEvade& self, nb::handle data) {
            const mjData* d = DataOf(data);
            mj_getState(self.m, d, self.state.data(), mjSTATE_INTEGRATION);
            mj_setState(self.m, self.scratch, self.state.data(), mjSTATE_INTEGRATION);
            Brake::Prepare(self.m, self.scratch);
            std::vector<double> ctrl(self.m->nu);
            self.failsafe->Compute(self.m, self.scratch, ctrl.data());
            return Owned(std::move(ctrl), {static_cast<size_t>(self.m->nu)});
          },
          "data"_a, "(nu,) controls at data's state (its bodies' positions read from it).");

  nb::class_<PyShield>(m, "Shield", "The safety shield (shield.h).")
      .def(
          "__init__",
          [](PyShield* self, nb::handle table_object, nb::object model, nb::object rolled,
             nb::object roll, nb::object scratch, const In<int64_t>& actuators,
             const In<int64_t>& bodies, const In<int64_t>& g1, const In<int64_t>& g2,
             int64_t period, double deviation, double rest_speed, double stop_time,
             double stop_distance, bool screen, double time_constant, nb::object policy,
             nb::object view, nb::object evade) {
            new (self) PyShield();
            auto tables = nb::cast<std::shared_ptr<Tables>>(table_object);
            self->m = ModelOf(model);
            self->model = model, self->rolled = rolled, self->roll = roll;
            self->scratch = scratch, self->policy = policy, self->view = view;
            std::string error;
            Failsafe failsafe;
            if (!evade.is_none()) {
              // Evade reads the obstacles from the data it is given: in the run that must be
              // the rollout's view (the live state would leave the plans it verified).
              if (view.is_none()) {
                Raise("InvalidInputError",
                      "evade needs the rollout's view: pass view=MjData(rolled) (the shield's "
                      "view), not None.");
              }
              // The native evasive failsafe: (x, y, obstacles, radius, room, gain, still,
              // sideways).
              auto e = nb::cast<std::tuple<int, int, std::vector<int>, std::vector<double>,
                                           std::vector<double>, double, double, bool>>(evade);
              auto b = Brake::Make(self->m, IntsOf(actuators), time_constant, &error);
              if (!b) Raise("InvalidInputError", error + ".");
              self->evade = Evade::Make(self->m, std::move(b), std::get<0>(e), std::get<1>(e),
                                        std::get<2>(e), std::get<3>(e), std::get<4>(e),
                                        std::get<5>(e), std::get<6>(e), std::get<7>(e), &error);
              if (!self->evade) Raise("InvalidInputError", error + ".");
              Evade* ev = self->evade.get();
              failsafe = [ev](const mjModel* mm, mjData* dd, double* ctrl) {
                ev->Compute(mm, dd, ctrl);
              };
            } else if (policy.is_none()) {
              self->brake = Brake::Make(self->m, IntsOf(actuators), time_constant, &error);
              if (!self->brake) Raise("InvalidInputError", error + ".");
              Brake* b = self->brake.get();
              failsafe = [b](const mjModel* mm, mjData* dd, double* ctrl) {
                b->Compute(mm, dd, nullptr, ctrl);
              };
            } else {
              // A Python policy(model, data) -> (nu,): given the rollout's objects, the view's
              // (the run, with a view) or the scratch's, whichever the shield is stepping.
              PyShield* s = self;
              const mjData* rolling = DataOf(roll);
              const mjData* viewing = view.is_none() ? nullptr : DataOf(view);
              failsafe = [s, rolling, viewing](const mjModel*, mjData* dd, double* ctrl) {
                nb::object out = dd == rolling   ? s->policy(s->rolled, s->roll)
                                 : dd == viewing ? s->policy(s->rolled, s->view)
                                                 : s->policy(s->model, s->scratch);
                const auto a = nb::cast<In<double>>(out);
                Require(Size(a) == s->m->nu, "the failsafe policy must return (nu,) controls");
                std::copy_n(a.data(), s->m->nu, ctrl);
              };
            }
            ShieldOptions o;
            o.period = period, o.deviation = deviation, o.rest_speed = rest_speed;
            o.stop_time = stop_time, o.stop_distance = stop_distance, o.screen = screen;
            self->shield = Shield::Make(
                self->m, std::move(tables), ModelOf(rolled), const_cast<mjData*>(DataOf(roll)),
                const_cast<mjData*>(DataOf(scratch)), IntsOf(actuators), IntsOf(bodies),
                std::vector<int64_t>(g1.data(), g1.data() + g1.size()),
                std::vector<int64_t>(g2.data(), g2.data() + g2.size()), std::move(failsafe), o,
                &error, view.is_none() ? nullptr : const_cast<mjData*>(DataOf(view)));
            if (!self->shield) Raise("InvalidInputError", error + ".");
            self->out = nb::module_::import_("numpy").attr("zeros")(self->m->nu);
            self->out_data = nb::cast<InOut<double>>(self->out).data();
            self->copy_out = self->out.attr("copy");
          },
          "tables"_a, "model"_a, "rolled"_a, "roll"_a, "scratch"_a, "actuators"_a, "bodies"_a,
          "g1"_a, "g2"_a, "period"_a, "deviation"_a, "rest_speed"_a, "stop_time"_a,
          "stop_distance"_a, "screen"_a, "time_constant"_a, "policy"_a.none(),
          "view"_a.none() = nb::none(), "evade"_a.none() = nb::none())
      .def(
          "reset",
          [](PyShield& self, nb::handle data) { self.shield->Reset(self.m, DataOf(data)); },
          "data"_a, "Start over at data's state.")
      .def(
          "control",
          [](PyShield& self, nb::handle data, const In<double>& intended) {
            Require(Size(intended) == self.m->nu, "intended must hold one control per actuator");
            if (!data.is(self.data)) {
              self.d = DataOf(data);
              self.data = nb::borrow(data);
            }
            self.shield->Control(self.m, self.d, intended.data(), self.out_data);
            return self.copy_out();
          },
          nb::sig("def control(self, data: object, intended: Annotated[NDArray[numpy.float64], "
                  "dict(order='C', device='cpu', writable=False)]) -> NDArray[numpy.float64]"),
          "data"_a, "intended"_a, "(nu,) the controls for the step about to start from data.")
      .def_prop_ro("guaranteed", [](const PyShield& s) { return s.shield->guaranteed(); })
      .def_prop_ro("intervening", [](const PyShield& s) { return s.shield->intervening(); })
      .def_prop_ro("counts", [](const PyShield& s) { return Counts(s.shield->counts()); })
      .def_prop_ro("interventions",
                   [](const PyShield& s) { return s.shield->counts().interventions; })
      .def_prop_ro("plan_knots", [](const PyShield& s) { return s.shield->plan_knots(); })
      .def_prop_ro("plan_rest", [](const PyShield& s) { return s.shield->plan_rest(); });
}

}  // namespace dua

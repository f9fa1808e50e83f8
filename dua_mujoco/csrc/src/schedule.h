// A schedule and the buffers it lives in (the C kernels of schedule.cc run on its dua_schedule).
// The rank buckets, the deadline wheel and select-all keep one state of the same shape, sized
// here from the schedule's options: the Python schedulers and the predictor's runtime both hold
// one (docs/theory.md, section 3).
#ifndef DUA_MUJOCO_SCHEDULE_H_
#define DUA_MUJOCO_SCHEDULE_H_

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "layout.h"

// The deadline schedule's screen: the pairs it holds off the wheel, with what the reach test
// reads of each (docs/theory.md, section 3, "The screen"), one column a vector so that the
// test runs down them. Between steps it may also list pairs that left the screen (made due,
// switched off: their WHERE is no longer kScreened); the next test drops them.
struct dua_screen {
  std::vector<int64_t> ids;            // the screened pairs
  std::vector<int32_t> first, second;  // their spheres
  std::vector<double> base;            // eps + delta h + A h^2 / 2 (h: horizon[0], H + latency)
  int64_t nsphere = 0;                 // one past the largest sphere of any of them
  // Scratch of a step: each sphere's centre and speed (nsphere, 4).
  std::vector<double> spheres;
};

namespace dua {

constexpr int64_t kAll = 2;  // select-all (every active pair every step)

// What a schedule is made of: its kind and options (checked by Check).
struct DUA_API ScheduleSpec {
  int64_t kind = kDeadline;
  double dt = 0.0;               // predictor period, seconds
  int64_t latency = 0;           // periods a verdict takes to act
  int64_t slots_per_bucket = 1;  // rank: the budget knob q, a power of two
  int64_t cap = 0;               // deadline: evaluations a step (0: no cap)
  int64_t max_interval = 1024;   // deadline: longest revisit interval, steps
  int64_t backoff = 8;           // deadline: longest interval of a pair that keeps alarming
  // Select-all: the alarm threshold on the urgency (tau: (1 + latency) dt + the alarm horizon
  // beyond one period; a distance for the paper's SA(d)).
  double threshold = 0.0;
  // The alarm horizon, seconds (at least dt; dt is one period, the default): every verdict alarms
  // that cannot cover the wait until the next one plus this less one period. Set by every
  // builder (Python converts the user's seconds to whole periods once); 0 fails Check.
  double alarm_horizon = 0.0;
  // Deadline: 1 keeps a screen (dua_screen): a pair out of alarm that a reach test clears for
  // the next step leaves the wheel, and the test, a few operations a pair, clears it each step
  // until it fails (docs/theory.md, section 3, "The screen").
  int64_t screen = 0;

  // An empty string, or what is wrong: the option, its value and the values it takes (the one
  // check of a schedule's options: the plugin's tables and the binding's schedules).
  std::string Check() const;
};

class DUA_API Schedule {
 public:
  // The initial classification of tau0 (m,) with pairs `active` (m,) switched on (empty: all).
  Schedule(const ScheduleSpec& spec, const std::vector<double>& tau0,
           const std::vector<uint8_t>& active);
  // A state of m pairs to be filled by Carry (ints at -1, nothing linked).
  Schedule(const ScheduleSpec& spec, int64_t m);
  // Copies point their C struct at their own buffers.
  Schedule(const Schedule& other);
  Schedule& operator=(const Schedule& other);
  // A move keeps the buffers (and so the struct's pointers).
  Schedule(Schedule&&) = default;
  Schedule& operator=(Schedule&&) = default;

  const ScheduleSpec& spec() const { return spec_; }
  int64_t m() const { return static_cast<int64_t>(last_tau.size()); }
  int64_t width() const { return static_cast<int64_t>(w_tau.size()); }
  dua_schedule* state() { return &view_; }
  const dua_schedule* state() const { return &view_; }

  // The pairs the classification (or the latest step) put in alarm, in id order.
  std::vector<int64_t> InitialAlarms() const;
  // Whether pair p stands in alarm: the alarm rule on its latest tau (its horizon: HorizonOf).
  // Inline, with the two below: the runtime asks it of every pair a step evaluates.
  bool Stands(int64_t p) const { return active[p] && last_tau[p] <= HorizonOf(p); }
  // The time pair p's latest verdict must cover (seconds; -inf: switched off, nothing).
  double HorizonOf(int64_t p) const {
    if (spec_.kind == kRank) return horizon[BucketOf(ints[kIntWhere * m() + p])];
    if (spec_.kind == kDeadline) {
      const int64_t where = ints[kIntWhere * m() + p], last = ints[kIntLastStep * m() + p];
      // On the screen: tested again at the next step, as a pair due then.
      if (where == kScreened) return horizon[0];
      if (where < 0) return -std::numeric_limits<double>::infinity();
      return static_cast<double>(where - last + spec_.latency) * spec_.dt + Extra();
    }
    return horizon[0];
  }
  // The step pair p is next evaluated at, if it stays switched on (a deadline pair switched off:
  // -1).
  int64_t NextDue(int64_t p) const;
  // The rank schedule's revisit interval of bucket k, in steps: its 2^k slots, q a step.
  int64_t Interval(int64_t k) const {
    return std::max<int64_t>(1, (int64_t{1} << k) / spec_.slots_per_bucket);
  }
  // The alarm horizon beyond one period (seconds, 0 by default).
  double Extra() const {
    return spec_.alarm_horizon - spec_.dt;  // 0 exactly at one period
  }
  // New pair k is old pair src[k] (its verdict carried) or new (src[k] < 0: it stands in alarm,
  // due at step n), as dua_deadline_carry does (deadline schedules only).
  void Carry(const Schedule& old, const std::vector<int64_t>& src, int64_t n);

  // The buffers (sized once; the C struct points at them).
  std::vector<double> last_tau, w_tau, horizon;
  std::vector<uint8_t> active;
  std::vector<int64_t> ints, slots, queue, params, work;
  int64_t step_count = 0;          // completed steps
  int64_t activation_changes = 0;  // switches that changed some pair, and carries
  // Deadline with spec().screen: its screen (else empty). Behind a pointer so that a move keeps
  // its address, as it keeps the buffers'.
  std::unique_ptr<dua_screen> screen = std::make_unique<dua_screen>();

 private:
  void Size(int64_t m);
  void Point();

  ScheduleSpec spec_;
  dua_schedule view_{};
};

}  // namespace dua

#endif  // DUA_MUJOCO_SCHEDULE_H_

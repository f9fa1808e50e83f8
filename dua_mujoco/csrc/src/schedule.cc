// The schedules: select, reinsert, restore, switch, make_due, and the deadline wheel's
// classification and carry. Rules and completeness proofs: docs/theory.md.
#include "schedule.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "internal.h"
#include "layout.h"

namespace {

using dua::kDeadline;
using dua::kLanes;
using dua::kRank;
using dua::LaneMask;
using dua::Lanes;
// Rows of ints, rows of work, entries of params (layout.h).
constexpr int64_t kWhere = dua::kIntWhere, kLastStep = dua::kIntLastStep, kNext = dua::kIntNext,
                  kPrev = dua::kIntPrev;
constexpr int64_t kWSlots = dua::kWorkSlots, kWIds = dua::kWorkIds, kWAlarms = dua::kWorkAlarms,
                  kWNew = dua::kWorkNew;
constexpr int64_t kNBuckets = dua::kParamNBuckets, kSlotsPerBucket = dua::kParamSlotsPerBucket,
                  kWheel = dua::kParamWheel, kMaxInterval = dua::kParamMaxInterval,
                  kCap = dua::kParamCap, kCount = dua::kParamCount, kDeferred = dua::kParamDeferred,
                  kExtra = dua::kParamExtra, kBackoff = dua::kParamBackoff,
                  kSettled = dua::kParamSettled;
constexpr double kNegInf = -std::numeric_limits<double>::infinity();

struct View {
  dua_schedule* st;
  int64_t* Int(int64_t row) const { return st->ints + row * st->m; }
  int64_t* Work(int64_t row) const { return st->work + row * st->width; }
};

// Whether a verdict covering `horizon` seconds alarms: tau at most the horizon (a contact at
// exactly tau is possible, so a verdict that ends its cover there has to stand in alarm).
inline bool Alarms(double tau, double horizon) { return tau <= horizon; }

// Whether a verdict stood in alarm (a pair switched back on, -inf, was never reported).
inline bool Stood(double last_tau, double horizon) {
  return Alarms(last_tau, horizon) && last_tau > kNegInf;
}

// A rank slot's entry: the pair, or -2 - pair if it stands in alarm.
inline int64_t Occupant(int64_t raw, bool alarmed) { return alarmed ? -2 - raw : raw; }

using dua::BucketOf;

// Appends pair p to the rank schedule's queue of pairs due out of their slots. A pair made due
// while queued and then evaluated in its own slot stays queued with a finite tau, so a second
// make_due queues it again: with bodies flagged every step the queue outgrew its m + 1 entries
// (found by the tables fuzzer). When it is full its duplicates are dropped first (each pair
// once: at most m, so p fits, or it is waiting already).
void Enqueue(dua_schedule* st, int64_t p) {
  int64_t* queue = st->queue;
  if (queue[0] >= st->nqueue - 1) {
    std::vector<uint8_t> seen(static_cast<size_t>(st->m), 0);
    int64_t kept = 0;
    for (int64_t j = 0; j < queue[0]; ++j) {
      const int64_t q = queue[1 + j];
      if (!seen[q]) seen[q] = 1, queue[1 + kept++] = q;
    }
    queue[0] = kept;
    if (seen[p]) return;
  }
  queue[1 + queue[0]] = p;
  queue[0] += 1;
}

int64_t RankSelect(const View& v, int64_t n) {
  dua_schedule* st = v.st;
  int64_t* params = st->params;
  int64_t* w_slots = v.Work(kWSlots);
  int64_t* w_ids = v.Work(kWIds);
  const int64_t q = params[kSlotsPerBucket];
  int64_t count = 0;
  for (int64_t k = 0; k < params[kNBuckets]; ++k) {
    const int64_t size = int64_t{1} << k, base = size - 1;
    const int64_t first = (n * q) % size;
    for (int64_t j = 0; j < std::min(q, size); ++j) {
      const int64_t slot = base + (first + j) % size;
      const int64_t raw = st->slots[slot];
      const int64_t pid = raw >= 0 ? raw : -2 - raw;
      if (raw != -1 && st->active[pid]) {
        // Whether it stood in alarm travels with the slot's entry (last_tau would miss cache).
        w_slots[count] = Occupant(slot, raw < -1);
        w_ids[count] = pid;
        ++count;
      }
    }
  }
  // Pairs switched back on, out of their slots, as many as the spare width holds.
  int64_t* queue = st->queue;
  const int64_t extra = std::min(queue[0], st->width - count);
  for (int64_t j = 0; j < extra; ++j) {
    w_slots[count + j] = -1;
    w_ids[count + j] = queue[1 + j];
  }
  const int64_t rest = queue[0] - extra;
  for (int64_t j = 0; j < rest; ++j) queue[1 + j] = queue[1 + extra + j];
  queue[0] = rest;
  params[kExtra] = extra;
  return count + extra;
}

int64_t RankReinsert(const View& v, int64_t n, int64_t count) {
  dua_schedule* st = v.st;
  int64_t* where = v.Int(kWhere);
  int64_t* last_step = v.Int(kLastStep);
  int64_t* w_slots = v.Work(kWSlots);
  int64_t* w_ids = v.Work(kWIds);
  int64_t* alarms = v.Work(kWAlarms);
  int64_t* fresh = v.Work(kWNew);
  const double* w_tau = st->w_tau;
  const int64_t regular = count - st->params[kExtra];
  // Stable: equal tau keep selection order (deterministic across runs).
  std::vector<int64_t> order(static_cast<size_t>(std::max<int64_t>(regular, 0)));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [w_tau](int64_t a, int64_t b) { return w_tau[a] < w_tau[b]; });
  int64_t nalarm = 0;
  for (int64_t i = 0; i < regular; ++i) {
    const int64_t src = order[i];
    const int64_t pid = w_ids[src];
    int64_t slot = w_slots[i];
    slot = slot >= 0 ? slot : -2 - slot;
    const double tau = w_tau[src];
    const bool alarmed = Alarms(tau, st->horizon[BucketOf(slot)]);
    st->slots[slot] = Occupant(pid, alarmed);
    where[pid] = slot;
    st->last_tau[pid] = tau;
    last_step[pid] = n;
    if (alarmed) {
      alarms[nalarm] = pid;
      fresh[nalarm] = w_slots[src] >= 0;  // it did not stand in alarm
      ++nalarm;
    }
  }
  for (int64_t i = regular; i < count; ++i) {
    const int64_t pid = w_ids[i];
    const double tau = w_tau[i];
    st->last_tau[pid] = tau;
    last_step[pid] = n;
    const bool alarmed = Alarms(tau, st->horizon[BucketOf(where[pid])]);
    st->slots[where[pid]] = Occupant(pid, alarmed);
    if (alarmed) {
      alarms[nalarm] = pid;
      fresh[nalarm] = 1;
      ++nalarm;
    }
  }
  return nalarm;
}

// Link pair p at the head of its due step's wheel slot.
inline void LinkInto(int64_t* slots, int64_t* ints, int64_t m, int64_t wheel, int64_t p,
                     int64_t due) {
  const int64_t slot = due & (wheel - 1);
  const int64_t head = slots[slot];
  ints[kNext * m + p] = head;
  ints[kPrev * m + p] = -1 - slot;
  if (head >= 0) ints[kPrev * m + head] = p;
  slots[slot] = p;
  ints[kWhere * m + p] = due;
}

inline void Link(const View& v, int64_t p, int64_t due) {
  LinkInto(v.st->slots, v.st->ints, v.st->m, v.st->params[kWheel], p, due);
}

// Take pair p out of its wheel slot's list, or off the screen (its entry is dropped at the next
// test), on rows and slots the caller read once; nothing if it is in neither.
inline void UnlinkFrom(int64_t* slots, int64_t* nxt, int64_t* prv, int64_t* where, int64_t p) {
  if (where[p] < 0) {
    if (where[p] == dua::kScreened) where[p] = -1;
    return;
  }
  const int64_t after = nxt[p], before = prv[p];
  if (before >= 0) {
    nxt[before] = after;
  } else {
    slots[-1 - before] = after;
  }
  if (after >= 0) prv[after] = before;
  nxt[p] = -1;
  prv[p] = -1;
  where[p] = -1;
}

inline void Unlink(const View& v, int64_t p) {
  UnlinkFrom(v.st->slots, v.Int(kNext), v.Int(kPrev), v.Int(kWhere), p);
}

// The deadline wheel's selection at step n: step n's list, after the first `count` pairs already
// in w_ids (SelectMadeDue's).
int64_t DeadlineSelect(const View& v, int64_t n, int64_t count = 0) {
  dua_schedule* st = v.st;
  int64_t* params = st->params;
  int64_t* last_step = v.Int(kLastStep);
  int64_t* nxt = v.Int(kNext);
  int64_t* prv = v.Int(kPrev);
  int64_t* where = v.Int(kWhere);
  int64_t* w_ids = v.Work(kWIds);
  const int64_t slot = n & (params[kWheel] - 1);
  int64_t p = st->slots[slot];
  st->slots[slot] = -1;
  while (p >= 0) {
    const int64_t after = nxt[p];
    nxt[p] = -1;
    prv[p] = -1;
    where[p] = -1;
    w_ids[count++] = p;
    p = after;
  }
  int64_t deferred = 0;
  const int64_t cap = params[kCap];
  if (cap > 0 && count > cap) {
    // The least time left first (ties to the lower id): none waits forever under overload.
    std::sort(w_ids, w_ids + count);
    std::vector<double> slack(static_cast<size_t>(count));
    for (int64_t k = 0; k < count; ++k) {
      const int64_t q = w_ids[k];
      slack[k] = st->last_tau[q] - static_cast<double>(n - last_step[q]) * st->dt;
    }
    std::vector<int64_t> order(static_cast<size_t>(count));
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&slack](int64_t a, int64_t b) { return slack[a] < slack[b]; });
    std::vector<int64_t> chosen(static_cast<size_t>(count));
    for (int64_t k = 0; k < count; ++k) chosen[k] = w_ids[order[k]];
    std::copy(chosen.begin(), chosen.end(), w_ids);
    deferred = count - cap;
    count = cap;
    for (int64_t k = count; k < count + deferred; ++k) Link(v, w_ids[k], n + 1);
  }
  params[kCount] = count;
  params[kDeferred] = deferred;
  return count;
}

// dua_deadline_interval of taus[0:count] into out (room for count rounded up to four), four at a
// time in lanes: its guess, and the two tests its loops begin with, in the same IEEE operations
// (s and s + latency are integers below 2^42 as doubles, so exact: ScheduleSpec::Check bounds
// latency and max_interval). A lane where either loop would take a step, or whose tau is not a
// number, gets the scalar function's answer; on every other lane the loops leave the guess as it
// is, so it is theirs (docs/theory.md, section 3, "The reinsertion's waits in lanes").
DUA_LANES_CLONES
void DeadlineIntervals(const double* taus, int64_t count, double dt, int64_t latency,
                       int64_t max_interval, double extra, int64_t* out) {
  const double lat = static_cast<double>(latency), lat1 = static_cast<double>(latency + 1);
  const double most = static_cast<double>(max_interval);
  // 2^52: c + 2^52 rounds c in [0, 2^52) to an integer r (to nearest), and r + 2^52's bits less
  // 2^52's are r.
  const Lanes magic = Lanes{} + 0x1p52;
  LaneMask magic_bits;
  std::memcpy(&magic_bits, &magic, sizeof(Lanes));
  for (int64_t k = 0; k < count; k += kLanes) {
    const int m = static_cast<int>(std::min<int64_t>(kLanes, count - k));
    Lanes tau;
    if (m == kLanes) {
      std::memcpy(&tau, taus + k, sizeof(Lanes));
    } else {
      for (int j = 0; j < kLanes; ++j) tau[j] = taus[k + std::min(j, m - 1)];
    }
    const Lanes guess = (tau - extra) / dt - lat;
    // The guess's s: max_interval at or above it, 1 below 2, else truncated; as the guess
    // clamped to [1, max_interval] and floored (the same integer on each of the three).
    const Lanes clamped = dua::Min(dua::Max(guess, Lanes{} + 1.0), Lanes{} + most);
    const Lanes big = clamped + magic;
    const Lanes near = big - magic;
    const LaneMask up = near > clamped;  // rounded up: one less
    const Lanes s = near - dua::Select(up, Lanes{} + 1.0, Lanes{});
    const LaneMask covered = (s + lat) * dt + extra < tau;
    const LaneMask next = (s + lat1) * dt + extra < tau;
    // Neither loop steps: s is 1 or covered, and s is the longest or s + 1 is not covered.
    const LaneMask settled = (tau == tau) & ((s <= 1.0) | covered) & ((s >= most) | ~next);
    LaneMask ints;
    std::memcpy(&ints, &big, sizeof(Lanes));
    ints = ints - magic_bits + up;  // up is -1 where rounded up
    std::memcpy(out + k, &ints, sizeof(Lanes));
    const int left = ~dua::Bits(settled) & ((1 << m) - 1);
    if (left != 0) {
      for (int j = 0; j < m; ++j) {
        if ((left >> j) & 1) {
          out[k + j] = dua_deadline_interval(taus[k + j], dt, latency, max_interval, extra);
        }
      }
    }
  }
}

int64_t DeadlineReinsert(const View& v, int64_t n, int64_t count) {
  dua_schedule* st = v.st;
  const int64_t* params = st->params;
  int64_t* last_step = v.Int(kLastStep);
  int64_t* where = v.Int(kWhere);
  int64_t* w_ids = v.Work(kWIds);
  int64_t* alarms = v.Work(kWAlarms);
  int64_t* fresh = v.Work(kWNew);
  const double dt = st->dt;
  const int64_t latency = st->latency;
  const int64_t max_interval = params[kMaxInterval], backoff = params[kBackoff];
  // Read once: the loop's stores of ints and taus could alias the schedule's own numbers (its m,
  // the wheel's size, the horizon and extra), which the compiler would then read again each pair.
  const double extra = st->extra, horizon = st->horizon[0];
  int64_t* slots = st->slots;
  int64_t* ints = st->ints;
  const int64_t m = st->m, wheel = params[kWheel];
  int64_t nalarm = 0;
  // The waits a chunk at a time, in lanes (DeadlineIntervals), then the chunk's pairs linked.
  constexpr int64_t kChunk = 64;
  int64_t intervals[kChunk];
  for (int64_t k0 = 0; k0 < count; k0 += kChunk) {
    const int64_t end = std::min(count, k0 + kChunk);
    DeadlineIntervals(st->w_tau + k0, end - k0, dt, latency, max_interval, extra, intervals);
    for (int64_t k = k0; k < end; ++k) {
      const int64_t p = w_ids[k];
      const double tau = st->w_tau[k];
      int64_t interval = intervals[k - k0];
      if (Alarms(tau, horizon)) {
        // Whether the last verdict stood, read only here (most evaluations do not alarm): due
        // now, it had to cover until this step (a deferred one, longer: it stood).
        const int64_t waited = n - last_step[p];
        const bool before =
            Stood(st->last_tau[p], static_cast<double>(waited + latency) * dt + extra);
        // Keeps alarming (resting contact, mostly): back off; it stands in alarm until then.
        if (before) interval = std::max<int64_t>(1, std::min(2 * waited, backoff));
        alarms[nalarm] = p;
        fresh[nalarm] = !before;
        ++nalarm;
      }
      st->last_tau[p] = tau;
      last_step[p] = n;
      LinkInto(slots, ints, m, wheel, p, n + interval);
    }
  }
  for (int64_t k = count; k < count + params[kDeferred]; ++k) {
    const int64_t p = w_ids[k];
    if (Alarms(st->last_tau[p],
               static_cast<double>(where[p] - last_step[p] + latency) * dt + st->extra)) {
      alarms[nalarm] = p;
      fresh[nalarm] =
          !Stood(st->last_tau[p], static_cast<double>(n - last_step[p] + latency) * dt + st->extra);
      ++nalarm;
    }
  }
  return nalarm;
}

int64_t AllSelect(const View& v) {
  int64_t* w_ids = v.Work(kWIds);
  int64_t count = 0;
  for (int64_t p = 0; p < v.st->m; ++p) {
    if (v.st->active[p]) w_ids[count++] = p;
  }
  return count;
}

int64_t AllReinsert(const View& v, int64_t n, int64_t count) {
  dua_schedule* st = v.st;
  int64_t* w_ids = v.Work(kWIds);
  int64_t* alarms = v.Work(kWAlarms);
  int64_t* fresh = v.Work(kWNew);
  int64_t* last_step = v.Int(kLastStep);
  int64_t nalarm = 0;
  for (int64_t k = 0; k < count; ++k) {
    const int64_t p = w_ids[k];
    const bool before = Stood(st->last_tau[p], st->horizon[0]);
    st->last_tau[p] = st->w_tau[k];
    last_step[p] = n;
    if (Alarms(st->w_tau[k], st->horizon[0])) {
      alarms[nalarm] = p;
      fresh[nalarm] = !before;
      ++nalarm;
    }
  }
  return nalarm;
}

}  // namespace

extern "C" {

int64_t dua_deadline_interval(double tau, double dt, int64_t latency, int64_t max_interval,
                              double extra) {
  // The wait is computed as the alarm test computes it, (s + latency) * dt + extra, so that a
  // pair that waits s steps is exactly one whose verdict covers them.
  // covered is monotone (the sum and product of numbers that grow with s), so the two loops
  // below give the largest s it holds for, or 1, from any guess in [1, max_interval].
  auto covered = [=](int64_t s) { return static_cast<double>(s + latency) * dt + extra < tau; };
  if (std::isnan(tau)) return 1;  // covers nothing
  // A guess only: truncated (floor, above 1) and rounded either way, then settled.
  const double guess = (tau - extra) / dt - static_cast<double>(latency);
  int64_t s = guess >= static_cast<double>(max_interval) ? max_interval  // inf too
              : guess < 2.0                              ? 1
                                                         : static_cast<int64_t>(guess);
  while (s > 1 && !covered(s)) --s;
  while (s < max_interval && covered(s + 1)) ++s;
  return s;
}

int64_t dua_select(dua_schedule* st, int64_t n) {
  const View v{st};
  int64_t count;
  st->params[kSettled] = 0;
  if (st->kind == kRank) {
    count = RankSelect(v, n);
  } else if (st->kind == kDeadline) {
    // No state to test here: the screen's pairs are all selected.
    count = st->screen != nullptr ? dua::ScreenPass(st, n, 0, nullptr) : 0;
    count = DeadlineSelect(v, n, count);
  } else {
    count = AllSelect(v);
  }
  st->params[kCount] = count;
  return count;
}

DUA_HOT int64_t dua_reinsert(dua_schedule* st, int64_t n, int64_t count) {
  const View v{st};
  if (st->kind == kRank) return RankReinsert(v, n, count);
  if (st->kind == kDeadline) return DeadlineReinsert(v, n, count);
  return AllReinsert(v, n, count);
}

void dua_restore(dua_schedule* st, int64_t n, int64_t count) {
  const View v{st};
  int64_t* w_ids = v.Work(kWIds);
  if (st->kind == kRank) {
    const int64_t extra = st->params[kExtra];
    int64_t* queue = st->queue;
    const int64_t waiting = queue[0];
    for (int64_t j = waiting - 1; j >= 0; --j) queue[1 + extra + j] = queue[1 + j];
    for (int64_t j = 0; j < extra; ++j) queue[1 + j] = w_ids[count - extra + j];
    queue[0] = waiting + extra;
  } else if (st->kind == kDeadline) {
    for (int64_t k = 0; k < count + st->params[kDeferred]; ++k) {
      Unlink(v, w_ids[k]);
      Link(v, w_ids[k], n);
    }
    // The settled pairs go back to made due, as the evaluated ones: a retry of step n would
    // otherwise take their verdict for one of its own state (SelectMadeDue leaves a verdict of
    // step n alone) and neither evaluate nor settle them again.
    const int64_t* w_settled = v.Work(kWSlots);
    for (int64_t k = 0; k < st->params[kSettled]; ++k) {
      st->last_tau[w_settled[k]] = kNegInf;
      Unlink(v, w_settled[k]);
      Link(v, w_settled[k], n);
    }
  }
  st->params[kCount] = 0;
  st->params[kDeferred] = 0;
  st->params[kExtra] = 0;
  st->params[kSettled] = 0;
}

int64_t dua_switch(dua_schedule* st, const int64_t* ids, int64_t nids, int64_t on, int64_t n_next) {
  const View v{st};
  const uint8_t want = on ? 1 : 0;
  int64_t changed = 0;
  for (int64_t k = 0; k < nids; ++k) {
    const int64_t p = ids[k];
    if (st->active[p] == want) continue;
    ++changed;
    st->active[p] = want;
    if (want) {
      // Its motion while off is unknown: it stands in alarm until the next selection.
      st->last_tau[p] = kNegInf;
      if (st->kind == kRank) {
        st->slots[v.Int(kWhere)[p]] = p;  // not reported as standing until evaluated
        Enqueue(st, p);
      } else if (st->kind == kDeadline) {
        Unlink(v, p);
        Link(v, p, n_next);
      }
    } else if (st->kind == kRank) {
      int64_t* queue = st->queue;
      int64_t kept = 0;
      for (int64_t j = 0; j < queue[0]; ++j) {
        if (queue[1 + j] != p) queue[1 + kept++] = queue[1 + j];
      }
      queue[0] = kept;
    } else if (st->kind == kDeadline) {
      Unlink(v, p);
    }
  }
  return changed;
}

void dua_make_due(dua_schedule* st, int64_t p, int64_t n) { dua::MakeDue(st, &p, 1, n); }

void dua_rank_classify(dua_schedule* st) {
  const View v{st};
  const int64_t m = st->m;
  int64_t* where = v.Int(kWhere);
  // The paper's initial classification (eq. 23): bucket k holds the pairs of rank
  // [2^k - 1, 2^(k+1) - 1) by tau, ties by id: a partition at each bucket boundary.
  std::vector<int64_t> order(static_cast<size_t>(m));
  std::iota(order.begin(), order.end(), 0);
  const double* tau = st->last_tau;
  auto less = [tau](int64_t a, int64_t b) {
    return tau[a] < tau[b] || (tau[a] == tau[b] && a < b);
  };
  int64_t lo = 0;
  for (int64_t k = 1; k < st->params[kNBuckets]; ++k) {
    const int64_t bound = (int64_t{1} << k) - 1;
    if (bound >= m) break;
    std::nth_element(order.begin() + lo, order.begin() + bound, order.end(), less);
    lo = bound;
  }
  for (int64_t i = 0; i < m; ++i) {
    const int64_t p = order[i];
    where[p] = i;
    // A pair standing in alarm is held as -2 - pair in its slot (Occupant).
    st->slots[i] = Occupant(p, st->active[p] && Alarms(tau[p], st->horizon[BucketOf(i)]));
  }
}

void dua_deadline_classify(dua_schedule* st) {
  const View v{st};
  const int64_t max_interval = st->params[kMaxInterval];
  for (int64_t p = 0; p < st->m; ++p) {
    if (st->active[p]) {
      Link(v, p,
           dua_deadline_interval(st->last_tau[p], st->dt, st->latency, max_interval, st->extra));
    }
  }
}

void dua_deadline_carry(const dua_schedule* old_state, dua_schedule* new_state, const int64_t* src,
                        int64_t nsrc, int64_t n) {
  const int64_t mo = old_state->m, mn = new_state->m;
  const int64_t wheel = new_state->params[kWheel];
  int64_t* ints = new_state->ints;
  for (int64_t p = 0; p < nsrc; ++p) {
    const int64_t q = src[p];
    if (q >= 0) {
      new_state->last_tau[p] = old_state->last_tau[q];
      new_state->active[p] = old_state->active[q];
      ints[kLastStep * mn + p] = old_state->ints[kLastStep * mo + q];
      const int64_t due = old_state->ints[kWhere * mo + q];
      // A screened pair's verdict covers step n at most (its next test): due then.
      if (due >= 0 || due == dua::kScreened) {
        LinkInto(new_state->slots, ints, mn, wheel, p, due >= 0 ? due : n);
      }
    } else {
      new_state->last_tau[p] = kNegInf;
      new_state->active[p] = 1;
      ints[kLastStep * mn + p] = n;
      LinkInto(new_state->slots, ints, mn, wheel, p, n);
    }
  }
}

}  // extern "C"

namespace dua {

DUA_HOT int64_t SelectMadeDue(dua_schedule* st, const int64_t* groups, int64_t ngroups,
                              const int64_t* start, const int64_t* members, int64_t n,
                              const dua_step_args* settle, const dua_step_args* screen) {
  if (st->kind != kDeadline) {
    for (int64_t k = 0; k < ngroups; ++k) {
      const int64_t g = groups[k];
      MakeDue(st, members + start[g], start[g + 1] - start[g], n);
    }
    return dua_select(st, n);
  }
  // MakeDue links each pair at the head of step n's list, and the selection walks that list
  // from its head: the pairs come out last made due first, then the ones due at n anyway. The
  // same order straight into w_ids: the groups and their members walked backwards, each pair
  // taken the first time it is met, out of whatever list holds it (step n's too).
  const View v{st};
  // Read once (the loop's stores could alias the schedule's m).
  int64_t* where = v.Int(kWhere);
  int64_t* nxt = v.Int(kNext);
  int64_t* prv = v.Int(kPrev);
  int64_t* slots = st->slots;
  int64_t* w_ids = v.Work(kWIds);
  double* last_tau = st->last_tau;
  const uint8_t* active = st->active;
  constexpr int64_t kTaken = -2;  // taken this step (Unlink leaves -1; never a due step)
  int64_t* last_step = v.Int(kLastStep);
  const double dt = st->dt, extra = st->extra, horizon = st->horizon[0];
  const int64_t latency = st->latency, max_interval = st->params[kMaxInterval];
  const int64_t m = st->m, wheel = st->params[kWheel];
  int64_t* w_settled = v.Work(kWSlots);  // the settled pairs (the wheel leaves the row unused)
  int64_t count = 0, settled = 0;
  for (int64_t k = ngroups - 1; k >= 0; --k) {
    const int64_t g = groups[k];
    for (int64_t j = start[g + 1] - 1; j >= start[g]; --j) {
      const int64_t p = members[j];
      // A pair linked in the wheel is switched on (docs/theory.md, section 3, "Linked pairs are
      // switched on"): active is read only of the others (where -1: off, or on and unlinked).
      const int64_t at = where[p];
      // A screened pair is the screen's to clear or select, below.
      if (at == kTaken || at == dua::kScreened || (at < 0 && !active[p])) continue;
      // Settled (docs/theory.md, section 6): only a pair linked in the wheel that does not stand
      // in alarm (the step's tracking reads the selection, and a pair left out of it must keep
      // its standing: none), with a bound from this state above the horizon (no alarm now).
      if (settle != nullptr && at >= 0 &&
          !Alarms(last_tau[p], static_cast<double>(at - last_step[p] + latency) * dt + extra)) {
        // A verdict of step n already (a pair of two flagged bodies, met again): it stays.
        if (last_step[p] == n) continue;
        // The wait until its due step, as Stands computes it once the verdict is of step n (0:
        // due now, nothing to keep).
        const double cover = at > n ? static_cast<double>(at - n + latency) * dt + extra : 0.0;
        const double tau = SettleBound(*settle, p, cover);
        if (cover > 0.0 && tau > cover) {  // covers its due step: stays linked there
          last_tau[p] = tau;
          last_step[p] = n;
          w_settled[settled++] = p;
          continue;
        }
        if (tau > horizon) {  // NaN: not settled
          last_tau[p] = tau;
          last_step[p] = n;
          UnlinkFrom(slots, nxt, prv, where, p);
          LinkInto(slots, st->ints, m, wheel, p,
                   n + dua_deadline_interval(tau, dt, latency, max_interval, extra));
          w_settled[settled++] = p;
          continue;
        }
      }
      last_tau[p] = kNegInf;
      UnlinkFrom(slots, nxt, prv, where, p);
      where[p] = kTaken;
      w_ids[count++] = p;
    }
  }
  if (st->screen != nullptr) count = ScreenPass(st, n, count, screen);
  for (int64_t k = 0; k < count; ++k) where[w_ids[k]] = -1;  // selected, as DeadlineSelect leaves
  count = DeadlineSelect(v, n, count);
  st->params[kCount] = count;
  st->params[kSettled] = settled;
  return count;
}

int64_t ScreenPass(dua_schedule* st, int64_t n, int64_t count, const dua_step_args* a) {
  dua_screen& s = *st->screen;
  const auto len = static_cast<int64_t>(s.ids.size());
  if (len == 0) return count;
  const double h = st->horizon[0];
  // ScreenClearsRows' conditions on h, once: where they fail, or there is no state to test, nothing
  // is cleared and every screened pair is selected.
  const bool test = a != nullptr && ScreenHorizon(h);
  double* sp = s.spheres.data();
  if (test) {
    // Each sphere's centre and speed once (its row is read in this step's epoch, which the
    // evaluations then share); each pair's test reads two of them, below.
    for (int64_t i = 0; i < s.nsphere; ++i) ScreenRowOf(*a, i, sp + 4 * i);
  }
  // A cleared pair's verdict: its first contact is later than h (Lemma 3.9), so than the next
  // double above it, which the alarm test (tau <= h) does not alarm.
  const double cleared = std::nextafter(h, std::numeric_limits<double>::infinity());
  int64_t* where = st->ints + kWhere * st->m;
  int64_t* last_step = st->ints + kLastStep * st->m;
  int64_t* w_ids = st->work + kWIds * st->width;
  int64_t* ids = s.ids.data();
  int32_t* first = s.first.data();
  int32_t* second = s.second.data();
  double* base = s.base.data();
  int64_t kept = 0;
  for (int64_t k = 0; k < len; ++k) {
    const int64_t p = ids[k];
    if (where[p] != kScreened) continue;  // left the screen since the last test
    const int32_t i = first[k], j = second[k];
    const double b = base[k];
    // Its base is at least kScreenLeastBase (ScreenEnter takes no other): the rest of the test.
    if (test && ScreenedPairClears(sp + 4 * static_cast<int64_t>(i),
                                   sp + 4 * static_cast<int64_t>(j), b, h)) {
      st->last_tau[p] = cleared;
      last_step[p] = n;
      ids[kept] = p, first[kept] = i, second[kept] = j, base[kept] = b;
      ++kept;
    } else {
      where[p] = -1;  // selected; its verdict stays the last test's, of step n - 1
      w_ids[count++] = p;
    }
  }
  s.ids.resize(kept), s.first.resize(kept), s.second.resize(kept), s.base.resize(kept);
  return count;
}

void Unscreen(dua_schedule* st, int64_t n) {
  if (st->screen == nullptr) return;
  dua_screen& s = *st->screen;
  const View v{st};
  for (const int64_t p : s.ids) {
    if (v.Int(kWhere)[p] == kScreened) Link(v, p, n);
  }
  s.ids.clear(), s.first.clear(), s.second.clear(), s.base.clear();
}

// A pair whose wait is longer stays on the wheel: its evaluation every wait (some 60 ns with the
// wheel's upkeep) costs less than the test at every step (a few ns with its spheres' reads).
// Measured (docs/benchmarks.md, screen42): with no limit franka_kitchen's far pairs made its
// step 5 % slower; at 16 it is 4 % faster and dmc_dog, yam and go1 keep their gains.
constexpr int64_t kScreenMostWait = 16;

void ScreenEnter(dua_schedule* st, int64_t n, int64_t count, const dua_step_args& a) {
  dua_screen& s = *st->screen;
  const double h = st->horizon[0];
  int64_t* where = st->ints + kWhere * st->m;
  int64_t* nxt = st->ints + kNext * st->m;
  int64_t* prv = st->ints + kPrev * st->m;
  const int64_t* w_ids = st->work + kWIds * st->width;
  for (int64_t k = 0; k < count; ++k) {
    // A pair in alarm stands until its due step; the others were linked by the reinsertion.
    const int64_t p = w_ids[k];
    if (Alarms(st->w_tau[k], h) || where[p] <= n || where[p] - n > kScreenMostWait) continue;
    const double* rec = a.pairs + p * kPairNcol;
    if (static_cast<int>(rec[kPairKind]) != kKindSphere) continue;
    const int64_t i = static_cast<int64_t>(rec[kPairFirst]);
    const int64_t j = static_cast<int64_t>(rec[kPairSecond]);
    double si[4], sj[4];
    ScreenRowOf(a, i, si);
    ScreenRowOf(a, j, sj);
    // The pair records do not change while the schedule lives (a new held set comes with a new
    // schedule, Runtime::Carry): the bounds' part of the reach is kept.
    const double base = ScreenBase(rec[kPairEps], rec[kPairAccel], rec[kPairDelta], h);
    if (!ScreenClearsRows(si, sj, base, h)) continue;
    UnlinkFrom(st->slots, nxt, prv, where, p);
    where[p] = kScreened;
    s.ids.push_back(p);
    s.first.push_back(static_cast<int32_t>(i));
    s.second.push_back(static_cast<int32_t>(j));
    s.base.push_back(base);
    s.nsphere = std::max(s.nsphere, std::max(i, j) + 1);
  }
  s.spheres.resize(static_cast<size_t>(4 * s.nsphere));
}

void MakeDue(dua_schedule* st, const int64_t* ids, int64_t count, int64_t n) {
  const View v{st};
  // The kind once for the batch (a flagged body's pairs: the check makes many due at once).
  if (st->kind == kRank) {
    for (int64_t k = 0; k < count; ++k) {
      const int64_t p = ids[k];
      if (!st->active[p] || st->last_tau[p] == kNegInf) continue;  // off, or already queued
      st->last_tau[p] = kNegInf;
      st->slots[v.Int(kWhere)[p]] = p;
      Enqueue(st, p);
    }
  } else if (st->kind == kDeadline) {
    for (int64_t k = 0; k < count; ++k) {
      const int64_t p = ids[k];
      if (!st->active[p]) continue;
      st->last_tau[p] = kNegInf;
      Unlink(v, p);
      Link(v, p, n);
    }
  } else {
    for (int64_t k = 0; k < count; ++k) {
      if (st->active[ids[k]]) st->last_tau[ids[k]] = kNegInf;
    }
  }
}

namespace {

// Pairs switched back on evaluated per step beyond the rank schedule's regular slots.
constexpr int64_t kSpare = 256;

int64_t BitLength(int64_t v) {
  int64_t bits = 0;
  while (v > 0) ++bits, v >>= 1;
  return bits;
}

}  // namespace

std::string ScheduleSpec::Check() const {
  auto bad = [](const std::string& name, const std::string& value, const std::string& fix) {
    return name + " = " + value + " is invalid: " + fix;
  };
  if (kind != kRank && kind != kDeadline && kind != kAll) {
    return bad("the schedule's kind", std::to_string(kind), "0 (rank), 1 (deadline), 2 (all)");
  }
  if (!(dt > 0.0) || !std::isfinite(dt)) {
    return bad("the period dt", Shown(dt), "a finite number of seconds > 0");
  }
  if (latency < 0 || latency > (int64_t{1} << 40)) {
    return bad("latency", std::to_string(latency), "an int >= 0 (periods a verdict takes to act)");
  }
  if (slots_per_bucket < 1 || (slots_per_bucket & (slots_per_bucket - 1)) != 0 ||
      slots_per_bucket > (int64_t{1} << 40)) {
    return bad("slots_per_bucket", std::to_string(slots_per_bucket),
               "a power of two (1, 2, 4, 8, ...), so that every revisit interval is exact");
  }
  if (cap < 0) return bad("the evaluation cap", std::to_string(cap), "an int >= 0 (0: none)");
  if (max_interval < 1 || max_interval > (int64_t{1} << 30)) {
    return bad("max_interval", std::to_string(max_interval), "an int in [1, 2^30] (steps)");
  }
  if (backoff < 1) {
    return bad("alarm_backoff", std::to_string(backoff),
               "an int >= 1 (steps; 1 re-evaluates alarmed pairs every step)");
  }
  if (screen != 0 && screen != 1) {
    return bad("screen", std::to_string(screen), "0 or 1 (1: the deadline schedule's screen)");
  }
  if (screen != 0 && kind != kDeadline) {
    return bad("screen", std::to_string(screen), "0 for the rank and select-all schedules");
  }
  if (std::isnan(threshold)) return bad("the select-all threshold", "NaN", "a number");
  if (!(alarm_horizon >= dt && std::isfinite(alarm_horizon))) {
    return bad("alarm_horizon", Shown(alarm_horizon),
               "seconds of warning, at least one period (" + Shown(dt) + " s)");
  }
  return "";
}

void Schedule::Size(int64_t m) {
  const ScheduleSpec& s = spec_;
  int64_t rows = 2, nslots = 0, nqueue = 0, width = m;
  params.assign(kNParams, 0);
  if (s.kind == kRank) {
    // L = ceil(log2(m + 1)) buckets (at least one) of 2^k slots; bucket k's slots are visited
    // every I_k = max(1, 2^k / q) steps.
    int64_t nbuckets = std::max<int64_t>(1, BitLength(m));
    nslots = (int64_t{1} << nbuckets) - 1;
    nqueue = m;
    width = 0;
    horizon.resize(nbuckets);
    for (int64_t k = 0; k < nbuckets; ++k) {
      const int64_t size = int64_t{1} << k;
      width += std::min(s.slots_per_bucket, size);
      horizon[k] = static_cast<double>(Interval(k) + s.latency) * s.dt + Extra();
    }
    width += std::min(m, kSpare);
    params[kParamNBuckets] = nbuckets;
    params[kParamSlotsPerBucket] = s.slots_per_bucket;
  } else if (s.kind == kDeadline) {
    rows = 4;
    nslots = int64_t{1} << BitLength(s.max_interval);  // a power of two > max_interval
    horizon.assign(1, static_cast<double>(1 + s.latency) * s.dt + Extra());
    params[kParamWheel] = nslots;
    params[kParamMaxInterval] = s.max_interval;
    params[kParamCap] = s.cap;
    params[kParamBackoff] = std::min(s.backoff, s.max_interval);
  } else {
    horizon.assign(1, s.threshold);
  }
  width = std::max<int64_t>(width, 1);
  last_tau.assign(m, 0.0);
  active.assign(m, 1);
  ints.assign(static_cast<size_t>(rows * m), s.kind == kDeadline ? -1 : 0);
  slots.assign(nslots, -1);
  queue.assign(nqueue + 1, 0);
  work.assign(static_cast<size_t>(4 * width), 0);
  w_tau.assign(width, 0.0);
  Point();
}

void Schedule::Point() {
  dua_schedule& v = view_;
  v.kind = spec_.kind;
  v.dt = spec_.dt;
  v.latency = spec_.latency;
  v.m = m();
  v.last_tau = last_tau.data();
  v.active = active.data();
  v.ints = ints.data();
  v.slots = slots.data();
  v.nslots = static_cast<int64_t>(slots.size());
  v.horizon = horizon.data();
  v.queue = queue.data();
  v.nqueue = static_cast<int64_t>(queue.size());
  v.params = params.data();
  v.work = work.data();
  v.width = width();
  v.w_tau = w_tau.data();
  v.extra = Extra();
  v.screen = spec_.kind == kDeadline && spec_.screen ? screen.get() : nullptr;
}

Schedule::Schedule(const ScheduleSpec& spec, int64_t m) : spec_(spec) { Size(m); }

Schedule::Schedule(const ScheduleSpec& spec, const std::vector<double>& tau0,
                   const std::vector<uint8_t>& on)
    : spec_(spec) {
  const auto m = static_cast<int64_t>(tau0.size());
  Size(m);
  last_tau = tau0;
  if (!on.empty()) active = on;
  Point();
  if (spec_.kind == kDeadline) {
    std::fill(ints.begin() + m, ints.begin() + 2 * m, 0);  // LAST_STEP: the classification
    dua_deadline_classify(&view_);
  } else if (spec_.kind == kRank) {
    dua_rank_classify(&view_);
  }
}

Schedule::Schedule(const Schedule& other)
    : last_tau(other.last_tau),
      w_tau(other.w_tau),
      horizon(other.horizon),
      active(other.active),
      ints(other.ints),
      slots(other.slots),
      queue(other.queue),
      params(other.params),
      work(other.work),
      step_count(other.step_count),
      activation_changes(other.activation_changes),
      screen(other.screen ? std::make_unique<dua_screen>(*other.screen)
                          : std::make_unique<dua_screen>()),
      spec_(other.spec_) {
  Point();
}

Schedule& Schedule::operator=(const Schedule& other) {
  if (this != &other) *this = Schedule(other);  // the move keeps the buffers it points at
  return *this;
}

std::vector<int64_t> Schedule::InitialAlarms() const {
  std::vector<int64_t> out;
  for (int64_t p = 0; p < m(); ++p) {
    if (Stands(p)) out.push_back(p);
  }
  return out;
}

int64_t Schedule::NextDue(int64_t p) const {
  const int64_t n = step_count + 1, where = ints[kIntWhere * m() + p];
  if (spec_.kind == kDeadline) return where == kScreened ? n : where;
  if (spec_.kind != kRank) return n;
  // RankSelect hands out slot o of bucket k at the steps n with (n q) mod 2^k == o - o mod q.
  const int64_t k = BucketOf(where), size = int64_t{1} << k, q = spec_.slots_per_bucket;
  const int64_t offset = where - (size - 1), interval = Interval(k);
  const int64_t phase = size <= q ? 0 : (offset - offset % q) / q;
  return n + ((phase - n) % interval + interval) % interval;
}

void Schedule::Carry(const Schedule& old, const std::vector<int64_t>& src, int64_t n) {
  params = old.params;
  params[kParamCount] = params[kParamDeferred] = 0;
  step_count = old.step_count;
  activation_changes = old.activation_changes + 1;
  dua_deadline_carry(old.state(), &view_, src.data(), static_cast<int64_t>(src.size()), n);
}

}  // namespace dua

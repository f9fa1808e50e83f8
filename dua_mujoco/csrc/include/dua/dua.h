// dua_mujoco's native core: the predictor's per-step kernels, one implementation shared by the
// runtime (src/runtime.h), which the Python package (through the binding dua_mujoco._core) and
// the MuJoCo plugin run, and C or C++ programs.
//
// Every table is a row-major float64 or int64 array owned by the caller; the structs below only
// point into them. Layouts (columns) are stated once in src/layout.h and documented where the
// Python side packs them: pairs: dua_mujoco/core/pairset.py (pack_pairs), spheres:
// dua_mujoco/build/kinematics.py, shapes: dua_mujoco/core/shapes.py, terrain:
// dua_mujoco/core/terrain.py, exact: dua_mujoco/build/exact.py, events: dua_mujoco/build/events.py,
// the schedule: dua_mujoco/core/schedules/state.py.
#ifndef DUA_MUJOCO_DUA_H_
#define DUA_MUJOCO_DUA_H_

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define DUA_API __attribute__((visibility("default")))

// ABI version of the structs below: the Python side refuses a library of another one.
#define DUA_ABI_VERSION 15

// ------------------------------------------------------------------------------- urgency

// min {t >= 0 : |x + v t| <= eps + delta t + accel t^2 / 2}, never above the exact root.
DUA_API double dua_tau_accel(double x0, double x1, double x2, double v0, double v1, double v2,
                             double eps, double accel, double delta);
// dua_tau_accel, raised by a relative speed bound (inf for none).
DUA_API double dua_tau_speed(double x0, double x1, double x2, double v0, double v1, double v2,
                             double eps, double accel, double delta, double speed);
// min {t >= 0 : gap + (n.v) t - delta t - accel t^2 / 2 <= 0}, never above the exact root.
// dua_tau_speed of n pairs (x, v: (n, 3) row-major) into out: the same values, four pairs at a
// time. Bit k of per_pair says the k-th of eps, accel, delta, speed holds n entries (else one).
DUA_API void dua_tau_speed_batch(int64_t n, const double* x, const double* v, const double* eps,
                                 const double* accel, const double* delta, const double* speed,
                                 int64_t per_pair, double* out);
DUA_API double dua_tau_halfspace(double gap, double normal_velocity, double accel, double delta);

// ------------------------------------------------------------------------------- static shapes

// Support h_S(n) of one packed shape record (16 columns).
DUA_API double dua_support(const double* n, const double* rec);
// Closest point of a shape record to c (c itself inside): out[0:3].
DUA_API void dua_closest_point(const double* c, const double* rec, double* out);
// Clearance along the closest-point direction: out = (gap, nx, ny, nz).
DUA_API void dua_static_gap(const double* c, const double* rec, double* out);
// tau of a sphere (centre c, velocity v) against a static shape record.
DUA_API double dua_tau_static(double c0, double c1, double c2, double v0, double v1, double v2,
                              const double* rec, double eps, double accel, double delta);

// ------------------------------------------------------------------------------- terrain

// A static height field is a shape record of kind 1 (MuJoCo's mjGEOM_HFIELD) followed, after
// every record of the table, by its block: the grid's max pyramid and heights
// (dua_mujoco/core/terrain.py). dua_tau_static, dua_support, dua_closest_point and
// dua_static_gap take such a record too, through a pointer into its table.
//
// tau of an object against the terrain of record rec: shape is a shape record of the object at
// its pose (world), v the velocity its points share, spin the rate their departure from that
// translation may grow at (|w| r), eps the contact distance, accel and delta its bounds.
DUA_API double dua_tau_terrain(const double* rec, const double* shape, const double* v, double spin,
                               double eps, double accel, double delta);
// The first terrain record of a shape table (nrows rows of 16) whose block does not fit the
// table, its header or its grid (what could read out of bounds; other records read their own
// row only); -1 when there is none.
DUA_API int64_t dua_check_shapes(const double* shapes, int64_t nrows);

// ------------------------------------------------------------------------------- schedules

// The deadline schedule's screen (its pairs off the wheel, csrc/src/schedule.h).
struct dua_screen;

typedef struct dua_schedule {
  int64_t kind;      // 0 rank (DUA), 1 deadline, 2 select-all
  double dt;         // predictor period, seconds
  int64_t latency;   // periods a verdict takes to act
  int64_t m;         // pairs
  double* last_tau;  // (m,)
  uint8_t* active;   // (m,) 0/1
  int64_t* ints;     // (rows, m)
  int64_t* slots;    // (nslots,)
  int64_t nslots;
  double* horizon;  // (nhorizon,)
  int64_t* queue;   // (nqueue,)
  int64_t nqueue;
  int64_t* params;  // (9,)
  int64_t* work;    // (4, width)
  int64_t width;
  double* w_tau;  // (width,)
  // The alarm horizon beyond one period (seconds, >= 0): a verdict alarms when it cannot cover
  // the wait until the next one plus this (docs/theory.md, section 3).
  double extra;
  // Deadline: the screen (null: none). Its pairs are in no slot (WHERE -3): each step clears
  // them by a reach test on the state, or selects them (docs/theory.md, section 3, "The screen").
  struct dua_screen* screen;
} dua_schedule;

DUA_API int64_t dua_select(dua_schedule* st, int64_t n);
DUA_API int64_t dua_reinsert(dua_schedule* st, int64_t n, int64_t count);
DUA_API void dua_restore(dua_schedule* st, int64_t n, int64_t count);
DUA_API int64_t dua_switch(dua_schedule* st, const int64_t* ids, int64_t nids, int64_t on,
                           int64_t n_next);
DUA_API void dua_make_due(dua_schedule* st, int64_t p, int64_t n);
DUA_API void dua_deadline_classify(dua_schedule* st);
// The rank schedule's initial classification: slots and WHERE from last_tau (tau0), pairs
// standing in alarm marked in their slots.
DUA_API void dua_rank_classify(dua_schedule* st);
DUA_API void dua_deadline_carry(const dua_schedule* old_state, dua_schedule* new_state,
                                const int64_t* src, int64_t nsrc, int64_t n);
// The deadline schedule's wait after a verdict tau: the largest s in [1, max_interval] with
// (s + latency) dt + extra < tau (1 when there is none: the verdict alarms).
DUA_API int64_t dua_deadline_interval(double tau, double dt, int64_t latency, int64_t max_interval,
                                      double extra);

// ------------------------------------------------------------------------------- the rigid step

// The instant the step reads: MjData's geom_xpos, geom_xmat, cvel, subtree_com, xpos and the
// twists of mocap roots (zero rows elsewhere).
typedef struct dua_frame {
  const double* pos;          // (ngeom, 3)
  const double* mat;          // (ngeom, 9)
  const double* twist;        // (nbody, 6)
  const double* twist_ref;    // (nbody, 3)
  const double* root_twist;   // (nbody, 6)
  const double* root_origin;  // (nbody, 3)
} dua_frame;

// A hull vertex's coordinates in its mesh's frame (MuJoCo's float mesh_vert, which every double
// computed from them reads exactly) and an integer: the first entry of a climb row (dua_exact)
// holds the vertex and its neighbour count, each later one a neighbour and its local id.
typedef struct dua_hull_entry {
  float x, y, z;
  int32_t id;
} dua_hull_entry;

typedef struct dua_exact {
  int64_t on;           // 0: the level is off
  const double* geoms;  // (ngeom, 24)
  double* records;      // (npair, 10), directions written
  // (npair, 6): the witness points of each pair's latest query, each in its geom's frame (first
  // geom, then second; NaN: none yet), written by the level.
  double* witness;
  int64_t queries;     // mj_geomDistance calls so far
  double below;        // seconds
  double query_below;  // seconds
  // Each hull vertex's climb row (mesh geom g's vertex k, in its hull graph's local order: row
  // hull_at[g] + k, hull_at[g] -1 when g has no hull graph): its entries from climb[climb_at[row]],
  // first the vertex and its neighbour count, then each neighbour and its local id, in the order
  // of MuJoCo's graph. A step of the climb reads one row, a few cache lines, where the graph's
  // lists and each neighbour's coordinates would be a line each.
  const int64_t* hull_at;  // (ngeom,)
  const dua_hull_entry* climb;
  const int64_t* climb_at;  // (hull vertices,)
  const void* model;        // mjModel*
  const void* data;         // mjData*
  // MuJoCo's contacts of data, indexed for the pairs the level skips (sorted geom-pair keys
  // min << 32 | max, and each key's least distance): built at the first look of a batch when
  // data has more than a few contacts; room for contact_room entries (0: always scan).
  int64_t* contact_keys;
  double* contact_dist;
  int64_t contact_room;
  int64_t contact_count;  // -1: not built for this batch
} dua_exact;

typedef struct dua_events {
  int64_t nbody;
  const double* rec;       // (nbody, 12)
  double* prev;            // (ceil(nbody / 4), 42, 4): four bodies' column together (the
                           // padding included; dua_reset_events fills it); the check's lanes
                           // run where it is 32-byte aligned, one body at a time elsewhere
  int64_t* meta;           // (3,)
  int64_t* flagged;        // (nbody,)
  const int64_t* start;    // (nbody + 1,)
  const int64_t* members;  // held pairs of each body
  const double* params;    // (h, rtol)
} dua_events;

// A flight plan the step follows (src/plan.h; docs/theory.md, section 8). impl null: none.
typedef struct dua_plan {
  const void* impl;  // the dua::Plan
  int64_t knot;      // the plan's knot at this step
  // (nbody,) 1 for a body the plan holds and found within its deviation so far (static bodies
  // too: planned, with deviation 0); 0 for one it does not know or found beyond its deviation.
  const uint8_t* body_ok;
  // (plan's nrel,) 1 for a relative pair (Plan::relative) found within its relative deviation
  // so far; 0 for one found beyond it (its pairs take D_a + D_b alone). Null: every one
  // within (a candidate plan's, whose bounds are assumed as its bodies' are).
  const uint8_t* rel_ok;
  const int64_t* geom1;  // (npair,) the geoms of each known pair (the plane or static geom second)
  const int64_t* geom2;
  const int* geom_body;     // the model's geom_bodyid
  const int64_t* geom_row;  // (ngeom,) each geom's body's row of the violation check (-1: none)
  void* data;               // an mjData of the model for MuJoCo's distance queries at knots
  uint8_t* planned;         // (batch,) which pairs of a batch the plan covered
  int64_t queries;          // MuJoCo's distance queries at knots so far
  // (K,) what each held pair's latest verdict rested on, and the one before it: bit 0 set when
  // its first geom's side rested on the plan (that body's deviation), bit 1 the same for its
  // second geom; a clear bit is the motion bounds of that body; bit 2 set when it rested on the
  // relative deviation of its two bodies (Lemma 8.2d). Null: not recorded.
  uint8_t* basis;
  uint8_t* basis_prev;
  // (K,) per held pair, the knot at which the latest walk of its knots with both bodies planned
  // ended under the plan as it stands (-1: none): a step at or before it takes it without a
  // walk (docs/theory.md, Lemma 8.2c); -2 - j: no walk under it yet, and its knots before j
  // cleared by the walk under the plan it replaced, so the first walk starts at j (Lemma
  // 8.2e). Null: not kept (a query of another plan).
  int64_t* cleared;
} dua_plan;

// Free spheres (the paper's setting: points on no MuJoCo body): each sphere's centre and velocity
// (nsphere, 3), given by the caller instead of read on the frame. centers null: the frame.
typedef struct dua_points {
  const double* centers;
  const double* velocities;
} dua_points;
// A flight plan as a caller gives it (dua_plugin_set_plan, Runtime::SetPlan).
typedef struct dua_plan_input {
  const double* qpos;       // (n, nq): row j the state at time start + j timestep
  int64_t n;                // knots
  const double* deviation;  // (n, nbody): how far any point of each body may stray at each knot
  double start;             // the time of row 0's state
  // (nbody,) 1 for the bodies the plan holds, null for the default: every moving body outside
  // mocap trees, and the mocap trees too when mocap poses are given. Bodies it does not hold
  // follow their motion bounds; static bodies are always planned (deviation 0).
  const uint8_t* bodies;
  const double* mocap_pos;   // (n, nmocap, 3), or null: mocap bodies unplanned
  const double* mocap_quat;  // (n, nmocap, 4), or null (then mocap_pos must be null too)
  // Relative deviations (docs/theory.md, Lemma 8.2d), for pairs of two bodies the plan holds:
  // nrel body pairs (a, b), a < b (relative_bodies (nrel, 2)), and relative_deviation (n, nrel),
  // a bound on how far any point of b's box may stray, in a's frame, from where the plan puts it
  // relative to a. A pair of geoms on a and b then takes min(D_a + D_b, D_ab) off its planned
  // gap. nrel 0 (both null): none.
  int64_t nrel;
  const int64_t* relative_bodies;
  const double* relative_deviation;
} dua_plan_input;

typedef struct dua_step_args {
  int64_t abi;  // DUA_ABI_VERSION
  dua_schedule schedule;
  const double* pairs;    // (K, 8)
  const double* spheres;  // (nsphere, 8)
  const double* shapes;   // (nshape, 16)
  const int64_t* ids;     // (K,) model pair id of each held pair
  dua_frame frame;
  dua_points points;  // free spheres' states (centers null: read on the frame)
  dua_exact exact;
  dua_events events;
  // Each sphere's state (centre, velocity) read once per batch of pairs: point_state (nsphere,
  // 6) and point_epoch (nsphere,), 2 x the batch that wrote each row, plus 1 where its six
  // numbers are tame (finite, at most 1e300 in magnitude); epoch counts the batches (each
  // dua_step or dua_evaluate adds one). Start point_epoch below 2 x epoch (-1 and 0), and
  // never share the two arrays between two structs (two MjData).
  double* point_state;
  int64_t* point_epoch;
  int64_t epoch;
  // The alarm log the step appends to.
  int64_t* log_pairs;
  double* log_tau;
  uint8_t* log_new;
  // Outputs of the latest step.
  int64_t bad;       // >= 0: a held pair whose state was not finite (the step was undone)
  int64_t deferred;  // pairs left over the cap
  int64_t count;     // pairs evaluated
  dua_plan plan;
  // The predictor's grid: a step every `period` physics steps of `timestep` seconds (free
  // spheres: one step of the period). Every tau the schedule acts on is rounded down to it
  // (docs/theory.md, section 8).
  double timestep;
  int64_t period;
  // 1: the step may screen (a deadline schedule with a screen, on the frame, no plan, period 1:
  // dua_step checks those); 0 sends every screened pair to the wheel at its next step (the
  // runtime clears it while it watches pairs for the shield, whose expiry needs their taus).
  int64_t screen;
} dua_step_args;

// One step n: the violation check, the selection, the gather, tau at every level, the
// reinsertion; alarms appended to the log at `start`. Returns the number of alarms, or -1 - p
// for a held pair p whose state was not finite (the step undone, nothing logged; a->bad = p).
DUA_API int64_t dua_step(dua_step_args* a, int64_t n, int64_t start);
// tau of held pairs ids[0:count] on the frame (every level, as the step computes it) into out;
// returns -1, or a pair whose state was not finite.
DUA_API int64_t dua_evaluate(dua_step_args* a, const int64_t* ids, int64_t count, double* out);
// The exact level alone: tau[k] of held pairs ids[k] raised to max(tau[k], exact) where it is
// below exact.below (dua_evaluate and dua_step run it after the sphere level).
DUA_API void dua_exact_pass(dua_step_args* a, const int64_t* ids, int64_t count, double* tau);
// Index n held pairs by the violation check's rows: pair k has geoms geom1[k], geom2[k] (-1:
// none), geom g the row row_of_geom[g] (-1: not checked); start (nrow + 1,) and members
// (2 n,) receive, for each row, the pairs with a geom on it, first by geom1 then by geom2, each
// in increasing k (a counting sort). Returns the number of members.
DUA_API int64_t dua_index_by_row(const int64_t* row_of_geom, const int64_t* geom1,
                                 const int64_t* geom2, int64_t n, int64_t nrow, int64_t* start,
                                 int64_t* members);
// Record the events check's state at the frame's instant, checking nothing. Also copies each
// body's box and bounds from events.rec into its state (columns 31..39) and the places of its
// inputs in the frame (columns 40..41), the last group's padding as its last body: run it before
// the first check, and again whenever events.rec or events.prev are bound anew. A check without
// it reads boxes and bounds of zero at the places of geom, body and root 0, and flags nothing
// where those do not move.
DUA_API void dua_reset_events(dua_step_args* a);
// The violation check alone, four bodies at a time (lanes != 0, as the step runs it) or one at a
// time: the reference the lanes are held to (tests). Returns the number of bodies flagged.
DUA_API int64_t dua_check_bodies(dua_step_args* a, int64_t lanes);
// Whether max |a + s0 x + s1 y + s2 z| over the sign choices s exceeds bound (the violation
// check's test of a box's eight corners).
DUA_API int64_t dua_exceeds12(double a0, double a1, double a2, double x0, double x1, double x2,
                              double y0, double y1, double y2, double z0, double z1, double z2,
                              double bound);
// tau of pairs ids[0:count] (pair records (K, 8)) on free spheres: centres and velocities
// (nsphere, 3), half-spaces planes (nplane, 4) (unit normal, offset; a pair's second member is
// its row), static shape records (nshape, 16). The same values as
// the step computes from MjData. Returns -1, or the first k whose state is not finite.
DUA_API int64_t dua_tau_free(const double* pairs, const double* shapes, const double* centers,
                             const double* velocities, const double* planes, const int64_t* ids,
                             int64_t count, double* out);
// Centre and velocity of sphere i: out[0:6].
DUA_API void dua_rigid_point(int64_t i, const double* spheres, const dua_frame* f, double* out);
// The same as the step reads it: a->points' row i for free spheres, else dua_rigid_point on
// a->frame.
DUA_API void dua_point(const dua_step_args* a, int64_t i, double* out);

// The run monitor's bound check over n points (sphere records (n, 8) on frame f): rows of prev
// and cur (n, 9) are [centre, velocity read, discrete velocity (c - c_prev) / h]; cur is written.
// nprev earlier updates (0, 1, 2+) are reflected in prev. values (n, 3) receive the chord speed,
// the one-step discrepancy |u - w_prev| and the discrete acceleration |u - u_prev| / h; broken
// (n, 3) which exceeded their bounds (accel, disc_bound (n,), speed_bound (n,) or null for none;
// the discrepancy only where check_disc[i]), with a relative tolerance rtol and the round-off of
// the differences. Returns how many (point, check) broke.
DUA_API int64_t dua_check_points(const double* points, int64_t n, const dua_frame* f,
                                 const double* prev, double* cur, int64_t nprev, double h,
                                 const double* accel, const double* disc_bound,
                                 const double* speed_bound, const uint8_t* check_disc, double rtol,
                                 double* values, uint8_t* broken);
// dua_check_points of the points in groups (group_start (ngroup + 1,): group g is points
// group_start[g] .. group_start[g + 1] - 1; groups (ngroup, kGroupNcol): a ball in the frame
// holding its points, and the frame, body, root and bounds they all share), screened: from the
// third update on (nprev 2) a group whose motion over the last three updates keeps every point of
// its ball within the bounds by more than the rounding is not measured (its broken rows are
// cleared; its rows and values are left as they were), and the others are, with the same flags
// and values as dua_check_points (docs/theory.md, "The monitor's screen"). frames (ngroup, 2,
// 30): the frame rows each group read at the last two updates (slot update % 2 written), from
// which a group's skipped rows are rebuilt; computed (ngroup,): the last update that measured
// each group (start at -1). h_prev: the h of the previous update.
DUA_API int64_t dua_check_groups(const double* points, const dua_frame* f,
                                 const int64_t* group_start, const double* groups, int64_t ngroup,
                                 double* frames, int64_t* computed, int64_t update, double* prev,
                                 double* cur, int64_t nprev, double h, double h_prev,
                                 const double* accel, const double* disc_bound,
                                 const double* speed_bound, const uint8_t* check_disc, double rtol,
                                 double* values, uint8_t* broken);

// Backward-difference velocities of mocap bodies bodies[0:n] (poses xpos (nbody, 3), xquat
// (nbody, 4)) against prev_pos (n, 3), prev_quat (n, 4), which are updated; linear and angular
// (n, 3) are written where user[i] is 0; twist (ntwist = nbody, 6), if ntwist > 0, receives
// [angular; linear] in the bodies' rows.
DUA_API void dua_difference_poses(const double* xpos, const double* xquat, const int64_t* bodies,
                                  int64_t n, double* prev_pos, double* prev_quat, double dt,
                                  const uint8_t* user, double* linear, double* angular,
                                  double* twist, int64_t ntwist);

DUA_API int64_t dua_abi_version(void);

// The columns and codes of the record tables the Python side packs (src/layout.h), by the
// Python side's names: entry i's name (NULL past the last) and value (-1 past the last).
DUA_API const char* dua_layout_name(int64_t i);
DUA_API int64_t dua_layout_value(int64_t i);

// ------------------------------------------------------------------------------- pair tables

// The sphere pairs of geom pairs k = (g1[k], g2[k]) (index[k] their ids, dist[k] their contact
// distances), grouped by geom pair: a geom held as a plane (plane[g] >= 0, its half-space
// index) or a static shape (shape[g] >= 0, its record) pairs as that one object with every
// sphere of the other geom, which comes first; otherwise every sphere of g1 with every sphere of
// g2 (start: each geom's first sphere, ngeom + 1 entries). Up to capacity rows of first, second
// (a sphere, plane or shape index), kind (0 sphere, 1 half-space, 2 shape), geom_pair and eps
// (r1 + r2 + d, or r + d); returns how many pairs there are.
DUA_API int64_t dua_sphere_pairs(const int64_t* g1, const int64_t* g2, const double* dist,
                                 const int64_t* index, int64_t ngp, const int64_t* start,
                                 const int64_t* plane, const int64_t* shape, const double* radius,
                                 int64_t capacity, int64_t* first, int64_t* second, int8_t* kind,
                                 int64_t* geom_pair, double* eps);
// The margin and gap MuJoCo gives the dynamic geom pairs (g1[k], g2[k]): the sums of the two
// geoms' (the margin o_margin instead under override_margin, mjENBL_OVERRIDE).
DUA_API void dua_contact_distance(const double* gmargin, const double* ggap, const int64_t* g1,
                                  const int64_t* g2, int64_t n, int64_t override_margin,
                                  double o_margin, double* margin, double* gap);
// Each pair's bounds: the sums of its two bodies' acceleration bounds, velocity uncertainties
// and (speed not null) speed bounds, a plane or static shape being the world body's (its speed
// bound: the sphere's alone); without speed bounds, inf.
DUA_API void dua_pair_bounds(const int64_t* first, const int64_t* second, const int8_t* kind,
                             int64_t n, const int64_t* sphere_body, const double* accel,
                             const double* delta, const double* speed, double* out_accel,
                             double* out_delta, double* out_speed);
// The exact level's records (n, 10) of pairs with geoms geom1, geom2 (a half-space pair's plane
// geom second), over its per-geom records geoms (ngeom, 24).
DUA_API void dua_exact_rows(const double* geoms, const int64_t* geom1, const int64_t* geom2,
                            const int8_t* kind, const double* dist, int64_t n, double* out);

// ------------------------------------------------------------------------------- the pair filter

// Per geom, what MuJoCo's dynamic pair filter reads (dua_mujoco/build/pairfilter.py, FilterTables).
typedef struct dua_filter {
  int64_t ngeom;
  const int64_t* body;         // (ngeom,) geom body
  const int64_t* weld;         // (ngeom,) weld group of that body
  const int64_t* parent_weld;  // (ngeom,) weld group of the parent of the weld root
  const uint8_t* movable;      // (ngeom,) the weld group has degrees of freedom
  const int64_t* contype;      // (ngeom,)
  const int64_t* conaffinity;  // (ngeom,)
  const uint8_t* lone;         // (ngeom,) plane or height field
  const int64_t* exclude;      // (nexclude,) sorted <exclude> body-pair signatures
  int64_t nexclude;
  int64_t filterparent;  // the parent filter is on
} dua_filter;

// out[k] = whether geom pair (g1[k], g2[k]) passes (a geom with itself never); returns how many.
DUA_API int64_t dua_filter_mask(const dua_filter* f, const int64_t* g1, const int64_t* g2,
                                int64_t n, uint8_t* out);
// Every pair g1 < g2 that passes, sorted, up to capacity into g1, g2; returns how many.
DUA_API int64_t dua_filter_all(const dua_filter* f, int64_t* g1, int64_t* g2, int64_t capacity);
// How many pairs pass; weighted receives the sum over them of weight[g1] weight[g2].
DUA_API int64_t dua_filter_count(const dua_filter* f, const int64_t* weight, int64_t* weighted);
// Whether any pair passes (stops at the first).
DUA_API int64_t dua_filter_any(const dua_filter* f);

// ------------------------------------------------------------------------------- candidate pairs

// The hashed grid behind candidate pairs of reachable balls: every pair i < j of n spheres with
// |c_i - c_j|^2 <= ((reach_i + reach_j) + margin)^2 (1 + 2^-44), sorted (contract and proof:
// src/grid.cc). Every buffer is the caller's: dua_grid_bounds, then
// dua_grid_plan_of (n >= 2), then buffers of the plan's sizes, dua_grid_count (K pairs), then
// dua_grid_fill into K more.
typedef struct dua_grid_plan {
  double lo[3];     // the grid's origin
  double h;         // cell edge
  int64_t mask[3];  // 2^bits - 1 of each axis of the bucket map
  int64_t shift_y;  // bits of x
  int64_t shift_z;  // bits of x and y
  int64_t wrap[3];  // axes wrapped onto the torus
  int64_t nbucket;  // buckets, 2^(bits of x, y, z)
  int64_t nheld;    // spheres held out of the grid (tested against every sphere)
  double rcut;      // the largest reach in the grid
} dua_grid_plan;

typedef struct dua_grid_work {
  int32_t* start;    // (nbucket + 1,)
  int32_t* sid;      // (n - nheld,)
  double* sxyz;      // (n - nheld, 3)
  double* sr;        // (n - nheld,)
  int64_t* cnt_a;    // (n,)
  int64_t* cnt_b;    // (n,)
  int32_t* found;    // (n,)
  uint8_t* is_held;  // (n,)
} dua_grid_work;

// Bounding box of n centres into lo[3], hi[3]; returns the first row with a coordinate that is
// NaN, inf or beyond 1e150 in magnitude, or -1.
DUA_API int64_t dua_grid_bounds(const double* centers, int64_t n, double* lo, double* hi);
// The grid of n >= 2 spheres within bounds lo, hi: held (256,) receives the sorted ids held out
// of it; work (n,) is scratch.
DUA_API void dua_grid_plan_of(const double* reach, int64_t n, double margin, const double* lo,
                              const double* hi, dua_grid_plan* plan, int64_t* held, double* work);
// Sort the spheres into the grid and count the pairs: returns K.
DUA_API int64_t dua_grid_count(const dua_grid_plan* plan, const double* centers,
                               const double* reach, int64_t n, double margin, const int64_t* held,
                               const dua_grid_work* work);
// Write the K pairs counted by dua_grid_count (same arguments) as rows of out (K, 2); tmp (K,).
DUA_API void dua_grid_fill(const dua_grid_plan* plan, const double* centers, const double* reach,
                           int64_t n, double margin, const int64_t* held, const dua_grid_work* work,
                           int32_t* tmp, int64_t* out);

// ------------------------------------------------------------------------------- pruned pairs

// A pruned predictor's reach (docs/many-objects.md): each sphere's anchor, the centre and
// measured speed the held set assumed for it from step built[i], and its reach r_i + R_i(T)
// from there.
typedef struct dua_reach {
  int64_t nsphere;
  const double* radius;         // (nsphere,)
  const int64_t* body_start;    // (nbody + 1,): body b's spheres are body_spheres[start[b]:]
  const int64_t* body_spheres;  // (nsphere,)
  const double* accel;          // (nsphere,) acceleration bound of each sphere's centre
  const double* delta;          // (nsphere,) velocity uncertainty
  const double* speed;          // (nsphere,) speed bound (inf: none)
  double* anchor;               // (nsphere, 3)
  double* speed0;               // (nsphere,)
  double* reach;                // (nsphere,)
  int64_t* built;               // (nsphere,) step of each anchor
  double dt;                    // seconds a step
  double horizon;               // T, seconds
  double margin;                // largest contact distance beyond the radii
} dua_reach;

// Reaches out[i] = radius[i] + min((speed[i] + delta[i]) T + accel[i] T^2 / 2, vmax[i] T) of n
// spheres over horizon T (vmax inf: no speed bound).
DUA_API void dua_reaches(const double* radius, const double* speed, const double* accel,
                         const double* delta, const double* vmax, int64_t n, double horizon,
                         double* out);
// Anchor spheres ids[0:n] anew at their state (dua_point), step `step` (their reach over the
// horizon from there), and find their candidate pairs as dua_reach_pairs does. Returns the
// number of pairs, or -1 - k if the state of ids[k] is not finite (nothing anchored).
DUA_API int64_t dua_renew(const dua_step_args* a, dua_reach* r, const int64_t* ids, int64_t n,
                          int64_t step, int64_t* out, int64_t capacity);

// Of spheres ids[0:n] at centres (n, 3) and measured velocities (n, 3), elapsed[k] seconds after
// their anchors, the ones that may have left their reach (Lemma 6.4 of docs/theory.md) into
// out; returns how many.
DUA_API int64_t dua_escapes(const dua_reach* r, const int64_t* ids, int64_t n,
                            const double* centers, const double* velocities, const double* elapsed,
                            int64_t* out);
// The same for every sphere of the bodies the latest violation pass of a flagged, read on a's
// frame at step `step` (free spheres, which have no violation pass: every sphere, read from
// a->points): out (nsphere,) receives the escaped spheres; returns how many.
DUA_API int64_t dua_escaped_spheres(const dua_step_args* a, const dua_reach* r, int64_t step,
                                    int64_t* out);
// Of escaped spheres ids[0:n] at step `step`, the first whose state proves its bounds broken since
// its anchor (a centre beyond its reach, or a measured speed above min(s0 + 2 delta + A t,
// V + delta), by more than rounding), or -1: an escape short of that may be a motion within the
// bounds (docs/theory.md, "The escape test, once").
DUA_API int64_t dua_proven_broken(const dua_step_args* a, const dua_reach* r, const int64_t* ids,
                                  int64_t n, int64_t step);
// Candidate pairs of spheres ids[0:n] against every sphere by their anchors and reaches: the
// pairs (i < j) with |c_i - c_j|^2 <= ((reach_i + reach_j) + margin)^2 (1 + 2^-44), each once,
// written as rows of out (capacity rows of 2); returns how many there are (more than capacity:
// call again with room for them). Time O(n nsphere).
DUA_API int64_t dua_reach_pairs(const dua_reach* r, const int64_t* ids, int64_t n, int64_t* out,
                                int64_t capacity);

// ------------------------------------------------------------------------------- the plugin

struct mjModel_;
struct mjData_;

// Follow a flight plan in instance `instance` of d (docs/plans.md): the plan (its bodies, their
// deviations, mocap poses if any). departures (nbody,) or null receives, for each body the
// replaced plan held, the first state time at which the new plan leaves the old plan's
// deviation tube within the span the old plan's verdicts cover (+inf: never; docs/theory.md,
// section 8). Returns 0, -1 if the instance is not this plugin's, -2 before its first compute,
// -3 if the plan is refused (why written to error, error_size bytes with the terminating 0).
DUA_API int64_t dua_plugin_set_plan(const struct mjModel_* m, struct mjData_* d, int instance,
                                    const dua_plan_input* plan, double* departures, char* error,
                                    int64_t error_size);
// Back to the motion bounds alone. Returns 0, or -1 if the instance is not this plugin's.
DUA_API int64_t dua_plugin_clear_plan(const struct mjModel_* m, struct mjData_* d, int instance);

// Geom pairs standing in alarm in instance `instance` of the sensor plugin
// "dua_mujoco.predictor" in d: up to `capacity` rows (g1, g2) into out; returns how many there
// are (-1: the instance is not this plugin's).
DUA_API int64_t dua_plugin_standing(const struct mjModel_* m, const struct mjData_* d, int instance,
                                    int64_t* out, int64_t capacity);
// What instance `instance` of d knows (issue 35: bounded over a run): out receives, up to
// `capacity` values, the sphere pairs known, the geom pairs known, the pairs held, the geom pairs
// forgotten so far, the compactions, then the known geom pairs as rows (g1, g2) in increasing
// order; returns how many values there are (-1: the instance is not this plugin's).
DUA_API int64_t dua_plugin_memory(const struct mjModel_* m, const struct mjData_* d, int instance,
                                  int64_t* out, int64_t capacity);
// Switches the pairs between bodies body_a and body_b (body_b < 0: every pair of body_a) off
// (on = 0) or back on; returns the number of sphere pairs between them, -1 if the instance is
// not this plugin's, -2 before its first compute.
DUA_API int64_t dua_plugin_set_active(const struct mjModel_* m, struct mjData_* d, int instance,
                                      int body_a, int body_b, int on);
// Switches off the pairs of every geom pair in contact in d; returns how many geom pairs (-1:
// not this plugin's instance, -2: before its first compute).
DUA_API int64_t dua_plugin_deactivate_contacts(const struct mjModel_* m, struct mjData_* d,
                                               int instance);

#ifdef __cplusplus
}
#endif

#endif  // DUA_MUJOCO_DUA_H_

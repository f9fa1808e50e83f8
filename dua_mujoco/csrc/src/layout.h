// The records and state the Python side packs and the native code reads by column: pairs,
// spheres, static shapes, the exact level, the schedule's state. Stated once for C++ (the
// violation check's are in internal.h, the plugin's config row in plugin_tables.h). Python
// states them in dua_mujoco/core/pairset.py, core/shapes.py, core/schedules/state.py,
// build/kinematics.py, build/exact.py, build/events.py and plugin.py; dua_layout_name and
// dua_layout_value (layout.cc) export all of them by Python's names, and tests/test_layout.py
// holds the two statements to each other.
#ifndef DUA_MUJOCO_LAYOUT_H_
#define DUA_MUJOCO_LAYOUT_H_

#include <cstdint>

namespace dua {

// Pair records (pack_pairs), and what a pair's second member is (PairKind).
constexpr int kPairFirst = 0, kPairSecond = 1, kPairKind = 2, kPairEps = 3, kPairAccel = 4,
              kPairDelta = 5, kPairSpeed = 6, kPairOther = 7, kPairNcol = 8;
constexpr int kKindSphere = 0, kKindHalfspace = 1, kKindShape = 2;

// Sphere records (pack_spheres); the offset takes three columns.
constexpr int kSphereFrame = 0, kSphereBody = 1, kSphereOffset = 2, kSphereRoot = 5,
              kSphereNcol = 8;

// The screened bound check's group records (build/kinematics.py's point groups): a ball holding
// the group's points in their frame (centre, radius), the frame, body and root they share, and
// their bounds (speed inf: none).
constexpr int kGroupCentre = 0, kGroupRadius = 3, kGroupFrame = 4, kGroupBody = 5, kGroupRoot = 6,
              kGroupAccel = 7, kGroupDisc = 8, kGroupSpeed = 9, kGroupNcol = 10;

// Static shape records (pack_shapes), and their kinds (ShapeKind: MuJoCo's geom types).
constexpr int kShapeKind = 0, kShapeSize = 1, kShapePos = 4, kShapeMat = 7, kShapeNcol = 16;
// A mesh is held as its box (kind 7, MuJoCo's mesh code).
constexpr int kGeomSphere = 2, kGeomCapsule = 3, kGeomEllipsoid = 4, kGeomCylinder = 5,
              kGeomBox = 6, kGeomMeshBox = 7;

// A height field held as terrain (terrain.cc, dua_mujoco/core/terrain.py): a shape record of kind
// kGeomHField whose size columns give the rows from the record to its block (in the same table,
// after every record) and the block's length in rows; the block's header (kTer*: half sizes,
// base, grid, levels, where the heights start, the largest |height|), then the cell maxima of
// every level of its max pyramid from kTerHeader on, then the heights.
constexpr int kGeomHField = 1;
constexpr int kTerrainBlock = kShapeSize, kTerrainRows = kShapeSize + 1;
constexpr int kTerRx = 0, kTerRy = 1, kTerBase = 2, kTerNrow = 3, kTerNcol = 4, kTerLevels = 5,
              kTerHeights = 6, kTerHabs = 7, kTerHeader = 16;

// The static guard's records (StaticRecords, tables.h): each static shape's geom, its pose as
// mj_kinematics places it (position, rotation matrix), its geom_size, and a 64-bit digest (two
// 32-bit halves) of what else its record was built from: a height field's size, grid and
// heights, a mesh's geom_aabb and vertices (0 for the other kinds).
constexpr int kStaticGeom = 0, kStaticPos = 1, kStaticMat = 4, kStaticSize = 13, kStaticDigest = 16,
              kStaticNcol = 18;

// The exact level: per-geom records (the first eight are a sphere record of the geom origin),
// per-pair records (the direction that served last, from kXN; the hull vertices highest last
// time, per side), and what the level does for a pair (ExactMode).
constexpr int kGxKind = 8, kGxSize = 9, kGxCentre = 12, kGxRadius = 15, kGxVert = 16, kGxGraph = 17,
              kGxSeed = 18, kGxNcol = 24;
constexpr int kXMode = 0, kXG1 = 1, kXG2 = 2, kXDist = 3, kXN = 4, kXHull1 = 7, kXHull2 = 8,
              kXNcol = 10;
constexpr int kModeNone = 0, kModeGeoms = 1, kModePlane = 2, kModeShape = 3, kModeTerrain = 4;

// The schedule's state (ScheduleState): its kinds (the select-all kind has no name of its own
// here), its rows of ints and of work, and the entries of its params.
constexpr int64_t kRank = 0, kDeadline = 1;
// Prefixed, being common words: schedule.cc names them shorter.
constexpr int64_t kIntWhere = 0, kIntLastStep = 1, kIntNext = 2, kIntPrev = 3;
// The deadline wheel's WHERE of a pair on its screen (in no slot; docs/theory.md, section 3,
// "The screen").
constexpr int64_t kScreened = -3;
constexpr int64_t kWorkSlots = 0, kWorkIds = 1, kWorkAlarms = 2, kWorkNew = 3;
constexpr int64_t kParamNBuckets = 0, kParamSlotsPerBucket = 1, kParamWheel = 2,
                  kParamMaxInterval = 3, kParamCap = 4, kParamCount = 5, kParamDeferred = 6,
                  kParamExtra = 7, kParamBackoff = 8, kParamSettled = 9, kNParams = 10;

}  // namespace dua

#endif  // DUA_MUJOCO_LAYOUT_H_

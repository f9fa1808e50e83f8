// The record layouts of layout.h, the violation check's of internal.h and the tables' config row
// of tables.h, by the names the Python side reads them by (dua_mujoco._core.LAYOUT).
#include "layout.h"

#include "dua/dua.h"
#include "internal.h"
#include "tables.h"

namespace {

struct Entry {
  const char* name;
  int64_t value;
};

constexpr Entry kEntries[] = {
    {"PAIR_FIRST", dua::kPairFirst},
    {"PAIR_SECOND", dua::kPairSecond},
    {"PAIR_KIND", dua::kPairKind},
    {"PAIR_EPS", dua::kPairEps},
    {"PAIR_ACCEL", dua::kPairAccel},
    {"PAIR_DELTA", dua::kPairDelta},
    {"PAIR_SPEED", dua::kPairSpeed},
    {"PAIR_OTHER", dua::kPairOther},
    {"PAIR_NCOL", dua::kPairNcol},
    {"PairKind.SPHERE", dua::kKindSphere},
    {"PairKind.HALFSPACE", dua::kKindHalfspace},
    {"PairKind.SHAPE", dua::kKindShape},
    {"SPHERE_FRAME", dua::kSphereFrame},
    {"SPHERE_BODY", dua::kSphereBody},
    {"SPHERE_OFFSET", dua::kSphereOffset},
    {"SPHERE_ROOT", dua::kSphereRoot},
    {"SPHERE_NCOL", dua::kSphereNcol},
    {"SHAPE_KIND", dua::kShapeKind},
    {"SHAPE_SIZE", dua::kShapeSize},
    {"SHAPE_POS", dua::kShapePos},
    {"SHAPE_MAT", dua::kShapeMat},
    {"SHAPE_NCOL", dua::kShapeNcol},
    {"ShapeKind.SPHERE", dua::kGeomSphere},
    {"ShapeKind.CAPSULE", dua::kGeomCapsule},
    {"ShapeKind.ELLIPSOID", dua::kGeomEllipsoid},
    {"ShapeKind.CYLINDER", dua::kGeomCylinder},
    {"ShapeKind.BOX", dua::kGeomBox},
    {"ShapeKind.MESH_BOX", dua::kGeomMeshBox},
    {"ShapeKind.HFIELD", dua::kGeomHField},
    {"TERRAIN_BLOCK", dua::kTerrainBlock},
    {"TERRAIN_ROWS", dua::kTerrainRows},
    {"T_RX", dua::kTerRx},
    {"T_RY", dua::kTerRy},
    {"T_BASE", dua::kTerBase},
    {"T_NROW", dua::kTerNrow},
    {"T_NCOL", dua::kTerNcol},
    {"T_LEVELS", dua::kTerLevels},
    {"T_HEIGHTS", dua::kTerHeights},
    {"T_HABS", dua::kTerHabs},
    {"T_HEADER", dua::kTerHeader},
    {"GX_KIND", dua::kGxKind},
    {"GX_SIZE", dua::kGxSize},
    {"GX_CENTRE", dua::kGxCentre},
    {"GX_RADIUS", dua::kGxRadius},
    {"GX_VERT", dua::kGxVert},
    {"GX_GRAPH", dua::kGxGraph},
    {"GX_SEED", dua::kGxSeed},
    {"GX_NCOL", dua::kGxNcol},
    {"X_MODE", dua::kXMode},
    {"X_G1", dua::kXG1},
    {"X_G2", dua::kXG2},
    {"X_DIST", dua::kXDist},
    {"X_N", dua::kXN},
    {"X_HULL1", dua::kXHull1},
    {"X_HULL2", dua::kXHull2},
    {"X_NCOL", dua::kXNcol},
    {"ExactMode.NONE", dua::kModeNone},
    {"ExactMode.GEOMS", dua::kModeGeoms},
    {"ExactMode.PLANE", dua::kModePlane},
    {"ExactMode.SHAPE", dua::kModeShape},
    {"ExactMode.TERRAIN", dua::kModeTerrain},
    {"B_FRAME", dua::kBFrame},
    {"B_BODY", dua::kBBody},
    {"B_ROOT", dua::kBRoot},
    {"B_CENTER", dua::kBCenter},
    {"B_HALF", dua::kBHalf},
    {"B_ACCEL", dua::kBAccel},
    {"B_DISC", dua::kBDisc},
    {"B_SPEED", dua::kBSpeed},
    {"NB_REC", dua::kBNcol},
    {"NB_STATE", dua::kSNcol},
    {"STATE_GROUP", dua::kLanes},
    {"M_NPREV", dua::kMNprev},
    {"M_COUNT", dua::kMCount},
    {"M_TOTAL", dua::kMTotal},
    {"RANK", dua::kRank},
    {"DEADLINE", dua::kDeadline},
    {"WHERE", dua::kIntWhere},
    {"LAST_STEP", dua::kIntLastStep},
    {"NEXT", dua::kIntNext},
    {"PREV", dua::kIntPrev},
    {"W_SLOTS", dua::kWorkSlots},
    {"W_IDS", dua::kWorkIds},
    {"W_ALARMS", dua::kWorkAlarms},
    {"W_NEW", dua::kWorkNew},
    {"P_NBUCKETS", dua::kParamNBuckets},
    {"P_SLOTS_PER_BUCKET", dua::kParamSlotsPerBucket},
    {"P_WHEEL", dua::kParamWheel},
    {"P_MAX_INTERVAL", dua::kParamMaxInterval},
    {"P_CAP", dua::kParamCap},
    {"P_COUNT", dua::kParamCount},
    {"P_DEFERRED", dua::kParamDeferred},
    {"P_EXTRA", dua::kParamExtra},
    {"P_BACKOFF", dua::kParamBackoff},
    {"NPARAMS", dua::kNParams},
    {"CFG_VERSION", dua::kCfgVersion},
    {"CFG_KIND", dua::kCfgKind},
    {"CFG_DT", dua::kCfgDt},
    {"CFG_LATENCY", dua::kCfgLatency},
    {"CFG_SLOTS_PER_BUCKET", dua::kCfgSlotsPerBucket},
    {"CFG_CAP", dua::kCfgCap},
    {"CFG_MAX_INTERVAL", dua::kCfgMaxInterval},
    {"CFG_BACKOFF", dua::kCfgBackoff},
    {"CFG_THRESHOLD", dua::kCfgThreshold},
    {"CFG_TIMESTEP", dua::kCfgTimestep},
    {"CFG_EXACT_ON", dua::kCfgExactOn},
    {"CFG_EXACT_BELOW", dua::kCfgExactBelow},
    {"CFG_QUERY_BELOW", dua::kCfgQueryBelow},
    {"CFG_NGEOM", dua::kCfgNgeom},
    {"CFG_NBODY", dua::kCfgNbody},
    {"CFG_SHAPE", dua::kCfgShape},
    {"CFG_PRUNED", dua::kCfgPruned},
    {"CFG_HORIZON", dua::kCfgHorizon},
    {"CFG_MARGIN", dua::kCfgMargin},
    {"CFG_STRIDE", dua::kCfgStride},
    {"CFG_RENEW_MAX", dua::kCfgRenewMax},
    {"CFG_CONTACTS", dua::kCfgContacts},
    {"CFG_FILTER_PARENT", dua::kCfgFilterParent},
    {"CFG_OVERRIDE", dua::kCfgOverride},
    {"CFG_O_MARGIN", dua::kCfgOMargin},
    {"CFG_HAS_SPEED", dua::kCfgHasSpeed},
    {"CFG_ALARM_HORIZON", dua::kCfgAlarmHorizon},
    {"CFG_SIZE", dua::kCfgSize},
};
constexpr int64_t kNEntries = sizeof(kEntries) / sizeof(kEntries[0]);

}  // namespace

extern "C" {

const char* dua_layout_name(int64_t i) {
  return i >= 0 && i < kNEntries ? kEntries[i].name : nullptr;
}

int64_t dua_layout_value(int64_t i) { return i >= 0 && i < kNEntries ? kEntries[i].value : -1; }

}  // extern "C"

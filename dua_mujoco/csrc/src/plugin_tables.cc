// Reading the plugin's tables (plugin_tables.h): each is its entry count, a space, then the
// entries' little-endian float64 bytes in base64, which survive an XML round trip exactly
// (MuJoCo writes numeric fields with six digits) and decode fast.
#include "plugin_tables.h"

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "dua/dua.h"
#include "internal.h"

namespace dua {
namespace {

// FNV-1a (64 bits) of the model's structure: geom_type, geom_bodyid and body_parentid as
// little-endian int32s, in that order (dua_mujoco/plugin.py computes the same at attach).
uint64_t StructureHash(const mjModel* m) {
  uint64_t h = 0xcbf29ce484222325ULL;
  auto feed = [&h](const int* values, int n) {
    for (int i = 0; i < n; ++i) {
      const uint32_t v = static_cast<uint32_t>(values[i]);
      for (int b = 0; b < 4; ++b) {
        h ^= (v >> (8 * b)) & 0xffu;
        h *= 0x100000001b3ULL;
      }
    }
  };
  feed(m->geom_type, m->ngeom);
  feed(m->geom_bodyid, m->ngeom);
  feed(m->body_parentid, m->nbody);
  return h;
}

// Parses "<prefix>:<name>" (its entry count, a space, then the entries' little-endian float64
// bytes in base64) into out; false (after a warning naming the field) if it is missing or does
// not parse.
bool ReadTable(const mjModel* m, const std::string& prefix, const char* name,
               std::vector<double>* out) {
  const std::string full = prefix + ":" + name;
  const int id = mj_name2id(m, mjOBJ_TEXT, full.c_str());
  if (id < 0) {
    mju_warning(
        "dua_mujoco.predictor: the model has no text field '%s' (plugin attribute 'prefix' = "
        "'%s'): build the model with dua_mujoco.attach(spec), which writes the tables.",
        full.c_str(), prefix.c_str());
    return false;
  }
  const char* text = m->text_data + m->text_adr[id];
  char* end = nullptr;
  const long long count = std::strtoll(text, &end, 10);
  if (end == text || count < 0 || *end != ' ') {
    mju_warning(
        "dua_mujoco.predictor: text field '%s' does not start with its entry count: "
        "attach the predictor again.",
        full.c_str());
    return false;
  }
  const char* digits = end + 1;
  const size_t nbytes = static_cast<size_t>(count) * sizeof(double);
  const size_t ndigits = (nbytes + 2) / 3 * 4;
  if (std::strlen(digits) != ndigits) {
    mju_warning(
        "dua_mujoco.predictor: text field '%s' does not hold its %lld entries: attach "
        "the predictor again.",
        full.c_str(), count);
    return false;
  }
  static const std::array<int8_t, 256> kDigit = [] {
    std::array<int8_t, 256> t{};
    t.fill(-1);
    const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i)
      t[static_cast<unsigned char>(alphabet[i])] = static_cast<int8_t>(i);
    t['='] = 0;
    return t;
  }();
  std::vector<unsigned char> bytes(ndigits / 4 * 3);
  const unsigned char* in = reinterpret_cast<const unsigned char*>(digits);
  for (size_t i = 0, o = 0; i < ndigits; i += 4, o += 3) {
    const int a = kDigit[in[i]], b = kDigit[in[i + 1]], c = kDigit[in[i + 2]],
              e = kDigit[in[i + 3]];
    if ((a | b | c | e) < 0) {
      mju_warning(
          "dua_mujoco.predictor: text field '%s' holds a character that is not base64: "
          "attach the predictor again.",
          full.c_str());
      return false;
    }
    const unsigned triple = (a << 18) | (b << 12) | (c << 6) | e;
    bytes[o] = static_cast<unsigned char>(triple >> 16);
    bytes[o + 1] = static_cast<unsigned char>(triple >> 8);
    bytes[o + 2] = static_cast<unsigned char>(triple);
  }
  // The padding ('=') decodes to zero bytes past the entries.
  out->resize(static_cast<size_t>(count));
  if (nbytes) std::memcpy(out->data(), bytes.data(), nbytes);  // little-endian, as written
  return true;
}

std::vector<int64_t> AsInts(const std::vector<double>& v) {
  std::vector<int64_t> out(v.size());
  for (size_t i = 0; i < v.size(); ++i) out[i] = static_cast<int64_t>(v[i]);
  return out;
}

// Reads "<prefix>:<name>" as (rows, ncol) into columns: out[c][r]; false after a warning.
bool ReadColumns(const mjModel* m, const std::string& prefix, const char* name, int64_t rows,
                 int ncol, std::vector<std::vector<double>>* out) {
  std::vector<double> v;
  if (!ReadTable(m, prefix, name, &v)) return false;
  if (static_cast<int64_t>(v.size()) != rows * ncol) {
    mju_warning(
        "dua_mujoco.predictor: text field '%s:%s' holds %lld entries, not %lld: attach the "
        "predictor again.",
        prefix.c_str(), name, static_cast<long long>(v.size()),
        static_cast<long long>(rows * ncol));
    return false;
  }
  out->assign(ncol, std::vector<double>(rows));
  for (int64_t r = 0; r < rows; ++r) {
    for (int c = 0; c < ncol; ++c) (*out)[c][r] = v[ncol * r + c];
  }
  return true;
}

// What learning a pair reads (universe.h); false after a warning saying why.
bool LoadLearn(const mjModel* m, const std::string& prefix, Tables* t) {
  LearnTables& l = t->learn;
  std::vector<std::vector<double>> f, c, lone, body;
  std::vector<double> exclude, start, planes, shapes;
  const int64_t nsphere = t->nsphere();
  if (!ReadColumns(m, prefix, "filter", m->ngeom, 7, &f) ||
      !ReadColumns(m, prefix, "contact", m->ngeom, 2, &c) ||
      !ReadColumns(m, prefix, "geom_lone", m->ngeom, 2, &lone) ||
      !ReadColumns(m, prefix, "body_bounds", m->nbody, 3, &body) ||
      !ReadTable(m, prefix, "exclude", &exclude) || !ReadTable(m, prefix, "geom_start", &start) ||
      !ReadTable(m, prefix, "plane_geom", &planes) ||
      !ReadTable(m, prefix, "shape_geom", &shapes)) {
    return false;
  }
  l.body = AsInts(f[0]), l.weld = AsInts(f[1]), l.parent_weld = AsInts(f[2]);
  l.movable.assign(f[3].begin(), f[3].end());
  l.contype = AsInts(f[4]), l.conaffinity = AsInts(f[5]);
  l.lone.assign(f[6].begin(), f[6].end());
  l.exclude = AsInts(exclude);
  l.filter.filterparent = static_cast<int64_t>(t->config[kCfgFilterParent]);
  l.contacts = t->config[kCfgContacts] != 0.0;
  l.margin = c[0], l.gap = c[1];
  l.override_margin = t->config[kCfgOverride] != 0.0;
  l.o_margin = t->config[kCfgOMargin];
  l.geom_start = AsInts(start);
  l.geom_plane = AsInts(lone[0]), l.geom_shape = AsInts(lone[1]);
  l.plane_geom = AsInts(planes), l.shape_geom = AsInts(shapes);
  l.accel = body[0], l.delta = body[1], l.speed = body[2];
  l.has_speed = t->config[kCfgHasSpeed] != 0.0;
  l.radius = t->held.radius.data();  // the Tables are never copied or moved once loaded
  l.sphere_geom.resize(nsphere), l.sphere_body.resize(nsphere);
  for (int64_t i = 0; i < nsphere; ++i) {
    l.sphere_geom[i] = static_cast<int64_t>(t->spheres[kSphereNcol * i + kSphereFrame]);
    l.sphere_body[i] = static_cast<int64_t>(t->spheres[kSphereNcol * i + kSphereBody]);
  }
  l.exact_geoms = t->exact ? t->geoms.data() : nullptr;
  // Every index the learning follows must point inside its table.
  bool ok = static_cast<int64_t>(l.geom_start.size()) == m->ngeom + 1 &&
            std::is_sorted(l.exclude.begin(), l.exclude.end());
  for (int64_t g = 0; ok && g <= m->ngeom; ++g) {
    ok = l.geom_start[g] >= 0 && l.geom_start[g] <= nsphere &&
         (g == 0 || l.geom_start[g] >= l.geom_start[g - 1]);
  }
  for (int64_t g = 0; ok && g < m->ngeom; ++g) {
    ok = l.body[g] >= 0 && l.body[g] < m->nbody && l.geom_plane[g] < (int64_t)l.plane_geom.size() &&
         l.geom_shape[g] < static_cast<int64_t>(l.shape_geom.size());
  }
  for (int64_t i = 0; ok && i < nsphere; ++i) {
    ok = l.sphere_geom[i] >= 0 && l.sphere_geom[i] < m->ngeom && l.sphere_body[i] >= 0 &&
         l.sphere_body[i] < m->nbody;
  }
  for (const auto* v : {&l.plane_geom, &l.shape_geom}) {
    for (const int64_t g : *v) ok = ok && g >= 0 && g < m->ngeom;
  }
  for (int64_t b = 0; ok && b < m->nbody; ++b) {
    ok = l.accel[b] >= 0 && std::isfinite(l.accel[b]) && l.delta[b] >= 0 &&
         std::isfinite(l.delta[b]) && l.speed[b] >= 0;
  }
  if (!ok) {
    mju_warning(
        "dua_mujoco.predictor: the tables for learning pairs under prefix '%s' do not fit "
        "this model: attach the predictor again.",
        prefix.c_str());
    return false;
  }
  l.Point();
  return true;
}

// The pruned pairs' tables (false after a warning saying why).
bool LoadPruned(const mjModel* m, const std::string& prefix, Tables* t) {
  std::vector<double> reach;
  if (!ReadTable(m, prefix, "reach", &reach)) return false;
  const double stride = t->config[kCfgStride];
  std::string bad;
  if (!(stride >= 1 && stride < 1e9)) bad = "the stride";
  // Pruned pairs are carried into the deadline schedule only (Predictor requires it too).
  if (static_cast<int64_t>(t->config[kCfgKind]) != kDeadline)
    bad = "a schedule other than deadline";
  for (int64_t r = 0; r < t->nbody_events; ++r) {
    const double b = t->events_rec[kBNcol * r + kBBody];
    if (!(b >= 0 && b < m->nbody)) bad = "the violation check's bodies";
  }
  if (bad.empty()) {
    bad = t->held.Build(reach, t->spheres, m->nbody, t->config[kCfgHorizon], t->config[kCfgMargin],
                        static_cast<int64_t>(stride));
  }
  if (!bad.empty()) {
    mju_warning(
        "dua_mujoco.predictor: the pruned pairs' tables under prefix '%s' do not fit (%s): "
        "attach the predictor again.",
        prefix.c_str(), bad.c_str());
    return false;
  }
  if (!LoadLearn(m, prefix, t)) return false;
  std::vector<int64_t> body_row(m->nbody, -1);
  for (int64_t r = 0; r < t->nbody_events; ++r) {
    body_row[static_cast<int64_t>(t->events_rec[kBNcol * r + kBBody])] = r;
  }
  t->geom_row.resize(m->ngeom);
  for (int g = 0; g < m->ngeom; ++g) t->geom_row[g] = body_row[m->geom_bodyid[g]];
  return true;
}

}  // namespace

std::shared_ptr<const Tables> LoadTables(const mjModel* m, const std::string& prefix) {
  auto t = std::make_shared<Tables>();
  std::vector<double> pair_geom, geom_pairs, events_start, events_members;
  if (!ReadTable(m, prefix, "config", &t->config)) return nullptr;
  if (t->config.size() != kCfgSize || static_cast<int64_t>(t->config[kCfgAbi]) != DUA_ABI_VERSION) {
    mju_warning(
        "dua_mujoco.predictor: '%s:config' was written by another version of "
        "dua_mujoco: attach the predictor again with this one.",
        prefix.c_str());
    return nullptr;
  }
  const uint64_t shape = StructureHash(m);
  if (static_cast<int64_t>(t->config[kCfgNgeom]) != m->ngeom ||
      static_cast<int64_t>(t->config[kCfgNbody]) != m->nbody ||
      static_cast<uint64_t>(t->config[kCfgShape]) != (shape & 0xffffffffu) ||
      static_cast<uint64_t>(t->config[kCfgShape + 1]) != (shape >> 32)) {
    mju_warning(
        "dua_mujoco.predictor: the tables under prefix '%s' were made for another model "
        "(%lld geoms and %lld bodies, or another structure; this one has %lld and %lld): "
        "the spec changed after dua_mujoco.attach; attach last, after every edit.",
        prefix.c_str(), static_cast<long long>(t->config[kCfgNgeom]),
        static_cast<long long>(t->config[kCfgNbody]), static_cast<long long>(m->ngeom),
        static_cast<long long>(m->nbody));
    return nullptr;
  }
  Universe& u = t->universe;
  if (!ReadTable(m, prefix, "pairs", &u.pairs) || !ReadTable(m, prefix, "spheres", &t->spheres) ||
      !ReadTable(m, prefix, "shapes", &t->shapes) ||
      !ReadTable(m, prefix, "horizon", &t->horizon) ||
      !ReadTable(m, prefix, "pair_geom", &pair_geom) ||
      !ReadTable(m, prefix, "geom_pairs", &geom_pairs) ||
      !ReadTable(m, prefix, "events_rec", &t->events_rec) ||
      !ReadTable(m, prefix, "events_params", &t->events_params) ||
      !ReadTable(m, prefix, "events_start", &events_start) ||
      !ReadTable(m, prefix, "events_members", &events_members)) {
    return nullptr;
  }
  t->nbody_events = static_cast<int64_t>(t->events_rec.size() / kBNcol);
  u.pair_geom = AsInts(pair_geom);
  u.geom_pairs = AsInts(geom_pairs);
  t->events_start = AsInts(events_start);
  t->events_members = AsInts(events_members);
  const std::string bad = u.Index(t->spheres, m->ngeom);
  const bool sizes = bad.empty() && static_cast<int64_t>(u.pairs.size()) == kPairNcol * u.npair() &&
                     static_cast<int64_t>(t->events_start.size()) == t->nbody_events + 1 &&
                     !t->horizon.empty() && !t->events_params.empty();
  if (!sizes) {
    mju_warning(
        "dua_mujoco.predictor: the tables under prefix '%s' do not fit together or "
        "this model (%s): attach the predictor again.",
        prefix.c_str(), bad.empty() ? "sizes" : bad.c_str());
    return nullptr;
  }
  t->exact = static_cast<int64_t>(t->config[kCfgExactOn]) != 0;
  if (t->exact) {
    if (!ReadTable(m, prefix, "exact_geoms", &t->geoms) ||
        !ReadTable(m, prefix, "exact_records", &u.exact)) {
      return nullptr;
    }
    if (static_cast<int64_t>(t->geoms.size()) != kGxNcol * static_cast<int64_t>(m->ngeom) ||
        static_cast<int64_t>(u.exact.size()) != kXNcol * u.npair()) {
      mju_warning(
          "dua_mujoco.predictor: the exact level's tables under prefix '%s' do not fit this "
          "model: attach the predictor again.",
          prefix.c_str());
      return nullptr;
    }
    // The mesh vertices in float64, as dua_mujoco.mj.exact reads them (exactly: float32 widens
    // without rounding).
    t->verts.assign(m->mesh_vert, m->mesh_vert + 3 * m->nmeshvert);
    if (t->verts.empty()) t->verts.assign(3, 0.0);
    t->graph.assign(m->mesh_graph, m->mesh_graph + m->nmeshgraph);
    if (t->graph.empty()) t->graph.assign(1, -1);
  }
  t->pruned = static_cast<int64_t>(t->config[kCfgPruned]) != 0;
  if (t->pruned && !LoadPruned(m, prefix, t.get())) return nullptr;
  return t;
}

}  // namespace dua

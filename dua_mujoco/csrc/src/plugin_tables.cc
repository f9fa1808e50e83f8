// Reading the plugin's tables (plugin_tables.h): each is its entry count, a space, then the
// entries' little-endian float64 bytes in base64, which survive an XML round trip exactly
// (MuJoCo writes numeric fields with six digits) and decode fast.
#include "plugin_tables.h"

#include <array>
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

// The pruned pairs' tables (false after a warning saying why).
bool LoadPruned(const mjModel* m, const std::string& prefix, Tables* t) {
  std::vector<double> reach;
  if (!ReadTable(m, prefix, "reach", &reach)) return false;
  const double stride = t->config[kCfgStride];
  std::string bad;
  if (!(stride >= 1 && stride < 1e9)) bad = "the stride";
  // Pruned pairs are carried into the deadline schedule only (Predictor requires it too).
  if (static_cast<int64_t>(t->config[kCfgKind]) != 1) bad = "a schedule other than deadline";
  for (int64_t r = 0; r < t->nbody_events; ++r) {
    const double b = t->events_rec[12 * r + kBBody];
    if (!(b >= 0 && b < m->nbody)) bad = "the violation check's bodies";
  }
  if (bad.empty()) {
    bad = t->held.Build(reach, t->spheres, t->pairs, m->nbody, t->config[kCfgHorizon],
                        t->config[kCfgMargin], static_cast<int64_t>(stride));
  }
  if (!bad.empty()) {
    mju_warning(
        "dua_mujoco.predictor: the pruned pairs' tables under prefix '%s' do not fit (%s): "
        "attach the predictor again.",
        prefix.c_str(), bad.c_str());
    return false;
  }
  constexpr int kFirst = 0, kSphereFrame = 0;
  t->geom1.resize(t->npair);
  t->geom2.resize(t->npair);
  for (int64_t p = 0; p < t->npair; ++p) {
    const auto first = static_cast<int64_t>(t->pairs[8 * p + kFirst]);
    const int64_t g = static_cast<int64_t>(t->spheres[8 * first + kSphereFrame]);
    const int64_t a = t->geom_pairs[2 * t->pair_geom[p]],
                  b = t->geom_pairs[2 * t->pair_geom[p] + 1];
    t->geom1[p] = g;
    t->geom2[p] = g == a ? b : a;
  }
  std::vector<int64_t> body_row(m->nbody, -1);
  for (int64_t r = 0; r < t->nbody_events; ++r) {
    body_row[static_cast<int64_t>(t->events_rec[12 * r + kBBody])] = r;
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
  if (!ReadTable(m, prefix, "pairs", &t->pairs) || !ReadTable(m, prefix, "spheres", &t->spheres) ||
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
  t->npair = static_cast<int64_t>(t->pairs.size() / 8);
  t->ngp = static_cast<int64_t>(geom_pairs.size() / 2);
  t->nbody_events = static_cast<int64_t>(t->events_rec.size() / 12);
  t->pair_geom = AsInts(pair_geom);
  t->geom_pairs = AsInts(geom_pairs);
  t->gp_keys.resize(t->ngp);
  for (int64_t k = 0; k < t->ngp; ++k) {
    t->gp_keys[k] = (t->geom_pairs[2 * k] << 32) | t->geom_pairs[2 * k + 1];
  }
  t->events_start = AsInts(events_start);
  t->events_members = AsInts(events_members);
  bool sizes = static_cast<int64_t>(t->pair_geom.size()) == t->npair &&
               static_cast<int64_t>(t->events_start.size()) == t->nbody_events + 1 &&
               !t->horizon.empty() && !t->events_params.empty();
  for (int64_t gp : t->pair_geom) sizes = sizes && gp >= 0 && gp < t->ngp;
  for (int64_t g : t->geom_pairs) sizes = sizes && g >= 0 && g < m->ngeom;
  // GeomPair's binary search needs the rows (g1 < g2) in increasing order, each once.
  for (int64_t k = 0; k < t->ngp; ++k) {
    sizes = sizes && t->geom_pairs[2 * k] < t->geom_pairs[2 * k + 1] &&
            (k == 0 || t->gp_keys[k - 1] < t->gp_keys[k]);
  }
  if (!sizes) {
    mju_warning(
        "dua_mujoco.predictor: the tables under prefix '%s' do not fit together or "
        "this model: attach the predictor again.",
        prefix.c_str());
    return nullptr;
  }
  t->exact = static_cast<int64_t>(t->config[kCfgExactOn]) != 0;
  if (t->exact) {
    if (!ReadTable(m, prefix, "exact_geoms", &t->geoms) ||
        !ReadTable(m, prefix, "exact_records", &t->exact_records)) {
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

// libFuzzer harness of the predictor's tables (docs/hardening.md): every malformed table must be
// refused with an error naming it, and every accepted one must run without a crash or a
// sanitizer report.
//
// An input is a model (an index into make_seeds.py's models) and a set of named tables (float64
// entries, or raw text as the plugin reads it); its format is make_seeds.py's. Each input:
//   1. builds the tables on the model (no plugin) from the arrays, as _core.Tables.build does,
//      and from their text, through Decode, as the plugin does; a refusal must name a table the
//      build asked for, and both paths must decide alike;
//   2. when they are accepted, runs a Runtime on them: the classification, then steps with
//      mj_step in between (a state perturbed, optionally NaN or huge; optionally the switches,
//      the contact deactivation, a copy, mocap velocities);
//      With a plan (the table "@plan"), Runtime::SetPlan at the classification and halfway,
//      and ClearPlan: garbage knots (NaN, inf, huge positions or deviations, a start off the
//      clock, too few knots) must be refused with a message when they are not finite, and run
//      without a crash when accepted;
//   3. with the plugin flag, writes the tables into the plugin model's text fields (the model
//      optionally edited after attach), compiles it, and runs mj_makeData, mj_step, mj_copyData
//      and mj_resetData: the plugin's own path, whose refusal (MuJoCo's warning) must name the
//      same table; the plan, if any, through dua_plugin_set_plan after the first step.
// The custom mutator works on that structure: entries set to NaN, inf, counts and indices out of
// range, bits flipped, tables truncated, extended, dropped, taken from another model, their text
// corrupted, another model, another state.
//
// Built by CMake with -DDUA_FUZZ=ON and clang (fuzz/run.sh); reads the models and seeds under
// $DUA_FUZZ_DIR (make_seeds.py's output).
#include <dirent.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "dua/dua.h"
#include "runtime.h"
#include "tables.h"

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

namespace {

// Flags of an input (make_seeds.py's).
constexpr uint8_t kFlagPlugin = 1, kFlagBadState = 2, kFlagExtras = 4;

struct Table {
  std::string name;
  uint8_t form = 0;  // 0: entries, 1: text
  std::vector<double> values;
  std::string text;
};

struct Input {
  uint8_t model = 0, flags = 0, steps = 0, seed = 0;
  std::vector<Table> tables;
};

// ------------------------------------------------------------------------------ the format

bool Parse(const uint8_t* data, size_t size, Input* in) {
  size_t at = 0;
  auto take = [&](void* out, size_t n) {
    if (size - at < n) return false;
    if (n) std::memcpy(out, data + at, n);
    at += n;
    return true;
  };
  char magic[4];
  uint16_t ntable = 0;
  if (!take(magic, 4) || std::memcmp(magic, "DUAF", 4) != 0 || !take(&in->model, 1) ||
      !take(&in->flags, 1) || !take(&in->steps, 1) || !take(&in->seed, 1) || !take(&ntable, 2)) {
    return false;
  }
  in->tables.resize(ntable);
  for (Table& t : in->tables) {
    uint8_t len = 0;
    uint32_t n = 0;
    if (!take(&len, 1)) return false;
    t.name.resize(len);
    if (!take(t.name.data(), len) || !take(&t.form, 1) || !take(&n, 4)) return false;
    if (t.form == 0) {
      if ((size - at) / 8 < n) return false;
      t.values.resize(n);
      if (!take(t.values.data(), 8 * static_cast<size_t>(n))) return false;
    } else {
      t.form = 1;
      t.text.resize(n);
      if (!take(t.text.data(), n)) return false;
    }
  }
  return at == size;
}

std::vector<uint8_t> Serialize(const Input& in) {
  std::vector<uint8_t> out;
  auto put = [&out](const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    out.insert(out.end(), b, b + n);
  };
  const auto ntable = static_cast<uint16_t>(std::min<size_t>(in.tables.size(), 65535));
  put("DUAF", 4);
  put(&in.model, 1), put(&in.flags, 1), put(&in.steps, 1), put(&in.seed, 1), put(&ntable, 2);
  for (size_t k = 0; k < ntable; ++k) {
    const Table& t = in.tables[k];
    const auto len = static_cast<uint8_t>(std::min<size_t>(t.name.size(), 255));
    put(&len, 1), put(t.name.data(), len), put(&t.form, 1);
    const auto n = static_cast<uint32_t>(t.form == 0 ? t.values.size() : t.text.size());
    put(&n, 4);
    if (t.form == 0) {
      put(t.values.data(), 8 * static_cast<size_t>(n));
    } else {
      put(t.text.data(), n);
    }
  }
  return out;
}

// A table as the plugin's text field holds it (plugin.py's _encode).
std::string Encode(const std::vector<double>& v) {
  static const char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out = std::to_string(v.size()) + " ";
  const auto* b = reinterpret_cast<const uint8_t*>(v.data());
  const size_t n = 8 * v.size();
  for (size_t i = 0; i < n; i += 3) {
    const uint32_t x = (uint32_t{b[i]} << 16) | (i + 1 < n ? uint32_t{b[i + 1]} << 8 : 0u) |
                       (i + 2 < n ? uint32_t{b[i + 2]} : 0u);
    out += kAlphabet[(x >> 18) & 63];
    out += kAlphabet[(x >> 12) & 63];
    out += i + 1 < n ? kAlphabet[(x >> 6) & 63] : '=';
    out += i + 2 < n ? kAlphabet[x & 63] : '=';
  }
  return out;
}

const std::string& TextOf(Table& t) {
  if (t.form == 0) t.text = Encode(t.values), t.form = 1, t.values.clear();
  return t.text;
}

// ------------------------------------------------------------------------------ the models

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "tables_fuzzer: %s\n", what.c_str());
  std::abort();
}

// Every table the plugin reads (dua_mujoco/runtime/table_arrays.py).
const char* const kNames[] = {"config",     "spheres",       "shapes",      "static",
                              "pairs",      "pair_geom",     "geom_pairs",  "geom_pair_contact",
                              "events_rec", "events_params", "exact_geoms", "exact_records",
                              "reach",      "filter",        "exclude",     "contact",
                              "geom_start", "geom_lone",     "plane_geom",  "shape_geom",
                              "body_bounds"};

struct Model {
  std::string name, edit;
  mjModel* bare = nullptr;   // without the plugin (the Runtime's model)
  mjData* data = nullptr;    // of bare
  mjSpec* plugin = nullptr;  // with the plugin, its tables replaced per input
  // plugin compiled, with a text field for every table in kNames, and the names of its fields.
  mjModel* compiled = nullptr;
  std::vector<std::string> fields;
};

// Never destroyed: the models stay reachable to the end (LeakSanitizer checks at exit).
std::vector<Model>& g_models = *new std::vector<Model>;
std::vector<Input>& g_seeds = *new std::vector<Input>;

// MuJoCo's warnings and errors: the plugin's refusal is a warning, then mj_makeData's error.
std::string g_warning, g_error;
jmp_buf g_jump;
bool g_armed = false;

void OnWarning(const char* msg) { g_warning = msg; }
void OnError(const char* msg) {
  g_error = msg;
  if (!g_armed) Die(std::string("MuJoCo error outside mj_makeData: ") + msg);
  std::longjmp(g_jump, 1);
}

std::string Dir() {
  const char* dir = std::getenv("DUA_FUZZ_DIR");
  if (!dir || !*dir) Die("set DUA_FUZZ_DIR to make_seeds.py's output (fuzz/run.sh does)");
  return dir;
}

std::string ReadFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) Die("cannot read " + path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

void Load() {
  const std::string dir = Dir();
  std::istringstream index(ReadFile(dir + "/models/index.txt"));
  std::string line;
  char error[1000] = "";
  while (std::getline(index, line)) {
    if (line.empty()) continue;
    Model mo;
    std::istringstream words(line);
    words >> mo.name >> mo.edit;
    const std::string base = dir + "/models/" + mo.name;
    mo.bare = mj_loadXML((base + ".bare.xml").c_str(), nullptr, error, sizeof(error));
    if (!mo.bare) Die(base + ".bare.xml: " + error);
    mo.data = mj_makeData(mo.bare);
    mo.plugin =
        mj_parseXMLString(ReadFile(base + ".plugin.xml").c_str(), nullptr, error, sizeof(error));
    if (!mo.plugin) Die(base + ".plugin.xml: " + error);
    // 4 MB of arena (these models use under 40 kB): the default 14 MB, allocated and cleared
    // for every MjData under AddressSanitizer, took most of the fuzzer's time.
    mo.plugin->memory = 4 << 20;
    for (const char* name : kNames) {
      const std::string full = std::string("dua:") + name;
      if (mjs_findElement(mo.plugin, mjOBJ_TEXT, full.c_str())) continue;
      mjsText* text = mjs_addText(mo.plugin);
      mjs_setName(text->element, full.c_str());
      mjs_setString(text->data, "0 ");
    }
    mo.compiled = mj_compile(mo.plugin, nullptr);
    if (!mo.compiled) Die(base + ".plugin.xml does not compile: " + mjs_getError(mo.plugin));
    for (int i = 0; i < mo.compiled->ntext; ++i) {
      mo.fields.push_back(mo.compiled->names + mo.compiled->name_textadr[i]);
    }
    g_models.push_back(mo);
  }
  if (g_models.empty()) Die("no models in " + dir + "/models/index.txt");
  if (DIR* d = opendir((dir + "/seeds").c_str())) {
    while (dirent* e = readdir(d)) {
      if (e->d_name[0] == '.') continue;
      const std::string bytes = ReadFile(dir + "/seeds/" + e->d_name);
      Input in;
      if (Parse(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), &in)) {
        g_seeds.push_back(std::move(in));
      }
    }
    closedir(d);
  }
  if (g_seeds.empty()) Die("no seeds in " + dir + "/seeds");
}

// ------------------------------------------------------------------------------ one input

// The table `err` names: err is before + name + after + " " + why, and name one the build read.
std::string NamedTable(const std::string& err, const std::string& before, const std::string& after,
                       const std::set<std::string>& read) {
  if (err.compare(0, before.size(), before) != 0) Die("a refusal that names no table: " + err);
  const size_t end = err.find(after + " ", before.size());
  if (end == std::string::npos) Die("a refusal that names no table: " + err);
  const std::string name = err.substr(before.size(), end - before.size());
  if (!read.count(name))
    Die("a refusal naming '" + name + "', which the build did not read: " + err);
  if (err.size() < end + after.size() + 4) Die("a refusal that does not say why: " + err);
  return name;
}

const Table* Find(const Input& in, const std::string& name) {
  for (const Table& t : in.tables) {
    if (t.name == name) return &t;
  }
  return nullptr;
}

// Builds the tables from the input, as arrays (text tables decoded) or all as text.
std::shared_ptr<const dua::Tables> Build(const Input& in, const mjModel* m, bool as_text,
                                         std::string* table, std::string* err) {
  std::set<std::string> read;
  const dua::TableSource source = [&](const std::string& name, std::vector<double>* out,
                                      std::string* why) {
    read.insert(name);
    const Table* t = Find(in, name);
    if (!t) {
      *why = "is missing";
      return false;
    }
    if (t->form == 0 && !as_text) {
      *out = t->values;
      return true;
    }
    const std::string text = t->form == 0 ? Encode(t->values) : t->text;
    return dua::Decode(text.c_str(), out, why);
  };
  const std::string before = as_text ? "text field 'dua:" : "table '";
  auto tables = dua::BuildTables(m, source, before, "'", err);
  if (!tables) *table = NamedTable(*err, before, "'", read);
  return tables;
}

// A state the runtime may meet: velocities and controls from the seed, and optionally a state
// that is not finite or is huge.
void Perturb(const mjModel* m, mjData* d, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < m->nv; ++i) d->qvel[i] = 2.0 * u(*rng);
  for (int i = 0; i < m->nu; ++i) d->ctrl[i] = u(*rng);
}

void Spoil(const mjModel* m, mjData* d, uint8_t seed) {
  const double bad = seed & 1 ? std::numeric_limits<double>::quiet_NaN() : 1e200;
  if (m->nq) d->qpos[seed % m->nq] = bad;
  if (m->nmocap) d->mocap_pos[0] = bad;
}

// A flight plan read from the input's table "@plan": its first entry the start, in timesteps
// from the state the next step reads, then rows of nq joint positions and nbody deviations (the
// knots: as many whole rows as it holds). Not one of the plugin's tables: the builds ignore it.
constexpr char kPlan[] = "@plan";

struct PlanInput {
  double offset = 0.0;
  int64_t n = 0;
  std::vector<double> qpos, dev;
  bool finite = true;  // every number the plan holds finite, and every deviation >= 0
  // The plan as the runtime takes it, starting `start` (every moving body outside mocap trees).
  dua_plan_input At(double start) const {
    dua_plan_input in{};
    in.qpos = qpos.data(), in.n = n, in.deviation = dev.data(), in.start = start;
    return in;
  }
};

PlanInput PlanOf(const Table& t, const mjModel* m) {
  PlanInput p;
  std::vector<double> v = t.values;
  std::string why;
  if (t.form == 1 && !dua::Decode(t.text.c_str(), &v, &why)) v.clear();
  if (v.empty()) return p;
  p.offset = v[0];
  const size_t stride = static_cast<size_t>(m->nq + m->nbody);
  p.n = static_cast<int64_t>((v.size() - 1) / stride);
  for (int64_t j = 0; j < p.n; ++j) {
    const double* row = v.data() + 1 + stride * j;
    p.qpos.insert(p.qpos.end(), row, row + m->nq);
    p.dev.insert(p.dev.end(), row + m->nq, row + stride);
  }
  p.finite = std::isfinite(p.offset);
  for (const double x : p.qpos) p.finite = p.finite && std::isfinite(x);
  for (const double x : p.dev) p.finite = p.finite && std::isfinite(x) && x >= 0.0;
  return p;
}

// Plans set, accepted and refused (printed at exit with DUA_FUZZ_STATS=1, over a corpus run
// once with -runs=0: what the corpus covers).
int64_t g_plans[3] = {0, 0, 0};

void PrintStats() {
  std::fprintf(stderr, "tables_fuzzer: plans set %lld, accepted %lld, refused %lld\n",
               static_cast<long long>(g_plans[0]), static_cast<long long>(g_plans[1]),
               static_cast<long long>(g_plans[2]));
}

// A plan holding a value that is not finite (or a negative deviation) must be refused, with a
// reason; `why` is the refusal ("" accepted).
void CheckPlanVerdict(const PlanInput& p, const std::string& why) {
  ++g_plans[0], ++g_plans[why.empty() ? 1 : 2];
  if (!p.finite && p.n > 0 && why.empty()) Die("a plan holding a value that is not finite ran");
  if (!why.empty() && why.size() < 8) Die("a plan refused without a reason: " + why);
}

void Run(const Model& mo, const std::shared_ptr<const dua::Tables>& tables, const Input& in) {
  const mjModel* m = mo.bare;
  mjData* d = mo.data;
  mj_resetData(m, d);
  std::mt19937_64 rng(in.seed);
  Perturb(m, d, &rng);
  mj_forward(m, d);
  dua::Runtime rt(tables, m, 1 + in.steps % 3, 0);
  rt.Classify(m, d);
  const Table* plan_table = Find(in, kPlan);
  const PlanInput plan = plan_table ? PlanOf(*plan_table, m) : PlanInput{};
  const auto set_plan = [&](dua::Runtime* r) {
    if (!plan_table) return;
    const double start = r->StateTime(m, d) + plan.offset * m->opt.timestep;
    std::vector<double> departures(m->nbody);
    CheckPlanVerdict(plan, r->SetPlan(m, plan.At(start), departures.data()));
  };
  set_plan(&rt);
  // Physics steps a period (at most 3 here: the runtime reads only d's state).
  const double ratio = tables->schedule.dt / tables->timestep;
  const int per = static_cast<int>(std::min(3.0, std::max(1.0, std::nearbyint(ratio))));
  const int steps = in.steps % 16;
  const bool extras = in.flags & kFlagExtras;
  std::vector<int64_t> switched;
  for (int k = 0; k < steps; ++k) {
    for (int j = 0; j < per; ++j) {
      if (m->nmocap) d->mocap_pos[0] += 0.004, d->mocap_pos[2] -= 0.002;
      mj_step(m, d);
    }
    if ((in.flags & kFlagBadState) && k == steps / 2) Spoil(m, d, in.seed), mj_forward(m, d);
    if (rt.Step(m, d) < 0) rt.Classify(m, d);  // as the plugin does
    (void)rt.nstanding(), (void)rt.FlaggedBodies();
    if (plan_table) {
      (void)rt.PlanBroken(m, d), (void)rt.plan_breaks(), (void)rt.plan_queries();
      (void)rt.CheckPlan(m, d);
      if (k == steps / 2) set_plan(&rt);
      if (k == 3 && m->ngeom > 1) {  // the shield's query, on every geom against geom 0
        std::vector<int64_t> g1, g2, knots;
        for (int g = 1; g < m->ngeom; ++g) g1.push_back(0), g2.push_back(g);
        (void)rt.PlanQuery(m, d, plan.At(rt.StateTime(m, d)), g1, g2, &knots);
      }
      if (k == 10) rt.ClearPlan();
    }
    if (!extras) continue;
    if (k == 1 && m->nbody > 1) {
      switched = rt.PairsBetweenBodies(m, 1 + in.seed % (m->nbody - 1), in.seed & 1 ? -1 : 0);
      rt.Switch(switched, false);
    } else if (k == 3) {
      rt.Switch(switched, true);
      rt.DeactivateContacts(d);
    } else if (k == 4 && m->ngeom > 1) {
      std::vector<int64_t> g1, g2;
      for (int g = 0; g < m->ngeom; ++g) {
        g1.push_back(g), g2.push_back(static_cast<int64_t>(rng() % m->ngeom));
      }
      (void)rt.GeomPairIds(g1, g2);
    } else if (k == 5 && m->nmocap) {
      const double v[3] = {0.1, 0.0, -0.2}, w[3] = {0.0, 1.0, 0.0};
      rt.mocap().Set(0, v, w);
    } else if (k == 6) {
      dua::Runtime copy(rt);
      if (copy.Step(m, d) < 0) copy.Classify(m, d);
      if (m->nmocap) rt.mocap().Clear(0);
    }
  }
}

// The table the plugin's latest refusal (MuJoCo's latest warning) names.
std::string PluginRefusal() {
  const std::string before = "dua_mujoco.predictor: text field 'dua:";
  std::set<std::string> names;
  for (const char* name : kNames) names.insert(name);
  return NamedTable(g_warning, before, "'", names);
}

// The plugin's path on model m, whose text fields hold the input's tables; `refused` names the
// table the build refused ("" if none).
void RunPluginModel(mjModel* m, const Input& in, const std::string& refused) {
  g_warning.clear(), g_error.clear();
  mjData* d = nullptr;
  g_armed = true;
  if (setjmp(g_jump) == 0) d = mj_makeData(m);
  g_armed = false;
  if (!d) {
    // Refused: the warning names the same table as the build's refusal.
    const std::string name = PluginRefusal();
    if (name != refused) {
      Die("the plugin refused '" + name + "' where the tables' build refused '" + refused +
          "': " + g_warning);
    }
    return;
  }
  if (!refused.empty()) Die("the plugin accepted tables the build refused ('" + refused + "')");
  std::mt19937_64 rng(in.seed);
  Perturb(m, d, &rng);
  const int steps = 1 + in.steps % 8;
  mjData* other = mj_makeData(m);
  const Table* plan_table = Find(in, kPlan);
  for (int k = 0; k < steps; ++k) {
    if (m->nmocap) d->mocap_pos[0] += 0.004;
    if ((in.flags & kFlagBadState) && k == steps / 2) Spoil(m, d, in.seed);
    mj_step(m, d);
    if (plan_table && k == 0) {
      // Inside mj_step the plugin reads the state at d->time (read lag 0).
      const PlanInput plan = PlanOf(*plan_table, m);
      char error[512] = {0};
      const double start = d->time + plan.offset * m->opt.timestep;
      const dua_plan_input input = plan.At(start);
      std::vector<double> departures(m->nbody);
      const int64_t r =
          dua_plugin_set_plan(m, d, 0, &input, departures.data(), error, sizeof(error));
      if (r != 0 && r != -3) Die("dua_plugin_set_plan returned " + std::to_string(r));
      CheckPlanVerdict(plan, r == 0 ? "" : error);
    }
    if (plan_table && k == 4 && (in.seed & 2)) dua_plugin_clear_plan(m, d, 0);
    if (k == 1) mj_copyData(other, m, d), mj_step(m, other);
    if (k == 2) mj_resetData(m, other), mj_forward(m, other);
  }
  mj_step(m, other);
  mj_deleteData(other);
  mj_deleteData(d);
}

// The plugin's path: the input's tables as the plugin model's text fields (the first table of
// each name, as Find). Mostly written into the compiled model in place (its text fields pointed
// at the input's; a table the input lacks is hidden by renaming its field), which MuJoCo reads
// only through mj_name2id and the text arrays; one input in 16 through the spec and mj_compile,
// as a user's edited model would be.
void RunPlugin(const Model& mo, const Input& in, const std::string& refused) {
  if (in.seed % 16 == 0) {
    mjSpec* s = mj_copySpec(mo.plugin);
    std::vector<mjsElement*> texts;
    for (mjsElement* e = mjs_firstElement(s, mjOBJ_TEXT); e; e = mjs_nextElement(s, e)) {
      texts.push_back(e);
    }
    for (mjsElement* e : texts) mjs_delete(s, e);
    std::set<std::string> names;
    for (const Table& t : in.tables) {
      if (t.name == kPlan || !names.insert(t.name).second) continue;
      Table copy = t;
      mjsText* text = mjs_addText(s);
      mjs_setName(text->element, ("dua:" + t.name).c_str());
      mjs_setString(text->data, TextOf(copy).c_str());
    }
    // The compiler makes an MjData (the plugin's init runs): a refusal fails the compile.
    g_warning.clear();
    mjModel* m = mj_compile(s, nullptr);
    const std::string error = mjs_getError(s);
    mj_deleteSpec(s);
    if (!m) {
      if (error.find("plugin->init failed") == std::string::npos) return;  // a name, say
      // The compiler's error quotes the plugin's warning (which it caught).
      const size_t at = error.find("dua_mujoco.predictor: ");
      if (g_warning.empty() && at != std::string::npos) g_warning = error.substr(at);
      const std::string name = PluginRefusal();
      if (name != refused) {
        Die("the plugin refused '" + name + "' where the tables' build refused '" + refused +
            "': " + g_warning);
      }
      return;
    }
    RunPluginModel(m, in, refused);
    mj_deleteModel(m);
    return;
  }
  mjModel* m = mo.compiled;
  const int n = m->ntext;
  std::string data;
  std::vector<int> adr(n), size(n), hidden;
  for (int i = 0; i < n; ++i) {
    const std::string& field = mo.fields[i];
    const Table* t = field.compare(0, 4, "dua:") == 0 ? Find(in, field.substr(4)) : nullptr;
    if (!t) {
      hidden.push_back(i);
      adr[i] = static_cast<int>(data.size()), size[i] = 1;
      data += '\0';
      continue;
    }
    Table copy = *t;
    const std::string text = TextOf(copy);
    const std::string stored = text.substr(0, text.find('\0'));  // as mjs_setString stores it
    adr[i] = static_cast<int>(data.size()), size[i] = static_cast<int>(stored.size()) + 1;
    data += stored;
    data += '\0';
  }
  char* const text_data = m->text_data;
  std::vector<int> old_adr(m->text_adr, m->text_adr + n), old_size(m->text_size, m->text_size + n);
  m->text_data = data.data();
  std::copy(adr.begin(), adr.end(), m->text_adr);
  std::copy(size.begin(), size.end(), m->text_size);
  for (const int i : hidden) m->names[m->name_textadr[i]] = '#';
  RunPluginModel(m, in, refused);
  for (const int i : hidden) m->names[m->name_textadr[i]] = 'd';
  m->text_data = text_data;
  std::copy(old_adr.begin(), old_adr.end(), m->text_adr);
  std::copy(old_size.begin(), old_size.end(), m->text_size);
}

// ------------------------------------------------------------------------------ mutations

// Values that break tables: not numbers, not integers, out of range, counts of the model.
double Interesting(std::mt19937_64* rng, const mjModel* m, double old) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const double v[] = {nan,
                      inf,
                      -inf,
                      0.0,
                      -0.0,
                      1.0,
                      -1.0,
                      0.5,
                      2.0,
                      -1e9,
                      1e9,
                      2147483648.0,
                      4294967296.0,
                      9007199254740992.0,
                      9223372036854775808.0,
                      1e308,
                      4.9e-324,
                      -2147483649.0,
                      static_cast<double>(m->ngeom),
                      static_cast<double>(m->ngeom - 1),
                      static_cast<double>(m->nbody),
                      static_cast<double>(m->nbody - 1),
                      static_cast<double>(m->nmeshvert),
                      static_cast<double>(m->nmeshgraph),
                      old + 1.0,
                      old - 1.0,
                      old * 2.0,
                      -old,
                      std::nextafter(old, inf)};
  return v[(*rng)() % (sizeof(v) / sizeof(v[0]))];
}

void MutateText(Table* t, std::mt19937_64* rng) {
  std::string s = TextOf(*t);
  const size_t space = s.find(' ');
  switch ((*rng)() % 6) {
    case 0: {  // another count
      const long long counts[] = {-1, 0, 1, (1LL << 40) + 1, 999999999999LL};
      // strtoll saturates a count past the range (atoll's result is undefined there), and the
      // step beside it must not overflow at the ends of that range either.
      const long long n = space == std::string::npos ? 0 : std::strtoll(s.c_str(), nullptr, 10);
      long long c = counts[(*rng)() % 5];
      if ((*rng)() % 2 && __builtin_add_overflow(n, static_cast<long long>((*rng)() % 5) - 2, &c))
        c = n;
      s = std::to_string(c) + (space == std::string::npos ? " " : s.substr(space));
      break;
    }
    case 1:  // a character changed
      if (!s.empty()) {
        const char junk[] = {'=', ' ', '\0', '-', '\xff', 'A', '/', '9', '\n'};
        s[(*rng)() % s.size()] =
            (*rng)() % 2 ? junk[(*rng)() % sizeof(junk)] : static_cast<char>((*rng)() % 256);
      }
      break;
    case 2:  // truncated
      s.resize(s.empty() ? 0 : (*rng)() % s.size());
      break;
    case 3:  // extended
      s += std::string(1 + (*rng)() % 8, "A=+/ 0"[(*rng)() % 6]);
      break;
    case 4:  // no space
      if (space != std::string::npos) s.erase(space, 1);
      break;
    default: {  // libFuzzer's own byte mutations
      const size_t room = s.size() + 64;
      s.resize(room);
      s.resize(LLVMFuzzerMutate(reinterpret_cast<uint8_t*>(s.data()), room - 64, room));
      break;
    }
  }
  t->text = s;
}

void MutateOnce(Input* in, std::mt19937_64* rng) {
  auto pick = [rng](size_t n) { return n ? static_cast<size_t>((*rng)() % n) : 0; };
  const mjModel* m = g_models[in->model % g_models.size()].bare;
  if (in->tables.empty()) {
    in->tables = g_seeds[pick(g_seeds.size())].tables;
    return;
  }
  Table& t = in->tables[pick(in->tables.size())];
  const unsigned op = (*rng)() % 17;
  if (t.form == 1 && op < 9) {
    MutateText(&t, rng);
    return;
  }
  std::vector<double>& v = t.values;
  switch (op) {
    case 0:
    case 1:
    case 2:  // an entry set to a value that breaks things
      if (!v.empty()) {
        double& x = v[pick(v.size())];
        x = Interesting(rng, m, x);
      }
      break;
    case 3:  // a bit flipped
      if (!v.empty()) {
        uint64_t bits;
        double& x = v[pick(v.size())];
        std::memcpy(&bits, &x, 8);
        bits ^= uint64_t{1} << pick(64);
        std::memcpy(&x, &bits, 8);
      }
      break;
    case 4:  // truncated (an entry, a row, or most of it)
      if (!v.empty())
        v.resize((*rng)() % 2 ? v.size() - 1 - pick(std::min<size_t>(v.size(), 24))
                              : pick(v.size()));
      break;
    case 5: {  // extended: a copy of its tail, zeros, or junk
      const size_t n = 1 + pick(48);
      for (size_t k = 0; k < n; ++k) {
        const unsigned how = (*rng)() % 3;
        v.push_back(how == 0 && !v.empty() ? v[v.size() - 1 - pick(std::min<size_t>(v.size(), 24))]
                    : how == 1             ? 0.0
                                           : Interesting(rng, m, 0.0));
      }
      break;
    }
    case 6: {  // rows copied or swapped (any plausible width)
      const size_t widths[] = {1, 2, 3, 4, 7, 8, 10, 12, 16, 24};
      const size_t w = widths[pick(10)];
      const size_t rows = v.size() / w;
      if (rows >= 2) {
        const size_t a = pick(rows), b = pick(rows);
        if ((*rng)() % 2) {
          std::copy_n(v.begin() + w * a, w, v.begin() + w * b);
        } else {
          std::swap_ranges(v.begin() + w * a, v.begin() + w * (a + 1), v.begin() + w * b);
        }
      }
      break;
    }
    case 7: {  // the same table of another model (or another seed of this one)
      const Input& other = g_seeds[pick(g_seeds.size())];
      if (const Table* o = Find(other, t.name)) t = *o;
      break;
    }
    case 8:  // dropped, or renamed
      if ((*rng)() % 2) {
        in->tables.erase(in->tables.begin() + (&t - in->tables.data()));
      } else {
        t.name = kNames[pick(sizeof(kNames) / sizeof(kNames[0]))];
      }
      break;
    case 9:  // as text, then corrupted
      MutateText(&t, rng);
      break;
    case 10:  // another model
      in->model = static_cast<uint8_t>(pick(g_models.size()));
      break;
    case 11:  // another run (the plugin's path, the slowest, in one of four)
      in->flags = static_cast<uint8_t>((*rng)() & 6) | ((*rng)() % 4 == 0 ? kFlagPlugin : 0);
      in->steps = static_cast<uint8_t>((*rng)());
      in->seed = static_cast<uint8_t>((*rng)());
      break;
    case 13: {  // a flight plan added (or made afresh): the model's qpos0 nudged, deviations
      // about a centimetre; the other mutations then break it
      std::vector<double> v{static_cast<double>(static_cast<int>(pick(5)) - 2)};
      const size_t n = 1 + pick(12);
      std::uniform_real_distribution<double> u(-0.05, 0.05);
      for (size_t j = 0; j < n; ++j) {
        for (int i = 0; i < m->nq; ++i) v.push_back(m->qpos0[i] + u(*rng));
        for (int b = 0; b < m->nbody; ++b) v.push_back(0.01 + std::fabs(u(*rng)));
      }
      Table plan{kPlan, 0, v, ""};
      auto at = std::find_if(in->tables.begin(), in->tables.end(),
                             [](const Table& x) { return x.name == kPlan; });
      if (at == in->tables.end()) {
        in->tables.push_back(plan);
      } else {
        *at = plan;
      }
      break;
    }
    case 12: {  // libFuzzer's byte mutations on the entries
      const size_t size = 8 * v.size(), room = size + 64;
      std::vector<uint8_t> bytes(room);
      if (size) std::memcpy(bytes.data(), v.data(), size);
      const size_t n = LLVMFuzzerMutate(bytes.data(), size, room) / 8;
      v.resize(n);
      if (n) std::memcpy(v.data(), bytes.data(), 8 * n);
      break;
    }
    default: {  // an entry nudged
      if (!v.empty()) {
        double& x = v[pick(v.size())];
        x += static_cast<double>(static_cast<int>(pick(9)) - 4);
      }
      break;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  mju_user_warning = OnWarning;
  mju_user_error = OnError;
  Load();
  if (std::getenv("DUA_FUZZ_STATS")) std::atexit(PrintStats);
  return 0;
}

extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size,
                                          unsigned int seed) {
  std::mt19937_64 rng(seed);
  Input in;
  if (!Parse(data, size, &in)) {
    if (rng() % 2) return LLVMFuzzerMutate(data, size, max_size);
    in = g_seeds[rng() % g_seeds.size()];
  }
  const int n = 1 + static_cast<int>(rng() % 3);
  for (int k = 0; k < n; ++k) MutateOnce(&in, &rng);
  const std::vector<uint8_t> out = Serialize(in);
  if (out.size() > max_size) return LLVMFuzzerMutate(data, size, max_size);
  std::memcpy(data, out.data(), out.size());
  return out.size();
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Input in;
  if (!Parse(data, size, &in)) return -1;  // not an input: kept out of the corpus
  const Model& mo = g_models[in.model % g_models.size()];
  std::string refused, refused_text, err, err_text;
  const auto tables = Build(in, mo.bare, false, &refused, &err);
  const auto from_text = Build(in, mo.bare, true, &refused_text, &err_text);
  // The text holds the same entries: both decide alike, for the same reason.
  if (refused != refused_text ||
      err.substr(err.find("' ") + 1) != err_text.substr(err_text.find("' ") + 1)) {
    Die("the array and text paths disagree: '" + err + "' against '" + err_text + "'");
  }
  if (tables) Run(mo, tables, in);
  static const bool no_plugin = std::getenv("DUA_FUZZ_NO_PLUGIN") != nullptr;
  if ((in.flags & kFlagPlugin) && !no_plugin) RunPlugin(mo, in, refused);
  return 0;
}

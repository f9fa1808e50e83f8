// A C++ program that runs a model exported by `dua-mujoco export` (or built with
// dua_mujoco.attach) without Python: it registers the plugins as a Python process does, loads
// the model, steps it, and prints the predictor's sensor after every step.
//
//   g++ -std=c++17 run_model.cc -I<mujoco>/include <mujoco>/libmujoco.so.*
//       -Wl,-rpath,<mujoco> -o run_model      (one line; <mujoco>: the mujoco package folder)
//   ./run_model <path>/libdua_mujoco.so model.xml 1000
//
// Output: one line a step, "time standing min_tau evaluated deferred flagged". Whatever goes
// wrong (the plugin library, the model, its tables) ends the program with one line on stderr
// and exit status 1.
#include <dlfcn.h>
#include <mujoco/mujoco.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

const char* g_model = "";
std::string g_warning;  // MuJoCo's latest warning: what a failure that follows it is about

// MuJoCo's warnings are kept for the line a failure prints; its errors end the program with it
// (MuJoCo's own handler would exit too, after writing MUJOCO_LOG.TXT).
void Warning(const char* msg) { g_warning = msg; }

// One line on stderr (MuJoCo's XML errors span several), exit status 1.
[[noreturn]] void Fail(const std::string& what) {
  std::string line;
  for (const char c : what) {
    if (c != '\n') {
      line += c;
    } else if (!line.empty() && line.back() != ' ') {
      line += ' ';
    }
  }
  while (!line.empty() && line.back() == ' ') line.pop_back();
  std::fprintf(stderr, "run_model: %s\n", line.c_str());
  std::exit(1);
}

void Error(const char* msg) {
  std::string what = msg;
  // A plugin that refused the model says why in a warning; the error then only says it failed.
  if (!g_warning.empty()) what = g_warning + " (" + what + ")";
  Fail(std::string(g_model) + ": " + what);
}

// MuJoCo's bundled plugins: the plugin folder beside the libmujoco this program runs with.
std::string BundledPlugins() {
  Dl_info info;
  if (!dladdr(reinterpret_cast<void*>(&mj_version), &info) || !info.dli_fname) return "";
  std::string path = info.dli_fname;
  const size_t slash = path.rfind('/');
  return (slash == std::string::npos ? std::string(".") : path.substr(0, slash)) + "/plugin";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s PLUGIN_LIBRARY MODEL(.xml|.mjb) STEPS\n", argv[0]);
    return 2;
  }
  const char* path = argv[2];
  g_model = path;
  mju_user_warning = Warning;
  mju_user_error = Error;
  // Plugins are registered as `import mujoco` registers them: MuJoCo's bundled ones (the same
  // folder, read in the same order), then this one. A model file in MuJoCo's binary format
  // (.mjb) records each plugin by its registration slot, which MuJoCo does not check: read
  // where the plugins sit elsewhere, it crashes (docs/plugin.md).
  mj_loadAllPluginLibraries(BundledPlugins().c_str(), nullptr);
  mj_loadPluginLibrary(argv[1]);  // a library that does not load: MuJoCo's error, above
  if (!mjp_getPlugin("dua_mujoco.predictor", nullptr)) {
    Fail(std::string(argv[1]) +
         " did not register the plugin dua_mujoco.predictor: pass libdua_mujoco.so (python -c "
         "'import dua_mujoco.native as n; print(n.library_path())')");
  }
  char error[1000] = "";
  const size_t n = std::strlen(path);
  const bool binary = n > 4 && std::strcmp(path + n - 4, ".mjb") == 0;
  mjModel* m =
      binary ? mj_loadModel(path, nullptr) : mj_loadXML(path, nullptr, error, sizeof(error));
  if (!m) {
    const std::string why = binary ? (g_warning.empty() ? "not a model" : g_warning) : error;
    Fail(std::string("cannot load ") + path + ": " + why);
  }
  const int sensor = mj_name2id(m, mjOBJ_SENSOR, "dua");
  if (sensor < 0) {
    Fail(std::string(path) + " has no sensor 'dua': export it with dua-mujoco export");
  }
  g_warning.clear();
  mjData* d = mj_makeData(m);  // the plugin reads its tables: a refusal is MuJoCo's error
  const int steps = std::atoi(argv[3]);
  for (int k = 0; k < steps; ++k) {
    mj_step(m, d);
    const mjtNum* out = d->sensordata + m->sensor_adr[sensor];
    std::printf("%.17g %g %.17g %g %g %g\n", d->time, out[0], out[1], out[2], out[3], out[4]);
  }
  mj_deleteData(d);
  mj_deleteModel(m);
  return 0;
}

// A C++ program that runs a model exported by `dua-mujoco export` (or built with
// dua_mujoco.attach) without Python: it loads the plugin library, steps the model, and prints
// the predictor's sensor after every step.
//
//   g++ -std=c++17 run_model.cc -I<mujoco>/include -L<mujoco> -l:libmujoco.so.4.0.0
//       -Wl,-rpath,<mujoco> -o run_model      (one line; <mujoco>: the mujoco package folder)
//   ./run_model <path>/libdua_mujoco.so model.xml 1000
//
// Output: one line a step, "time standing min_tau evaluated deferred flagged".
#include <mujoco/mujoco.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s PLUGIN_LIBRARY MODEL(.xml|.mjb) STEPS\n", argv[0]);
    return 2;
  }
  // Registers the sensor plugin "dua_mujoco.predictor" (MuJoCo's simulate does the same for
  // every library in its plugin folder).
  mj_loadPluginLibrary(argv[1]);
  char error[1000] = "";
  const char* path = argv[2];
  const size_t n = std::strlen(path);
  mjModel* m = (n > 4 && std::strcmp(path + n - 4, ".mjb") == 0)
                   ? mj_loadModel(path, nullptr)
                   : mj_loadXML(path, nullptr, error, sizeof(error));
  if (!m) {
    std::fprintf(stderr, "cannot load %s: %s\n", path, error);
    return 1;
  }
  const int sensor = mj_name2id(m, mjOBJ_SENSOR, "dua");
  if (sensor < 0) {
    std::fprintf(stderr, "%s has no sensor 'dua': export it with dua-mujoco export\n", path);
    return 1;
  }
  mjData* d = mj_makeData(m);
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

// What dua_mujoco._core's binding files share: the array types they take and give, and the
// errors they raise (bindings.cc holds the module; each Bind* registers one part of it).
#ifndef DUA_MUJOCO_BINDINGS_H_
#define DUA_MUJOCO_BINDINGS_H_

#include <mujoco/mujoco.h>
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/pair.h>  // functions return (array, count) pairs

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "dua/dua.h"

namespace nb = nanobind;

namespace dua {

// Arrays in: C-contiguous on the CPU (nanobind converts other layouts and dtypes by copying).
template <class T>
using In = nb::ndarray<const T, nb::c_contig, nb::device::cpu>;
// Arrays written in place.
template <class T>
using InOut = nb::ndarray<T, nb::c_contig, nb::device::cpu>;
template <class T>
using Out = nb::ndarray<nb::numpy, T>;

// A numpy array that owns v.
template <class T>
Out<T> Owned(std::vector<T> v, std::vector<size_t> shape) {
  if (v.empty()) v.reserve(1);  // a valid pointer
  auto* held = new std::vector<T>(std::move(v));
  nb::capsule owner(held, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  return Out<T>(held->data(), shape.size(), shape.data(), owner);
}

// A numpy array that owns a copy of v.
inline Out<int64_t> Ints(const std::vector<int64_t>& v) {
  return Owned(std::vector<int64_t>(v), {v.size()});
}

// A bool array that owns v (0/1 bytes: numpy's bool).
inline Out<bool> OwnedBools(std::vector<uint8_t> v) {
  const size_t shape[1] = {v.size()};
  if (v.empty()) v.reserve(1);
  auto* held = new std::vector<uint8_t>(std::move(v));
  nb::capsule owner(held, [](void* p) noexcept { delete static_cast<std::vector<uint8_t>*>(p); });
  return Out<bool>(reinterpret_cast<bool*>(held->data()), 1, shape, owner);
}

// A numpy view of data that `owner` keeps alive (read-only when T is const).
template <class T>
nb::ndarray<nb::numpy, T> View(T* data, std::vector<size_t> shape, nb::handle owner) {
  return nb::ndarray<nb::numpy, T>(data, shape.size(), shape.data(), owner);
}

template <class A>
int64_t Size(const A& a) {
  return static_cast<int64_t>(a.size());
}

// Raises dua_mujoco.exceptions.<name>(message).
[[noreturn]] inline void Raise(const char* name, const std::string& message) {
  nb::object cls = nb::module_::import_("dua_mujoco.exceptions").attr(name);
  PyErr_SetObject(cls.ptr(), nb::str(message.c_str()).ptr());
  throw nb::python_error();
}

// A shape or index that does not fit: ShapeError (an InvalidInputError).
inline void Require(bool ok, const std::string& message) {
  if (!ok) Raise("ShapeError", message);
}

// A literal message is made a string only when it is raised: checks run once an element, and
// a std::string of a message past 15 characters is a heap allocation each time.
inline void Require(bool ok, const char* message) {
  if (!ok) Require(false, std::string(message));
}

inline const mjModel* ModelOf(nb::handle model) {
  return reinterpret_cast<const mjModel*>(nb::cast<uintptr_t>(model.attr("_address")));
}

inline const mjData* DataOf(nb::handle data) {
  return reinterpret_cast<const mjData*>(nb::cast<uintptr_t>(data.attr("_address")));
}

// Registers what dua_mujoco.core needs beyond bindings.cc (bindings_core.cc); called last.
void BindCore(nb::module_& m);
// Registers the shield's brake and shield (bindings_shield.cc); after the Tables class.
void BindShield(nb::module_& m);

}  // namespace dua

#endif  // DUA_MUJOCO_BINDINGS_H_

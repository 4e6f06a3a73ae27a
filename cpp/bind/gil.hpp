// Bindings: taking back the GIL after a render (render.cpp), and dropping Python references from
// a thread without it (mesh.cpp), while the interpreter may be finalizing.
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>

namespace sr {
namespace bind {

bool interpreter_finalizing();
// For a thread that must not return to Python because the interpreter is finalizing: sleeps
// until the process exits, touching nothing of Python's (its thread state may be freed already).
[[noreturn]] void park_forever();
// Takes back the GIL released for a render (gil.cpp states why not gil_scoped_release).
void take_gil_or_park(PyThreadState* state);
extern std::atomic<int> g_parked_threads;  // _parked_threads(), for tests

}  // namespace bind
}  // namespace sr

// Bindings: the GIL around a render and at interpreter exit (gil.hpp).
#include "gil.hpp"

#include <cxxabi.h>
#include <unistd.h>

namespace sr {
namespace bind {

std::atomic<int> g_parked_threads{0};

bool interpreter_finalizing() {
#if PY_VERSION_HEX >= 0x030D0000
  return Py_IsFinalizing();
#else
  return _Py_IsFinalizing();
#endif
}

[[noreturn]] void park_forever() {
  g_parked_threads.fetch_add(1);
  for (;;) pause();
}

// Takes back the GIL released for a render, outside any destructor. During finalization Python
// ends a thread that asks for the GIL with pthread_exit, whose forced unwind aborted the process
// when it reached pybind11's gil_scoped_release destructor (noexcept): a daemon thread rendering
// while the interpreter exited died with "terminate called without an active exception" in 10
// runs of 10 (pybind11 issue 2215). Such a thread parks instead: when finalization has begun
// before it asks, or when the unwind arrives (finalization began in between). Its render is
// complete and its Renderer unlocked; the references it holds are never dropped.
void take_gil_or_park(PyThreadState* state) {
  if (interpreter_finalizing()) park_forever();
  try {
    PyEval_RestoreThread(state);
  } catch (abi::__forced_unwind&) {
    park_forever();  // not rethrown: the handler is never left
  }
}

}  // namespace bind
}  // namespace sr
